"""PointCloud2 <-> NumPy: round trips, zero-copy views, layouts, rgb, malformed messages."""
import numpy as np
import pytest
from numpy.testing import assert_array_equal
from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from example_pcl import conversions
from example_pcl.errors import PerceptionError


def organized(h=4, w=5, seed=0):
    rng = np.random.default_rng(seed)
    xyz = rng.normal(size=(h, w, 3)).astype(np.float32)
    xyz[0, 1] = np.nan
    rgb = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    return xyz, rgb


def pcl_style_msg(xyz, rgb):
    """A message laid out like PCL's PointXYZRGB: x y z pad rgb pad pad pad (32 bytes a point)."""
    h, w = xyz.shape[:2]
    fields = [PointField("x", 0, 7, 1), PointField("y", 4, 7, 1), PointField("z", 8, 7, 1),
              PointField("rgb", 16, 7, 1)]
    buf = np.zeros((h, w, 32), np.uint8)
    buf[..., 0:12] = xyz.view(np.uint8).reshape(h, w, 12)
    buf[..., 16:20] = conversions.pack_rgb(rgb).astype("<u4").view(np.uint8).reshape(h, w, 4)
    return PointCloud2(header=Header(frame_id="camera"), height=h, width=w, fields=fields, is_bigendian=False,
                       point_step=32, row_step=32 * w, data=buf.tobytes(), is_dense=False)


def test_dtype_primitives_round_trip():
    """fields_to_dtype and dtype_to_fields are inverse, padding kept in itemsize."""
    fields = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("intensity", 16, 7, 1), ("ring", 20, 4, 1),
              ("t", 24, 8, 1), ("hist", 32, 2, 4)]
    dtype = conversions.fields_to_dtype(fields, 40)
    assert dtype.itemsize == 40
    assert conversions.dtype_to_fields(dtype) == fields


def test_organized_view_is_zero_copy():
    """An organized message views as (H, W) and its xyz as a read-only (H, W, 3) view of msg.data."""
    xyz, rgb = organized()
    msg = pcl_style_msg(xyz, rgb)
    arr = conversions.cloud_to_array(msg)
    assert arr.shape == (4, 5)
    view = conversions.cloud_to_xyz(msg)
    assert view.shape == (4, 5, 3) and view.dtype == np.float32
    assert np.shares_memory(view, np.frombuffer(msg.data, np.uint8))
    assert not view.flags.writeable
    assert_array_equal(view, xyz)
    assert_array_equal(conversions.unpack_rgb(arr), rgb)


def test_matches_sensor_msgs_read_points():
    """read_points(skip_nans) gives the same points as sensor_msgs.point_cloud2.read_points."""
    xyz, rgb = organized(6, 7)
    msg = pcl_style_msg(xyz, rgb)
    ours = conversions.read_points(msg, field_names=("x", "y", "z"), skip_nans=True)
    theirs = np.array(list(point_cloud2.read_points(msg, field_names=("x", "y", "z"), skip_nans=True)), np.float32)
    assert_array_equal(conversions.xyz_view(ours), theirs)


def test_round_trip_xyz_rgb_organized():
    """xyz_to_cloud then cloud_to_xyz / unpack_rgb returns the input, organized shape and header kept."""
    xyz, rgb = organized()
    msg = conversions.xyz_to_cloud(xyz, rgb, frame_id="cam")
    assert (msg.height, msg.width, msg.header.frame_id, msg.is_dense) == (4, 5, "cam", False)
    assert_array_equal(conversions.cloud_to_xyz(msg), xyz)
    assert_array_equal(conversions.unpack_rgb(conversions.cloud_to_array(msg)), rgb)


def test_round_trip_through_serialization():
    """A message survives rospy serialization: deserialized bytes view back to the same points."""
    from io import BytesIO

    xyz, rgb = organized()
    msg = conversions.xyz_to_cloud(xyz, rgb, frame_id="cam")
    buf = BytesIO()
    msg.serialize(buf)
    back = PointCloud2()
    back.deserialize(buf.getvalue())
    assert_array_equal(conversions.cloud_to_xyz(back), xyz)


def serialized(msg):
    from io import BytesIO

    buf = BytesIO()
    msg.serialize(buf)
    return buf.getvalue()


@pytest.mark.parametrize("make", [
    lambda: conversions.xyz_to_cloud(*organized(), frame_id="kamera_\u00f6", stamp=None),
    lambda: pcl_style_msg(*organized(3, 4)),
    lambda: conversions.xyz_to_cloud(np.arange(12, dtype=np.float32).reshape(4, 3), frame_id="cam"),
])
def test_cloud_from_bytes_reads_what_genpy_reads(make):
    """A serialized cloud read by cloud_from_bytes equals genpy's deserialize, field by field."""
    msg = make()
    msg.header.seq, msg.header.stamp.secs, msg.header.stamp.nsecs = 7, 1234, 5678
    raw = serialized(msg)
    ours, theirs = conversions.cloud_from_bytes(raw), PointCloud2().deserialize(raw)
    for name in ("header", "height", "width", "fields", "is_bigendian", "point_step", "row_step", "is_dense"):
        assert getattr(ours, name) == getattr(theirs, name), name
    assert bytes(ours.data) == theirs.data
    assert_array_equal(conversions.cloud_to_xyz(ours), conversions.cloud_to_xyz(theirs))


