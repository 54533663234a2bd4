"""sensor_msgs/PointCloud2 <-> NumPy, vectorised and zero-copy where the layout allows.

Everything here rests on two primitives that own padding and offsets: :func:`fields_to_dtype`
(a message's or PCD file's field list -> a NumPy structured dtype of exactly ``point_step``
bytes) and :func:`dtype_to_fields` (the reverse). A message's buffer is then viewed, not copied,
as a structured array of shape (height, width) for an organized cloud or (width,) for an
unorganized one; :func:`xyz_view` gives its x, y, z as a float32 (..., 3) strided view.
:func:`cloud_from_bytes` reads a serialized message (rospy.AnyMsg's buffer) with its data a view too.

The same field tuples ``(name, offset, datatype, count)`` describe PCD files (example_pcl.pcd),
since PCL's PCLPointField uses the datatype codes of sensor_msgs/PointField.
"""
from __future__ import annotations

import struct
from typing import Iterable, Optional, Sequence

import numpy as np

from example_pcl.errors import PerceptionError

# sensor_msgs/PointField datatype codes <-> little-endian NumPy types.
DATATYPE_TO_NUMPY = {
    1: np.dtype("<i1"), 2: np.dtype("<u1"), 3: np.dtype("<i2"), 4: np.dtype("<u2"),
    5: np.dtype("<i4"), 6: np.dtype("<u4"), 7: np.dtype("<f4"), 8: np.dtype("<f8"),
}
NUMPY_TO_DATATYPE = {(t.kind, t.itemsize): code for code, t in DATATYPE_TO_NUMPY.items()}


def _field_tuple(field) -> tuple:
    """(name, offset, datatype, count) of a PointField message or a tuple."""
    if isinstance(field, tuple):
        return field
    return (field.name, field.offset, field.datatype, field.count)


def fields_to_dtype(fields: Iterable, point_step: int) -> np.dtype:
    """A structured dtype of ``point_step`` bytes with each field at its offset.

    ``fields``: PointField messages or ``(name, offset, datatype, count)`` tuples. A field with
    count > 1 becomes a sub-array. Padding between and after fields is kept as unnamed bytes,
    so the dtype can view a message's buffer as it is.
    """
    names, formats, offsets = [], [], []
    for field in fields:
        name, offset, datatype, count = _field_tuple(field)
        if datatype not in DATATYPE_TO_NUMPY:
            raise PerceptionError(f"field '{name}' has unknown datatype {datatype}")
        if count < 1:
            # PCL and rviz treat count 0 as 1.
            count = 1
        base = DATATYPE_TO_NUMPY[datatype]
        if offset < 0 or offset + base.itemsize * count > point_step:
            raise PerceptionError(
                f"field '{name}' ({base.itemsize * count} bytes at offset {offset}) "
                f"runs past point_step {point_step}")
        if name in names:
            raise PerceptionError(f"field '{name}' appears twice")
        names.append(name)
        formats.append(base if count == 1 else np.dtype((base, (count,))))
        offsets.append(offset)
    if point_step < 1:
        raise PerceptionError(f"point_step must be positive, got {point_step}")
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})


def dtype_to_fields(dtype: np.dtype) -> list:
    """``(name, offset, datatype, count)`` for each named field of a structured dtype."""
    fields = []
    for name in dtype.names or ():
        sub, offset = dtype.fields[name][:2]
        base, count = (sub.base, int(np.prod(sub.shape))) if sub.shape else (sub, 1)
        code = NUMPY_TO_DATATYPE.get((base.kind, base.itemsize))
        if code is None or base.byteorder == ">":
            raise PerceptionError(f"field '{name}' has type {sub}, which PointCloud2 cannot hold")
        fields.append((name, offset, code, count))
    return fields


def point_fields(dtype: np.dtype) -> list:
    """sensor_msgs/PointField messages for a structured dtype."""
    from sensor_msgs.msg import PointField

    return [PointField(name=n, offset=o, datatype=d, count=c) for n, o, d, c in dtype_to_fields(dtype)]


