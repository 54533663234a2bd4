"""Malformed PointCloud2 messages: each kind logged once as a warning and dropped; the node goes on to the next good one."""
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from graph_helpers import wait_for

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from malformed_sender import KINDS  # noqa: E402

from example_pcl import pcd  # noqa: E402

SENDER = str(pathlib.Path(__file__).resolve().parent / "malformed_sender.py")
pytestmark = pytest.mark.skipif(subprocess.run(["which", "roscore"], capture_output=True).returncode != 0,
                                reason="roscore missing: run `make test`, which installs ROS")


def test_pcd_save_drops_each_malformed_kind_once_then_saves(ros_graph, tmp_path):
    """pcd_save warns once per malformed kind (7 kinds sent twice each), keeps running and saves the good cloud."""
    out = tmp_path / "snap.pcd"
    saver = ros_graph.rosrun("pcd_save", "pcd_save", f"_file:={out}", "_format:=binary", "_timeout:=60")
    sender = ros_graph.start("sender", [sys.executable, SENDER, "/kinect/depth/points", str(tmp_path / "good.npz")])
    assert wait_for(lambda: saver.poll() is not None, 90), ros_graph.log(saver)
    ros_graph.stop(sender)
    log = ros_graph.log(saver)
    assert saver.returncode == 0, log
    warnings = [line for line in log.splitlines() if "dropping a malformed cloud" in line]
    assert len(warnings) == len(KINDS), "\n".join(warnings)
    good = np.load(tmp_path / "good.npz")["xyz"]
    np.testing.assert_array_equal(pcd.read_pcd(out).xyz, good)


def test_find_can_rejects_each_malformed_selection_once_then_takes_the_next(ros_graph, tmp_path):
    """find_can warns once per malformed kind on selected_points, keeps answering, and stores the next good selection."""
    from example_pcl import scene

    scene_path = tmp_path / "scene.pcd"
    scene.main([str(scene_path), "--format", "binary", "--seed", "4"])
    node = ros_graph.rosrun("find_can", "find_can", f"_pcd_file:={scene_path}")
    sender = ros_graph.start("sender", [sys.executable, SENDER, "/selected_points", str(tmp_path / "good.npz")])
    assert wait_for(lambda: "selection of" in ros_graph.log(node), 90), ros_graph.log(node)
    ros_graph.stop(sender)
    answer = subprocess.run(["rosservice", "call", "/process_mode", "7"], env=ros_graph.env, capture_output=True,
                            text=True, timeout=30)
    assert "unknown mode 7" in answer.stdout, answer.stdout + answer.stderr
    log = ros_graph.log(node)
    assert node.poll() is None, log
    warnings = [line for line in log.splitlines() if "selection rejected" in line and "[WARN]" in line]
    assert len(warnings) == len(KINDS), "\n".join(warnings)
