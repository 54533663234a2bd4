"""example_pcl.snapshot, no master: pcd_save's config, file names, destination check, the write and its sidecar,
the writer threads."""
import json
import os
import threading
import time

import numpy as np
import pytest
from numpy.testing import assert_array_equal

pytest.importorskip("sensor_msgs.msg", reason="sensor_msgs not importable: source the devel space")
pytest.importorskip("example_pcl._native", reason="example_pcl._native not built: source the devel space")

from example_pcl import pcd  # noqa: E402
from example_pcl.conversions import array_to_cloud, fields_to_dtype, make_points  # noqa: E402
from example_pcl.errors import PerceptionError  # noqa: E402
from example_pcl.snapshot import (SaveConfig, SnapshotWriter, check_destination, cloud_metadata,  # noqa: E402
                                  packed_points, save_cloud, sidecar_path, snapshot_path, validate_cloud)


def kinect_cloud(height=12, width=16, seed=0, seq=0):
    """An organized PointCloud2 laid out as a Kinect driver sends it: x y z _ rgb _ _ _ (32 bytes), NaN holes."""
    rng = np.random.default_rng(seed)
    dtype = fields_to_dtype([("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 16, 7, 1)], 32)
    points = np.zeros((height, width), dtype)
    for c in "xyz":
        points[c] = rng.normal(size=(height, width)).astype(np.float32)
    points["x"][::3, ::4] = points["y"][::3, ::4] = points["z"][::3, ::4] = np.nan
    points["rgb"] = rng.integers(0, 1 << 24, size=(height, width), dtype=np.uint32).view(np.float32)
    msg = array_to_cloud(points, frame_id="camera_depth_optical_frame", is_dense=False)
    msg.header.seq = seq
    msg.header.stamp.secs, msg.header.stamp.nsecs = 1355496176, 332395000 + seq
    return msg


def assert_same_fields(saved, msg):
    """Every named field of the message is in the file with the same shape and the same bits."""
    sent = validate_cloud(msg)
    assert saved.shape == sent.shape
    assert set(saved.dtype.names) == set(sent.dtype.names)
    for name in sent.dtype.names:
        assert_array_equal(np.ascontiguousarray(saved[name]).view(np.uint32),
                           np.ascontiguousarray(sent[name]).view(np.uint32), err_msg=name)


def test_snapshot_path_single_is_the_file_itself():
    """count 1 writes ~file itself."""
    assert snapshot_path("/d/test_pcd.pcd", 0, 1) == "/d/test_pcd.pcd"


@pytest.mark.parametrize("count", [0, 2, 100])
def test_snapshot_path_numbered_sorts_in_order(count):
    """count N or 0 numbers the files with six digits, keeping the extension, so names sort in order."""
    names = [snapshot_path("/d/test_pcd.pcd", i, count) for i in (0, 1, 9, 10, 999999)]
    assert names[0] == "/d/test_pcd_000000.pcd" and names == sorted(names)
    assert snapshot_path("/d/cloud", 3, count) == "/d/cloud_000003"


def test_sidecar_path():
    """The sidecar is <file>.json beside the PCD file."""
    assert sidecar_path("/d/test_pcd_000001.pcd") == "/d/test_pcd_000001.pcd.json"


def test_config_defaults_and_validation():
    """Defaults match the issue (test_pcd.pcd in the cwd, ascii, one snapshot); bad values are refused."""
    config = SaveConfig.from_params(lambda name, default: default)
    assert config.file == os.path.abspath("test_pcd.pcd") and config.format == "ascii" and config.count == 1
    for name, value in [("format", "pcd"), ("count", -1), ("timeout", -2), ("queue_size", 0), ("writers", 0),
                        ("count", "many")]:
        with pytest.raises(PerceptionError, match=name if name != "count" or value != "many" else "bad parameter"):
            SaveConfig.from_params(lambda n, d: value if n == "~" + name else d)
    assert SaveConfig.from_params(lambda n, d: "BINARY" if n == "~format" else d).format == "binary"


def test_check_destination_accepts_a_writable_directory(tmp_path):
    """A file in an existing writable directory passes, and the check leaves nothing behind."""
    check_destination(str(tmp_path / "out.pcd"))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("case", ["missing_dir", "parent_is_file", "is_directory"])
def test_check_destination_refuses_unwritable(tmp_path, case):
    """A missing directory, a parent that is a file and a destination that is a directory are refused, by name."""
    (tmp_path / "afile").write_text("x")
    (tmp_path / "adir").mkdir()
    path = {"missing_dir": tmp_path / "nope" / "out.pcd", "parent_is_file": tmp_path / "afile" / "out.pcd",
            "is_directory": tmp_path / "adir"}[case]
    with pytest.raises(PerceptionError, match="cannot save to"):
        check_destination(str(path))


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_check_destination_refuses_read_only_directory(tmp_path):
    """A directory without write permission is refused."""
    tmp_path.chmod(0o500)
    try:
        with pytest.raises(PerceptionError, match="not writable"):
            check_destination(str(tmp_path / "out.pcd"))
    finally:
        tmp_path.chmod(0o700)


def test_packed_points_drops_padding_only():
    """A 32-byte x y z _ rgb _ point becomes 16 bytes x y z rgb with the same values; a packed one is untouched."""
    msg = kinect_cloud()
    view = validate_cloud(msg)
    packed = packed_points(view)
    assert packed.dtype.itemsize == 16 and packed.dtype.names == ("x", "y", "z", "rgb")
    assert packed.flags.c_contiguous
    assert_same_fields(packed, msg)
    tight = make_points(np.zeros((2, 3, 3), np.float32), np.zeros((2, 3, 3), np.uint8))
    assert packed_points(tight) is tight


@pytest.mark.parametrize("fmt", pcd.FORMATS)
def test_save_cloud_round_trip(tmp_path, fmt):
    """Saved then read back: every field bit-exact (ascii too, at 9 digits), organized shape, NaNs, is_dense."""
    msg = kinect_cloud()
    path = str(tmp_path / "test_pcd.pcd")
    save_cloud(path, msg, fmt, "/kinect/depth/points", publisher="/pcd_publisher")
    cloud = pcd.read_pcd(path)
    assert cloud.format == fmt and cloud.is_dense is False and cloud.organized
    assert_same_fields(cloud.points, msg)
    assert np.isnan(cloud.xyz).any(axis=-1).sum() == np.isnan(validate_cloud(msg)["x"]).sum()
    assert sorted(os.listdir(tmp_path)) == ["test_pcd.pcd", "test_pcd.pcd.json"]  # no temporary files left


def test_save_cloud_ascii_to_print_precision(tmp_path):
    """ascii values equal the published ones to the printed precision (9 significant digits)."""
    msg = kinect_cloud(seed=3)
    path = str(tmp_path / "a.pcd")
    save_cloud(path, msg, "ascii", "/t")
    saved, sent = pcd.read_pcd(path).points, validate_cloud(msg)
    for c in "xyz":
        np.testing.assert_allclose(saved[c], sent[c], rtol=1e-8, equal_nan=True)


def test_sidecar_records_frame_stamp_and_layout(tmp_path):
    """The sidecar holds frame_id, stamp, seq, topic, publisher, shape, fields and the wall time of the save."""
    msg = kinect_cloud(seq=41)
    path = str(tmp_path / "s.pcd")
    before = time.time()
    save_cloud(path, msg, "binary", "/kinect/depth/points", publisher="/pcd_publisher")
    meta = json.loads((tmp_path / "s.pcd.json").read_text())
    assert meta["frame_id"] == "camera_depth_optical_frame"
    assert meta["stamp"] == {"secs": 1355496176, "nsecs": 332395041} and meta["seq"] == 41
    assert meta["topic"] == "/kinect/depth/points" and meta["publisher"] == "/pcd_publisher"
    assert (meta["width"], meta["height"], meta["is_dense"], meta["point_step"]) == (16, 12, False, 32)
    assert [f["name"] for f in meta["fields"]] == ["x", "y", "z", "rgb"]
    assert meta["pcd_file"] == "s.pcd" and meta["format"] == "binary"
    assert before <= meta["saved_wall_time"] <= time.time()
    assert meta == cloud_metadata(msg, "/kinect/depth/points", path, "binary", "/pcd_publisher",
                                  saved_at=meta["saved_wall_time"])


def test_save_cloud_failure_leaves_nothing_under_the_final_name(tmp_path, monkeypatch):
    """A write that fails half-way (disk full) leaves neither the PCD file, its sidecar nor a temporary file."""
    def half_write(tmp, data, *args):
        with open(tmp, "wb") as f:
            f.write(b"# .PCD v0.7 half a file")
        raise RuntimeError("No space left on device")

    monkeypatch.setattr(pcd._native, "write_pcd", half_write)
    with pytest.raises(OSError, match="No space left"):
        save_cloud(str(tmp_path / "full.pcd"), kinect_cloud(), "binary", "/t")
    assert os.listdir(tmp_path) == []


def test_save_cloud_keeps_an_older_file_when_the_new_write_fails(tmp_path, monkeypatch):
    """Overwriting is atomic too: a failed write leaves the previous snapshot intact."""
    path = str(tmp_path / "keep.pcd")
    save_cloud(path, kinect_cloud(seed=1), "binary", "/t")
    before = open(path, "rb").read()
    monkeypatch.setattr(pcd._native, "write_pcd", lambda *a: (_ for _ in ()).throw(RuntimeError("disk full")))
    with pytest.raises(OSError):
        save_cloud(path, kinect_cloud(seed=2), "binary", "/t")
    assert open(path, "rb").read() == before
    assert sorted(os.listdir(tmp_path)) == ["keep.pcd", "keep.pcd.json"]


@pytest.mark.parametrize("breakage,match", [
    (lambda m: setattr(m, "is_bigendian", True), "big-endian"),
    (lambda m: setattr(m, "data", m.data[:-5]), "data has"),
    (lambda m: setattr(m.fields[3], "offset", 30), "runs past point_step"),
    (lambda m: (setattr(m, "width", 0), setattr(m, "height", 0), setattr(m, "data", b"")), "empty cloud"),
])
def test_validate_cloud_rejects_malformed(breakage, match):
    """Malformed messages (big-endian, short data, fields past point_step, empty) raise PerceptionError."""
    msg = kinect_cloud()
    breakage(msg)
    with pytest.raises(PerceptionError, match=match):
        validate_cloud(msg)


def wait_done(writer, timeout=20.0):
    assert writer.done.wait(timeout), "writer did not finish"


@pytest.mark.parametrize("fmt", ["binary", "binary_compressed"])
def test_snapshot_writer_writes_count_numbered_files(tmp_path, fmt):
    """count N: exactly N numbered files with sidecars, in arrival order, then done; later clouds are ignored."""
    config = SaveConfig(file=str(tmp_path / "snap.pcd"), format=fmt, count=3, queue_size=8, writers=2)
    writer = SnapshotWriter(config, "/t").start()
    msgs = [kinect_cloud(seed=i, seq=i + 1) for i in range(5)]
    for msg in msgs:
        writer.submit(msg)
    wait_done(writer)
    writer.stop()
    assert writer.error is None and writer.saved == 3
    names = sorted(os.listdir(tmp_path))
    assert names == [f"snap_00000{i}.pcd{ext}" for i in range(3) for ext in ("", ".json")]
    for i in range(3):
        meta = json.loads((tmp_path / f"snap_00000{i}.pcd.json").read_text())
        assert_same_fields(pcd.read_pcd(str(tmp_path / meta["pcd_file"])).points, msgs[meta["seq"] - 1])
    assert sorted(json.loads((tmp_path / f"snap_00000{i}.pcd.json").read_text())["seq"] for i in range(3)) == [1, 2, 3]


def test_snapshot_writer_counts_queue_discards_when_writes_are_slow(tmp_path):
    """A slow writer never blocks submit: the bounded queue discards the oldest clouds and counts them."""
    release = threading.Event()

    def slow_save(path, msg, fmt, topic, publisher, points=None):
        release.wait(10)
        return {}

    config = SaveConfig(file=str(tmp_path / "x.pcd"), format="binary", count=0, queue_size=2, writers=1)
    writer = SnapshotWriter(config, "/t", save=slow_save).start()
    msg = kinect_cloud()
    start = time.monotonic()
    for seq in range(1, 11):
        msg.header.seq = seq
        writer.submit(msg)
        time.sleep(0.01)
    assert time.monotonic() - start < 2.0
    # one cloud in the writer, two queued, the other seven discarded
    assert writer.drops.queue_discards == 7 and writer.drops.seq_gaps == 0
    release.set()
    writer.stop()
    assert writer.saved >= 1 and writer.drops.dropped == 7


def test_snapshot_writer_skips_rejected_clouds_and_stops_on_os_error(tmp_path):
    """A cloud the writer rejects does not count as a snapshot; an OSError stops the writer and is kept."""
    rejected = []
    calls = []

    def flaky_save(path, msg, fmt, topic, publisher, points=None):
        calls.append(path)
        if len(calls) == 1:
            raise PerceptionError("PCL refused it")
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        return {}

    config = SaveConfig(file=str(tmp_path / "x.pcd"), format="binary", count=5, queue_size=8, writers=1)
    writer = SnapshotWriter(config, "/t", save=flaky_save, on_reject=rejected.append).start()
    for seq in range(1, 5):
        msg = kinect_cloud(seq=seq)
        writer.submit(msg)
    wait_done(writer)
    writer.stop()
    assert len(rejected) == 1 and writer.saved == 1
    assert isinstance(writer.error, OSError) and writer.error.errno == 28


def test_continuous_writer_carries_on_after_transient_os_errors(tmp_path):
    """In continuous mode (count 0) failed writes are counted and reported, and later clouds are still saved."""
    errors = []
    calls = []

    def full_then_free(path, msg, fmt, topic, publisher, points=None):
        calls.append(path)
        if len(calls) in (2, 3):
            raise OSError(28, "No space left on device")
        return {}

    config = SaveConfig(file=str(tmp_path / "x.pcd"), format="binary", count=0, queue_size=8, writers=1)
    writer = SnapshotWriter(config, "/t", save=full_then_free, on_write_error=errors.append).start()
    for seq in range(1, 6):
        writer.submit(kinect_cloud(seq=seq))
    deadline = time.monotonic() + 10
    while writer.saved + writer.failed < 5 and time.monotonic() < deadline:
        time.sleep(0.01)
    writer.stop()
    assert writer.error is None and not writer.done.is_set()
    assert (writer.saved, writer.failed, len(errors)) == (3, 2, 2)