def _buffer(data) -> np.ndarray:
    """The message's data as a uint8 array: a view of bytes/bytearray, a copy of a list."""
    if isinstance(data, (bytes, bytearray, memoryview)):
        return np.frombuffer(data, dtype=np.uint8)
    return np.asarray(data, dtype=np.uint8)


def cloud_from_bytes(buffer):
    """A sensor_msgs/PointCloud2 from its ROS serialization (what rospy.AnyMsg holds), its ``data``
    a memoryview of ``buffer`` (no copy: genpy's deserialize copies the points, about 1 ms for a
    640x480 XYZRGB cloud). Raises PerceptionError for a buffer that is not a whole PointCloud2."""
    from sensor_msgs.msg import PointCloud2, PointField

    view = memoryview(buffer).cast("B")
    msg = PointCloud2()
    try:
        msg.header.seq, msg.header.stamp.secs, msg.header.stamp.nsecs = struct.unpack_from("<3I", view, 0)
        frame_id, end = _string_at(view, 12)
        msg.header.frame_id = frame_id
        msg.height, msg.width, n_fields = struct.unpack_from("<3I", view, end)
        end += 12
        for _ in range(n_fields):
            name, end = _string_at(view, end)
            offset, datatype, count = struct.unpack_from("<IBI", view, end)
            end += 9
            msg.fields.append(PointField(name=name, offset=offset, datatype=datatype, count=count))
        is_bigendian, msg.point_step, msg.row_step, size = struct.unpack_from("<B3I", view, end)
        end += 13
        if end + size + 1 != len(view):
            raise PerceptionError(f"a serialized PointCloud2 of {len(view)} bytes holds {size} bytes of data at "
                                  f"{end}: not a whole message")
        msg.data = view[end:end + size]
        msg.is_bigendian, msg.is_dense = bool(is_bigendian), bool(view[end + size])
    except (struct.error, UnicodeDecodeError) as e:
        raise PerceptionError(f"not a serialized PointCloud2 ({len(view)} bytes): {e}") from None
    return msg


def _string_at(view, start):
    """(the ROS string serialized at start, the offset after it)."""
    (length,) = struct.unpack_from("<I", view, start)
    start += 4
    if start + length > len(view):
        raise struct.error(f"a string of {length} bytes at {start} runs past the end")
    return bytes(view[start:start + length]).decode("utf-8"), start + length


def frozen_data(cloud) -> bool:
    """Whether a PointCloud2's points are in memory that never changes (bytes, or a view of bytes,
    as rospy delivers them): views of them can be read later, from another thread, uncopied."""
    data = cloud.data
    return isinstance(data, bytes) or (isinstance(data, memoryview) and isinstance(data.obj, bytes))


def cloud_to_array(cloud) -> np.ndarray:
    """The points of a PointCloud2 as a structured array, viewing the message's buffer.

    Shape (height, width) for an organized cloud (height > 1), (width,) otherwise. No copy when
    the data is bytes (as rospy delivers it); the view is then read-only. Any point_step, field
    offsets and row padding are honoured. Raises PerceptionError for a big-endian message, a
    field layout that does not fit point_step, or data whose length is not height * row_step.
    """
    if cloud.is_bigendian:
        raise PerceptionError("big-endian PointCloud2 messages are not supported")
    height, width, point_step, row_step = cloud.height, cloud.width, cloud.point_step, cloud.row_step
    dtype = fields_to_dtype(cloud.fields, point_step)
    if row_step < width * point_step:
        raise PerceptionError(f"row_step {row_step} is smaller than width {width} x point_step {point_step}")
    buf = _buffer(cloud.data)
    if buf.size != height * row_step:
        raise PerceptionError(
            f"data has {buf.size} bytes, height {height} x row_step {row_step} needs {height * row_step}")
    shape = (height, width) if height > 1 else (width,)
    strides = (row_step, point_step) if height > 1 else (point_step,)
    if height * width == 0:
        return np.zeros(shape, dtype=dtype)
    return np.ndarray(shape, dtype=dtype, buffer=buf, strides=strides)


