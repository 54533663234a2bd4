"""PCD files through PCL: round trips in every format, PCL's files, PCL's tools, malformed files."""
import os
import shutil
import subprocess

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from example_pcl import conversions, pcd
from example_pcl.errors import PerceptionError


def assert_same_points(a, b):
    """Same shape, field names and bits in every field.

    Bits, not values: PCL's ascii writer stores the float-packed rgb as its uint32 bit pattern
    (TYPE U), so the field's type may change while the colour stays exactly the same.
    """
    assert a.shape == b.shape and a.dtype.names == b.dtype.names
    for name in a.dtype.names:
        bits_a = np.ascontiguousarray(a[name]).view(np.uint8)
        bits_b = np.ascontiguousarray(b[name]).view(np.uint8)
        assert_array_equal(bits_a, bits_b, err_msg=name)


@pytest.fixture
def rich_points():
    """An organized cloud with NaN points, rgb, normals, curvature and an integer intensity."""
    rng = np.random.default_rng(7)
    fields = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 7, 1), ("normal_x", 16, 7, 1),
              ("normal_y", 20, 7, 1), ("normal_z", 24, 7, 1), ("curvature", 28, 7, 1), ("intensity", 32, 4, 1)]
    pts = np.zeros((6, 8), conversions.fields_to_dtype(fields, 36))
    for name in ("x", "y", "z", "normal_x", "normal_y", "normal_z", "curvature"):
        pts[name] = rng.normal(size=pts.shape).astype(np.float32) * 3
    pts["x"][2, 3] = pts["y"][2, 3] = pts["z"][2, 3] = np.nan
    pts["rgb"] = conversions.pack_rgb(rng.integers(0, 256, (6, 8, 3))).view(np.float32)
    pts["intensity"] = rng.integers(0, 65535, pts.shape)
    return pts


@pytest.mark.parametrize("fmt", pcd.FORMATS)
def test_round_trip_every_field(tmp_path, rich_points, fmt):
    """write_pcd then read_pcd returns every field bit-exact, organized shape, viewpoint and format."""
    path = tmp_path / "c.pcd"
    pcd.write_pcd(path, rich_points, fmt=fmt, origin=(1, 2, 3), orientation=(0, 1, 0, 0))
    back = pcd.read_pcd(path)
    assert_same_points(rich_points, back.points)
    assert back.organized and back.format == fmt and not back.is_dense
    assert back.origin == (1, 2, 3) and back.orientation == (0, 1, 0, 0)


@pytest.mark.parametrize("fmt", pcd.FORMATS)
def test_unorganized_and_empty(tmp_path, fmt):
    """An (N,) cloud stays (N,); an empty one reads back empty."""
    xyz = np.random.default_rng(1).normal(size=(50, 3)).astype(np.float32)
    pcd.write_cloud(tmp_path / "u.pcd", xyz, fmt=fmt)
    back = pcd.read_pcd(tmp_path / "u.pcd")
    assert back.points.shape == (50,) and back.is_dense
    assert_array_equal(back.xyz, xyz)
    pcd.write_cloud(tmp_path / "e.pcd", np.zeros((0, 3), np.float32), fmt=fmt)
    assert pcd.read_pcd(tmp_path / "e.pcd").points.shape == (0,)


@pytest.mark.parametrize("name, shape, fields", [
    ("frame_20121214T142256.332395.pcd", (480, 640), ("x", "y", "z", "rgba")),
    ("milk.pcd", (13704,), ("x", "y", "z")),
    ("sac_plane_test.pcd", (3283,), ("x", "y", "z", "normal_x", "normal_y", "normal_z", "curvature")),
])
def test_reads_pcl_files(shared_pcd, tmp_path, name, shape, fields):
    """PCL's own test files load with their shape and fields, and survive a round trip in every format."""
    cloud = pcd.read_pcd(shared_pcd(name))
    assert cloud.points.shape == shape and cloud.points.dtype.names == fields
    for fmt in pcd.FORMATS:
        pcd.write_pcd(tmp_path / f"{fmt}.pcd", cloud.points, fmt=fmt)
        assert_same_points(cloud.points, pcd.read_pcd(tmp_path / f"{fmt}.pcd").points)


def test_kinect_frame_values(shared_pcd):
    """The real Kinect frame has about 12% NaN points and plausible depths (0.5-10 m)."""
    cloud = pcd.read_pcd(shared_pcd("frame_20121214T142256.332395.pcd"))
    nan = np.isnan(cloud.xyz).any(axis=-1)
    assert 0.08 < nan.mean() < 0.16
    z = cloud.xyz[..., 2][~nan]
    assert 0.3 < z.min() and z.max() < 10


