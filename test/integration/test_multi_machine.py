"""ROS 1's graph across separate hosts (network namespaces): snapshot intact, stream resumed, services reach."""
import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tools"))
import netns_graph  # noqa: E402

REASON = netns_graph.netns_available()


@pytest.mark.skipif(REASON is not None, reason=f"network namespaces unavailable: {REASON}")
def test_graph_over_three_hosts(tmp_path):
    """roscore, pcd_publisher and pcd_save/find_can on three hosts: data intact, publisher restart survived."""
    from example_pcl import scene

    scene_path = tmp_path / "scene.pcd"
    scene.main([str(scene_path), "--format", "binary", "--seed", "3"])
    results = netns_graph.run_scenario(str(scene_path), str(tmp_path), log=print)
    assert results == {"snapshot_intact": True, "silent_while_publisher_dead": True, "resumed_after_restart": True,
                       "resumed_snapshot_intact": True, "service_across_hosts": True}, results