def xyz_view(points: np.ndarray) -> np.ndarray:
    """x, y, z of a structured array as float32 of shape points.shape + (3,).

    A strided view (no copy) when x, y, z are float32 at consecutive offsets, as in every
    PointCloud2 and PCD cloud PCL or a driver makes; otherwise a copy. Raises PerceptionError
    when a coordinate is missing.
    """
    names = points.dtype.names or ()
    missing = [c for c in "xyz" if c not in names]
    if missing:
        raise PerceptionError(f"the cloud has no {', '.join(missing)} field (fields: {', '.join(names)})")
    types = [points.dtype.fields[c][0] for c in "xyz"]
    offsets = [points.dtype.fields[c][1] for c in "xyz"]
    if all(t == np.float32 for t in types) and offsets[1] == offsets[0] + 4 and offsets[2] == offsets[0] + 8:
        x = points["x"]
        return np.lib.stride_tricks.as_strided(
            x, shape=points.shape + (3,), strides=points.strides + (4,), writeable=x.flags.writeable)
    return np.stack([points[c].astype(np.float32) for c in "xyz"], axis=-1)


def cloud_to_xyz(cloud, copy: bool = False) -> np.ndarray:
    """x, y, z of a PointCloud2 as float32 (N, 3), or (H, W, 3) when organized; NaN points kept.

    A read-only view of the message's buffer unless ``copy``.
    """
    xyz = xyz_view(cloud_to_array(cloud))
    return np.array(xyz, dtype=np.float32, copy=True) if copy else xyz


def unpack_rgb(points: np.ndarray) -> np.ndarray:
    """Colours of a structured array's ``rgb`` (float32-packed) or ``rgba`` (uint32) field.

    Returns uint8 of shape points.shape + (3,), channels r, g, b.
    """
    names = points.dtype.names or ()
    field = "rgb" if "rgb" in names else "rgba" if "rgba" in names else None
    if field is None:
        raise PerceptionError(f"the cloud has no rgb or rgba field (fields: {', '.join(names)})")
    packed = np.ascontiguousarray(points[field]).view(np.uint32)
    return np.stack([(packed >> 16) & 0xFF, (packed >> 8) & 0xFF, packed & 0xFF], axis=-1).astype(np.uint8)


def pack_rgb(rgb: np.ndarray) -> np.ndarray:
    """uint8 (..., 3) colours packed as PCL does: uint32 0x00RRGGBB, shape rgb.shape[:-1]."""
    rgb = np.asarray(rgb)
    if rgb.shape[-1:] != (3,):
        raise ValueError(f"rgb must have shape (..., 3), got {rgb.shape}")
    rgb = rgb.astype(np.uint32)
    return (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]


def make_points(xyz: np.ndarray, rgb: Optional[np.ndarray] = None, rgb_field: str = "rgb") -> np.ndarray:
    """A structured array of x, y, z (float32) and optionally a packed colour field.

    xyz: (..., 3) metres; rgb: uint8 (..., 3). ``rgb_field`` "rgb" stores the colour as float32
    (PCL's PointXYZRGB, what rviz expects), "rgba" as uint32. Points are 16 bytes: x y z rgb.
    """
    xyz = np.asarray(xyz)
    if xyz.ndim < 2 or xyz.shape[-1] != 3:
        raise ValueError(f"xyz must have shape (N, 3) or (H, W, 3), got {xyz.shape}")
    fields = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1)]
    if rgb is not None:
        if np.shape(rgb) != xyz.shape:
            raise ValueError(f"rgb must have the shape of xyz {xyz.shape}, got {np.shape(rgb)}")
        fields.append((rgb_field, 12, 7 if rgb_field == "rgb" else 6, 1))
    points = np.zeros(xyz.shape[:-1], dtype=fields_to_dtype(fields, 16 if rgb is not None else 12))
    xyz_view(points)[...] = xyz
    if rgb is not None:
        points[rgb_field] = pack_rgb(rgb).view(points.dtype.fields[rgb_field][0])
    return points


