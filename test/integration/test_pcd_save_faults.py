"""pcd_save under faults: kill -9 mid-write, a full disk, its directory removed. Never a partial file under a final name."""
import os
import pathlib
import signal
import subprocess

import numpy as np
import pytest
from graph_helpers import wait_for

from example_pcl import pcd, scene

pytestmark = pytest.mark.skipif(subprocess.run(["which", "roscore"], capture_output=True).returncode != 0,
                                reason="roscore missing: run `make test`, which installs ROS")


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene.pcd"
    scene.main([str(path), "--format", "binary", "--seed", "5"])
    return path


def final_files(directory):
    return sorted(p for p in pathlib.Path(directory).glob("*.pcd") if not p.name.startswith("."))


def assert_all_complete(directory, reference):
    """Every PCD under a final name reads back equal to the published cloud."""
    files = final_files(directory)
    for path in files:
        points = pcd.read_pcd(path).points
        assert points.shape == reference.shape, path
        for name in reference.dtype.names:
            assert np.array_equal(points[name], reference[name], equal_nan=True), (path, name)
    return files


def test_kill_9_mid_write_leaves_no_partial_file(ros_graph, scene_file, tmp_path):
    """SIGKILL while pcd_save writes (3 rounds): every file under a final name is complete."""
    reference = pcd.read_pcd(scene_file).points
    ros_graph.rosrun("publisher", "pcd_publisher", f"_file:={scene_file}", "_rate:=15")
    out = tmp_path / "out"
    out.mkdir()
    temps_seen = 0
    for round_ in range(3):
        saver = ros_graph.rosrun(f"saver{round_}", "pcd_save", f"_file:={out}/r{round_}.pcd", "_count:=0",
                                 "_format:=binary_compressed")
        assert wait_for(lambda: len(list(out.glob(f"r{round_}_*.pcd"))) >= 2, 60), ros_graph.log(saver)
        # kill the moment a temporary file shows a write in flight
        wait_for(lambda: any(p.name.startswith(".") for p in out.iterdir()), 5, step=0.002)
        temps_seen += any(p.name.startswith(".") and p.suffix == ".tmp" for p in out.iterdir())
        os.killpg(saver.pid, signal.SIGKILL)
        saver.wait()
    files = assert_all_complete(out, reference)
    assert len(files) >= 6
    assert temps_seen >= 1, "no write was in flight at any kill: the test did not exercise a mid-write kill"


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a small tmpfs needs root")
def test_full_disk_then_space_freed(ros_graph, scene_file, tmp_path):
    """On a full tmpfs writes fail cleanly and are reported; once space is freed, continuous mode saves again."""
    reference = pcd.read_pcd(scene_file).points
    disk = tmp_path / "disk"
    disk.mkdir()
    one_file = os.path.getsize(scene_file)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={int(one_file * 1.6)}", "tmpfs", str(disk)], check=True)
    try:
        ros_graph.rosrun("publisher", "pcd_publisher", f"_file:={scene_file}", "_rate:=5")
        saver = ros_graph.rosrun("saver", "pcd_save", f"_file:={disk}/s.pcd", "_count:=0", "_format:=binary")
        assert wait_for(lambda: "carrying on" in ros_graph.log(saver), 60), ros_graph.log(saver)
        first = assert_all_complete(disk, reference)
        assert len(first) == 1  # room for one file only
        assert not any(p.name.startswith(".") for p in disk.iterdir())  # failed temporaries removed
        for path in first:
            path.unlink()
            pathlib.Path(str(path) + ".json").unlink(missing_ok=True)
        assert wait_for(lambda: len(final_files(disk)) >= 1, 30), ros_graph.log(saver)
        assert saver.poll() is None  # still running
        ros_graph.stop(saver)
        assert_all_complete(disk, reference)
    finally:
        subprocess.run(["umount", "-l", str(disk)])


def test_directory_removed_then_recreated(ros_graph, scene_file, tmp_path):
    """With its directory removed pcd_save reports failed writes and keeps running; recreated, it saves again."""
    reference = pcd.read_pcd(scene_file).points
    out = tmp_path / "gone"
    out.mkdir()
    ros_graph.rosrun("publisher", "pcd_publisher", f"_file:={scene_file}", "_rate:=5")
    saver = ros_graph.rosrun("saver", "pcd_save", f"_file:={out}/s.pcd", "_count:=0", "_format:=binary")
    assert wait_for(lambda: len(final_files(out)) >= 1, 60), ros_graph.log(saver)
    # pcd_save may create its next temporary file between rm's listing and its rmdir ("Directory
    # not empty"): remove until the directory is gone.
    assert wait_for(lambda: subprocess.run(["rm", "-rf", str(out)], capture_output=True).returncode == 0, 10)
    assert wait_for(lambda: "carrying on" in ros_graph.log(saver), 30), ros_graph.log(saver)
    assert saver.poll() is None
    out.mkdir()
    assert wait_for(lambda: len(final_files(out)) >= 1, 30), ros_graph.log(saver)
    ros_graph.stop(saver)
    assert saver.returncode == 0
    assert_all_complete(out, reference)