def test_cloud_from_bytes_views_the_buffer():
    """The points of a cloud read by cloud_from_bytes are the serialized bytes themselves, not a copy."""
    raw = serialized(conversions.xyz_to_cloud(*organized(), frame_id="cam"))
    xyz = conversions.cloud_to_xyz(conversions.cloud_from_bytes(raw))
    assert np.shares_memory(xyz, np.frombuffer(raw, np.uint8)) and not xyz.flags.writeable


@pytest.mark.parametrize("cut", [slice(0, 10), slice(0, -2), slice(0, None, None)])
def test_cloud_from_bytes_refuses_a_partial_message(cut):
    """A truncated buffer, or one with bytes after the message, is a PerceptionError."""
    raw = serialized(conversions.xyz_to_cloud(*organized(), frame_id="cam"))
    broken = raw[cut] if cut.stop is not None else raw + b"\0"
    with pytest.raises(PerceptionError, match="PointCloud2"):
        conversions.cloud_from_bytes(broken)


def test_frozen_data_is_bytes_or_a_view_of_bytes():
    """Only immutable point data counts as frozen: bytes and views of bytes, not bytearray or lists."""
    raw = serialized(conversions.xyz_to_cloud(*organized(), frame_id="cam"))
    assert conversions.frozen_data(conversions.cloud_from_bytes(raw))
    assert conversions.frozen_data(PointCloud2().deserialize(raw))
    msg = conversions.xyz_to_cloud(*organized())
    assert conversions.frozen_data(msg)
    for mutable in (bytearray(msg.data), memoryview(bytearray(msg.data)), list(msg.data)):
        msg.data = mutable
        assert not conversions.frozen_data(msg)


def test_unorganized_and_dense():
    """An (N, 3) array gives height 1, is_dense true when all finite."""
    xyz = np.arange(12, dtype=np.float32).reshape(4, 3)
    msg = conversions.xyz_to_cloud(xyz)
    assert (msg.height, msg.width, msg.is_dense) == (1, 4, True)
    assert conversions.cloud_to_xyz(msg).shape == (4, 3)


def test_row_padding_honoured():
    """row_step larger than width * point_step (padded rows) is viewed correctly."""
    xyz, rgb = organized(3, 4)
    msg = pcl_style_msg(xyz, rgb)
    rows = np.frombuffer(msg.data, np.uint8).reshape(3, -1)
    msg.data = np.hstack([rows, np.zeros((3, 8), np.uint8)]).tobytes()
    msg.row_step += 8
    assert_array_equal(conversions.cloud_to_xyz(msg), xyz)


def test_rgba_uint32_and_rgb_float_agree():
    """Colours packed as float32 rgb and as uint32 rgba unpack to the same uint8 triples."""
    xyz, rgb = organized()
    a = conversions.make_points(xyz, rgb, rgb_field="rgb")
    b = conversions.make_points(xyz, rgb, rgb_field="rgba")
    assert a.dtype.fields["rgb"][0] == np.float32 and b.dtype.fields["rgba"][0] == np.uint32
    assert_array_equal(conversions.unpack_rgb(a), conversions.unpack_rgb(b))


def test_non_float_xyz_copied():
    """x, y, z stored as float64 come back as a float32 copy."""
    dtype = conversions.fields_to_dtype([("x", 0, 8, 1), ("y", 8, 8, 1), ("z", 16, 8, 1)], 24)
    pts = np.zeros(3, dtype)
    pts["x"], pts["y"], pts["z"] = [1, 2, 3], [4, 5, 6], [7, 8, 9]
    assert_array_equal(conversions.xyz_view(pts), [[1, 4, 7], [2, 5, 8], [3, 6, 9]])


def test_create_cloud_like_sensor_msgs():
    """create_cloud writes what sensor_msgs.point_cloud2.create_cloud writes."""
    fields = [PointField("x", 0, 7, 1), PointField("y", 4, 7, 1), PointField("z", 8, 7, 1)]
    pts = np.random.default_rng(5).normal(size=(10, 3)).astype(np.float32)
    ours = conversions.create_cloud(Header(), fields, pts)
    theirs = point_cloud2.create_cloud(Header(), fields, pts.tolist())
    assert ours.data == theirs.data and ours.point_step == theirs.point_step


def test_empty_cloud():
    """width x height = 0 gives an empty array, not an error."""
    msg = conversions.xyz_to_cloud(np.zeros((0, 3), np.float32))
    assert conversions.cloud_to_xyz(msg).shape == (0, 3)


@pytest.mark.parametrize("breakage, text", [
    (lambda m: setattr(m, "is_bigendian", True), "big-endian"),
    (lambda m: setattr(m, "data", m.data[:-1]), "data has"),
    (lambda m: setattr(m, "point_step", 8), "runs past point_step"),
    (lambda m: setattr(m, "fields", m.fields[1:]), "no x"),
    (lambda m: setattr(m.fields[0], "datatype", 42), "unknown datatype"),
    (lambda m: setattr(m, "row_step", 4), "row_step"),
])
def test_malformed_messages_raise(breakage, text):
    """Each kind of malformed message raises PerceptionError saying what is wrong."""
    xyz, rgb = organized()
    msg = pcl_style_msg(xyz, rgb)
    breakage(msg)
    with pytest.raises(PerceptionError, match=text):
        conversions.cloud_to_xyz(msg)