def array_to_cloud(points: np.ndarray, header=None, frame_id: Optional[str] = None, stamp=None,
                   is_dense: Optional[bool] = None):
    """A PointCloud2 holding a structured array, every field kept.

    Shape (H, W) gives an organized cloud of height H; (N,) an unorganized one. ``header`` is
    copied (``frame_id`` and ``stamp`` override its fields). ``is_dense`` defaults to "no NaN or
    inf in x, y, z".
    """
    from sensor_msgs.msg import PointCloud2
    from std_msgs.msg import Header

    if points.dtype.names is None or points.ndim not in (1, 2):
        raise ValueError(f"points must be a 1-D or 2-D structured array, got {points.dtype} {points.shape}")
    msg = PointCloud2()
    msg.header = Header() if header is None else Header(seq=header.seq, stamp=header.stamp, frame_id=header.frame_id)
    if frame_id is not None:
        msg.header.frame_id = frame_id
    if stamp is not None:
        msg.header.stamp = stamp
    msg.height, msg.width = points.shape if points.ndim == 2 else (1, points.shape[0])
    msg.fields = point_fields(points.dtype)
    msg.is_bigendian = False
    msg.point_step = points.dtype.itemsize
    msg.row_step = msg.point_step * msg.width
    if is_dense is None:
        names = points.dtype.names
        is_dense = not all(c in names for c in "xyz") or bool(np.isfinite(xyz_view(points)).all())
    msg.is_dense = bool(is_dense)
    msg.data = np.ascontiguousarray(points).tobytes()
    return msg


def xyz_to_cloud(xyz: np.ndarray, rgb: Optional[np.ndarray] = None, header=None,
                 frame_id: Optional[str] = None, stamp=None):
    """A PointCloud2 of x, y, z (and rgb) from (N, 3) or (H, W, 3) arrays, organized shape kept."""
    return array_to_cloud(make_points(xyz, rgb), header=header, frame_id=frame_id, stamp=stamp)


def read_points(cloud, field_names: Optional[Sequence[str]] = None, skip_nans: bool = False) -> np.ndarray:
    """The vectorised counterpart of sensor_msgs.point_cloud2.read_points: a structured array.

    Flattened to (N,), only ``field_names`` when given, and with ``skip_nans`` the points whose
    x, y or z is NaN left out (a copy then).
    """
    points = cloud_to_array(cloud).reshape(-1)
    if field_names is not None:
        missing = [f for f in field_names if f not in points.dtype.names]
        if missing:
            raise PerceptionError(f"the cloud has no field {', '.join(missing)}")
        points = points[list(field_names)]
    if skip_nans:
        xyz = xyz_view(cloud_to_array(cloud).reshape(-1))
        points = points[~np.isnan(xyz).any(axis=1)]
    return points


def create_cloud(header, fields, points: np.ndarray):
    """The vectorised counterpart of sensor_msgs.point_cloud2.create_cloud.

    ``fields``: PointField messages; ``points``: an (N, len(fields)) array or a structured array
    whose fields are written at the given offsets.
    """
    fields = list(fields)
    point_step = max(o + DATATYPE_TO_NUMPY[d].itemsize * max(c, 1) for _, o, d, c in map(_field_tuple, fields))
    dtype = fields_to_dtype(fields, point_step)
    out = np.zeros(len(points), dtype=dtype)
    if points.dtype.names is not None:
        for name in dtype.names:
            out[name] = points[name]
    else:
        for i, name in enumerate(dtype.names):
            out[name] = points[:, i]
    return array_to_cloud(out, header=header)


def validate_cloud(cloud, max_points: Optional[int] = None) -> np.ndarray:
    """The structured view of a PointCloud2 that a node can use, or PerceptionError saying why not.

    Beyond :func:`cloud_to_array`'s checks (endianness, field layout, data length): the cloud
    must have points, float x, y, z fields, at most ``max_points`` points (a guard against a
    runaway publisher), and at least one finite point.
    """
    points = cloud_to_array(cloud)
    if points.size == 0:
        raise PerceptionError("empty cloud (width x height is 0)")
    if max_points and points.size > max_points:
        raise PerceptionError(f"cloud of {points.size} points, more than ~max_points {max_points}")
    xyz = xyz_view(points).reshape(-1, 3)
    # Every 1009th z first (a camera cloud has finite points all over; 300 reads of a 640x480 one
    # that is not in the cache yet cost 50 us, all of them 1 ms), then all.
    if not (np.isfinite(xyz[::1009, 2]).any() or np.isfinite(xyz).any()):
        raise PerceptionError("cloud has no finite point (all NaN or inf)")
    return points
