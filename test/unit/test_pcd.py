"""PCD files through PCL: round trips in every format, PCL's files, PCL's tools, malformed files."""
import os
import shutil
import subprocess
import sys
import tempfile

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


# ---- binary_compressed: the body is compressed by the extension, in chunks on several threads ----

def layout(name, n):
    """Points of one of the field layouts the tests and nodes use, ``n`` of them, NaNs included."""
    rng = np.random.default_rng(n)
    if name == "xyz":  # milk.pcd
        fields, step = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1)], 12
    elif name == "xyz_rgb":  # make_points, pcd_publisher
        fields, step = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 7, 1)], 16
    elif name == "xyz_rgba_padded":  # a Kinect driver's PointCloud2: x y z _ rgba _ _ _
        fields, step = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgba", 16, 6, 1)], 32
    elif name == "normals_intensity":  # rich_points: float, uint16
        fields, step = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 7, 1), ("normal_x", 16, 7, 1),
                        ("normal_y", 20, 7, 1), ("normal_z", 24, 7, 1), ("curvature", 28, 7, 1),
                        ("intensity", 32, 4, 1)], 36
    else:  # every size: int8, uint8 x3, int16, float64, and a 33-float descriptor (FPFH-like)
        fields, step = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("label", 12, 1, 1), ("rgb3", 13, 2, 3),
                        ("ring", 16, 3, 1), ("time", 24, 8, 1), ("fpfh", 32, 7, 33)], 164
    points = np.zeros(n, conversions.fields_to_dtype(fields, step))
    raw = points.view(np.uint8).reshape(n, step)
    raw[...] = rng.integers(0, 256, raw.shape, dtype=np.uint8)  # every bit pattern, padding included
    for c in "xyz":
        points[c] = rng.normal(size=n).astype(np.float32)
    points["x"][::3] = np.nan
    return points


LAYOUTS = ("xyz", "xyz_rgb", "xyz_rgba_padded", "normals_intensity", "all_sizes")


@pytest.mark.parametrize("name", LAYOUTS)
@pytest.mark.parametrize("n", [1, 2, 3, 31, 1001])
@pytest.mark.parametrize("threads", [1, 2, 3, 7, 64])
def test_compressed_round_trip_any_threads(tmp_path, name, n, threads):
    """Whatever the number of compression chunks (more than bytes too), PCL's reader gets every field bit-exact."""
    points = layout(name, n)
    pcd.write_pcd(tmp_path / "c.pcd", points, fmt="binary_compressed", threads=threads)
    back = pcd.read_pcd(tmp_path / "c.pcd")
    assert back.format == "binary_compressed" and back.points.shape == (n,)
    assert_same_points(points, back.points)


@pytest.mark.parametrize("shape", [(1, 1), (3, 1), (1, 5), (7, 11), (480, 640)])
@pytest.mark.parametrize("threads", [0, 1, 3])
def test_compressed_organized_shapes(tmp_path, shape, threads):
    """Organized clouds (height > 1) keep height x width; 1-point and 1-row clouds stay what they were."""
    points = layout("xyz_rgb", shape[0] * shape[1]).reshape(shape if shape[0] > 1 else (shape[1],))
    pcd.write_pcd(tmp_path / "o.pcd", points, fmt="binary_compressed", threads=threads)
    back = pcd.read_pcd(tmp_path / "o.pcd")
    assert back.organized == (shape[0] > 1)
    assert_same_points(points, back.points)


@pytest.mark.parametrize("nbytes", [1, 2, 5, 31, 32, 33, 4097, 300_007])
@pytest.mark.parametrize("threads", [1, 2, 3, 8])
def test_compressed_incompressible_data(tmp_path, nbytes, threads):
    """Random bytes, which LZF makes larger than they were (one control byte per 32), round-trip in any chunking."""
    points = np.zeros(nbytes, [("x", np.uint8)])
    points["x"] = np.random.default_rng(nbytes).integers(0, 256, nbytes, dtype=np.uint8)
    path = tmp_path / "r.pcd"
    pcd.write_pcd(path, points, fmt="binary_compressed", threads=threads, is_dense=True)
    assert_same_points(points, pcd.read_pcd(path).points)
    data = path.read_bytes()
    body = data.index(b"DATA binary_compressed\n") + len(b"DATA binary_compressed\n")
    compressed, uncompressed = np.frombuffer(data[body:body + 8], np.uint32)
    assert uncompressed == nbytes and compressed == len(data) - body - 8
    assert compressed > nbytes  # the expanded case the output bound must hold


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_compressed_empty_cloud_as_pcl_writes_it(tmp_path, threads):
    """An empty cloud gets PCL's empty body: both sizes 0."""
    pcd.write_cloud(tmp_path / "e.pcd", np.zeros((0, 3), np.float32), threads=threads)
    assert (tmp_path / "e.pcd").read_bytes().endswith(b"DATA binary_compressed\n" + bytes(8))
    assert pcd.read_pcd(tmp_path / "e.pcd").points.shape == (0,)


def test_compressed_threads_checked(tmp_path):
    """A negative thread count is refused before anything is written."""
    with pytest.raises(PerceptionError, match="threads"):
        pcd.write_pcd(tmp_path / "t.pcd", layout("xyz", 3), fmt="binary_compressed", threads=-1)
    assert list(tmp_path.iterdir()) == []


needs_pcl_tools = pytest.mark.skipif(shutil.which("pcl_convert_pcd_ascii_binary") is None,
                                     reason="pcl-tools not installed")