def test_ascii_reading_matches_binary(shared_pcd, tmp_path):
    """PCL's ascii file and our binary copy of it read to identical values."""
    cloud = pcd.read_pcd(shared_pcd("sac_plane_test.pcd"))
    assert cloud.format == "ascii"
    pcd.write_pcd(tmp_path / "b.pcd", cloud.points, fmt="binary")
    assert_same_points(cloud.points, pcd.read_pcd(tmp_path / "b.pcd").points)


@pytest.mark.skipif(shutil.which("pcl_convert_pcd_ascii_binary") is None, reason="pcl-tools not installed")
@pytest.mark.parametrize("fmt", pcd.FORMATS)
def test_pcl_tools_read_our_files(tmp_path, rich_points, fmt):
    """PCL's pcl_convert_pcd_ascii_binary loads what we write; its binary output reads back identical."""
    pcd.write_pcd(tmp_path / "ours.pcd", rich_points, fmt=fmt)
    proc = subprocess.run(["pcl_convert_pcd_ascii_binary", str(tmp_path / "ours.pcd"), str(tmp_path / "pcl.pcd"), "1"],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.returncode == 0, proc.stdout
    assert "48 points" in proc.stdout
    assert_same_points(rich_points, pcd.read_pcd(tmp_path / "pcl.pcd").points)


def test_missing_file_named(tmp_path):
    """A missing file raises PerceptionError naming it."""
    with pytest.raises(PerceptionError, match="nope.pcd"):
        pcd.read_pcd(tmp_path / "nope.pcd")


@pytest.mark.parametrize("fmt", pcd.FORMATS)
@pytest.mark.parametrize("keep", [0.0, 0.3, 0.6, 0.9, 0.99])
def test_truncated_files_rejected(tmp_path, rich_points, fmt, keep):
    """A file cut anywhere raises PerceptionError naming the file, never crashes."""
    path = tmp_path / "t.pcd"
    pcd.write_pcd(path, rich_points, fmt=fmt)
    # PCL pads binary files with zeros after the data: cut inside the data, not the padding.
    data = path.read_bytes().rstrip(b"\0")
    path.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(PerceptionError, match="t.pcd"):
        pcd.read_pcd(path)


@pytest.mark.parametrize("header_edit", [
    (b"POINTS 48", b"POINTS 4800000000"),
    (b"WIDTH 8", b"WIDTH 80000000"),
    (b"SIZE 4", b"SIZE 9"),
    (b"TYPE F", b"TYPE Q"),
    (b"VERSION 0.7", b"VERSION x"),
    (b"FIELDS x", b"FIELDS"),
])
@pytest.mark.parametrize("fmt", pcd.FORMATS)
def test_malformed_headers_rejected(tmp_path, rich_points, header_edit, fmt):
    """A forged header raises PerceptionError (or reads consistently), never crashes or allocates wildly."""
    path = tmp_path / "m.pcd"
    pcd.write_pcd(path, rich_points, fmt=fmt)
    data = path.read_bytes()
    old, new = header_edit
    assert old in data
    path.write_bytes(data.replace(old, new, 1))
    try:
        cloud = pcd.read_pcd(path)
    except PerceptionError as e:
        assert "m.pcd" in str(e)
    else:
        assert cloud.points.size * cloud.points.dtype.itemsize < 10 * len(data)


def test_garbage_file_rejected(tmp_path):
    """Random bytes raise PerceptionError."""
    path = tmp_path / "g.pcd"
    path.write_bytes(os.urandom(4096))
    with pytest.raises(PerceptionError):
        pcd.read_pcd(path)


def test_atomic_write_leaves_nothing_on_failure(tmp_path, rich_points):
    """A write that fails leaves neither the final file nor a temporary one behind."""
    bad = rich_points.copy()
    with pytest.raises(PerceptionError):
        pcd.write_pcd(tmp_path / "x.pcd", bad, fmt="nonsense")
    with pytest.raises(OSError):
        pcd.write_pcd(tmp_path / "no_such_dir" / "x.pcd", bad)
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_replaces_whole_file(tmp_path, rich_points):
    """Overwriting an existing file swaps it whole; no temporary files remain."""
    path = tmp_path / "x.pcd"
    pcd.write_pcd(path, rich_points[:2])
    pcd.write_pcd(path, rich_points)
    assert [p.name for p in tmp_path.iterdir()] == ["x.pcd"]
    assert pcd.read_pcd(path).points.shape == rich_points.shape


def test_written_file_mode_follows_umask(tmp_path, rich_points):
    """A written file gets the usual mode (0666 less the umask), not the temporary file's 0600."""
    umask = os.umask(0o022)
    try:
        pcd.write_pcd(tmp_path / "m.pcd", rich_points)
    finally:
        os.umask(umask)
    assert (tmp_path / "m.pcd").stat().st_mode & 0o777 == 0o644