def pcl_convert(src, dst, fmt):
    """pcl_convert_pcd_ascii_binary: PCL's loadPCDFile then PCDWriter in format 0 ascii, 1 binary, 2 compressed."""
    proc = subprocess.run(["pcl_convert_pcd_ascii_binary", str(src), str(dst), str(fmt)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.returncode == 0 and dst.exists(), proc.stdout
    return proc.stdout


@needs_pcl_tools
@pytest.mark.parametrize("name", LAYOUTS)
@pytest.mark.parametrize("threads", [0, 1, 3])
def test_pcl_tools_read_our_compressed_files(tmp_path, name, threads):
    """pcl_convert_pcd_ascii_binary loads our chunked compressed files; its binary copy reads back bit-exact."""
    points = layout(name, 100_003)
    pcd.write_pcd(tmp_path / "ours.pcd", points, fmt="binary_compressed", threads=threads)
    assert "100003 points" in pcl_convert(tmp_path / "ours.pcd", tmp_path / "pcl.pcd", 1)
    assert_same_points(points, pcd.read_pcd(tmp_path / "pcl.pcd").points)


@needs_pcl_tools
@pytest.mark.parametrize("name", LAYOUTS)
def test_one_thread_is_pcls_file_byte_for_byte(tmp_path, name):
    """On one thread our file is PCL's writeBinaryCompressed file byte for byte (less PCL's zero padding)."""
    points = layout(name, 5000)
    pcd.write_pcd(tmp_path / "b.pcd", points, fmt="binary")
    pcl_convert(tmp_path / "b.pcd", tmp_path / "pcl.pcd", 2)
    pcd.write_pcd(tmp_path / "ours.pcd", points, fmt="binary_compressed", threads=1, is_dense=False)
    ours, theirs = (tmp_path / "ours.pcd").read_bytes(), (tmp_path / "pcl.pcd").read_bytes()
    assert theirs[:len(ours)] == ours
    assert theirs[len(ours):].strip(b"\0") == b""  # PCL's mmap writer rounds the file up to a page


@needs_pcl_tools
def test_reads_a_kinect_frame_pcl_compressed(shared_pcd, tmp_path):
    """A 640x480 frame PCL wrote binary_compressed reads organized, NaNs and rgba bit-exact; so does ours."""
    frame = pcd.read_pcd(shared_pcd("frame_20121214T142256.332395.pcd"))
    pcl_convert(shared_pcd("frame_20121214T142256.332395.pcd"), tmp_path / "pcl.pcd", 2)
    theirs = pcd.read_pcd(tmp_path / "pcl.pcd")
    assert theirs.format == "binary_compressed" and theirs.points.shape == (480, 640)
    assert np.isnan(theirs.xyz).any() and "rgba" in theirs.points.dtype.names
    assert_same_points(frame.points, theirs.points)
    pcd.write_pcd(tmp_path / "ours.pcd", frame.points, fmt="binary_compressed")
    assert_same_points(frame.points, pcd.read_pcd(tmp_path / "ours.pcd").points)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
@pytest.mark.parametrize("fmt, threads", [("binary", 0), ("binary_compressed", 1), ("binary_compressed", 3)])
def test_full_disk_is_an_error(fmt, threads):
    """Every write is checked: on a full disk (/dev/full) the writer raises ENOSPC, never reports success."""
    from example_pcl import _native

    points = layout("xyz_rgb", 20_000)
    with pytest.raises(RuntimeError, match="No space left on device"):
        _native.write_pcd("/dev/full", points.view(np.uint8), conversions.dtype_to_fields(points.dtype),
                          len(points), 1, points.dtype.itemsize, False, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0),
                          fmt, 9, threads)


NO_THREADS_PROBE = """
import sys
import numpy as np
from example_pcl import pcd
points = np.zeros(300_000, [("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
points["x"] = np.random.default_rng(0).normal(size=points.shape)
pcd.write_pcd(sys.argv[1], points, threads=4, fsync=False)
assert (pcd.read_pcd(sys.argv[1]).points.view(np.uint8) == points.view(np.uint8)).all()
"""


def copy_package_for_anyone(dest):
    """The imported example_pcl package (its Python files and _native, from every directory of its
    __path__: src/ and the devel space) copied into dest, readable by every user; returns dest.
    The checkout itself may sit under a directory only its owner can enter."""
    import example_pcl
    package = os.path.join(dest, "example_pcl")
    for source in reversed(list(example_pcl.__path__)):  # src/ last: its __init__.py is the package's
        shutil.copytree(source, package, dirs_exist_ok=True, ignore=shutil.ignore_patterns("__pycache__"))
    for root, dirs, files in os.walk(dest):
        for name in dirs + files:
            os.chmod(os.path.join(root, name), 0o755)
    return dest


@pytest.mark.skipif(os.geteuid() != 0 or not shutil.which("setpriv") or not shutil.which("prlimit"),
                    reason="running as another user with a process limit needs root, setpriv and prlimit")
def test_compressed_without_threads_to_be_had():
    """When no thread can be started (RLIMIT_NPROC), the chunks are compressed on the calling thread."""
    out = tempfile.mkdtemp(prefix="pcd_no_threads_")
    try:
        os.chmod(out, 0o755)
        site = copy_package_for_anyone(os.path.join(out, "site"))
        os.mkdir(os.path.join(out, "w"), 0o777)
        os.chmod(os.path.join(out, "w"), 0o777)
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONPATH=site)
        proc = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "prlimit", "--nproc=1",
                               sys.executable, "-c", NO_THREADS_PROBE, os.path.join(out, "w", "n.pcd")],
                              env=env, cwd=out, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
    finally:
        shutil.rmtree(out, ignore_errors=True)
