"""pcd_publisher's pure logic and launch/pcd_save.launch, no master."""
import os
import pathlib

import numpy as np
import pytest
from numpy.testing import assert_array_equal

pytest.importorskip("sensor_msgs.msg", reason="sensor_msgs not importable: source the devel space")
pytest.importorskip("example_pcl._native", reason="example_pcl._native not built: source the devel space")

from example_pcl import pcd  # noqa: E402
from example_pcl.conversions import cloud_to_array, make_points  # noqa: E402
from example_pcl.errors import PerceptionError  # noqa: E402
from example_pcl.pcd_publisher_node import PublisherConfig, load_cloud_message  # noqa: E402
from example_pcl.resources import default_scene_path  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("fmt", pcd.FORMATS)
def test_load_cloud_message_keeps_every_field(tmp_path, fmt):
    """The published message holds the file's fields bit for bit, organized H x W, NaNs, is_dense, the frame id."""
    rng = np.random.default_rng(5)
    xyz = rng.normal(size=(6, 8, 3)).astype(np.float32)
    xyz[1, 2] = np.nan
    points = make_points(xyz, rng.integers(0, 256, size=(6, 8, 3), dtype=np.uint8))
    path = str(tmp_path / "in.pcd")
    pcd.write_pcd(path, points, fmt=fmt)
    msg = load_cloud_message(path, "camera_depth_optical_frame")
    assert (msg.height, msg.width, msg.is_dense) == (6, 8, False)
    assert msg.header.frame_id == "camera_depth_optical_frame"
    sent = cloud_to_array(msg)
    for name in points.dtype.names:
        assert_array_equal(np.ascontiguousarray(sent[name]).view(np.uint32), points[name].view(np.uint32))


def test_load_cloud_message_names_a_missing_file(tmp_path):
    """A missing file is a PerceptionError naming it; the missing bundled scene says how to make it."""
    with pytest.raises(PerceptionError, match="nope.pcd"):
        load_cloud_message(str(tmp_path / "nope.pcd"), "f")
    if not os.path.exists(default_scene_path()):
        with pytest.raises(PerceptionError, match="make_scene"):
            load_cloud_message(default_scene_path(), "f")


def test_config_defaults_and_validation():
    """Defaults: the bundled scene, 1 Hz, camera_depth_optical_frame; a leading slash is dropped; bad values refused."""
    config = PublisherConfig.from_params(lambda name, default: default)
    assert config.file == default_scene_path() and config.file.endswith(os.path.join("data", "test_pcd.pcd"))
    assert (config.rate, config.frame_id) == (1.0, "camera_depth_optical_frame")
    assert PublisherConfig.from_params(lambda n, d: "/cam" if n == "~frame_id" else d).frame_id == "cam"
    with pytest.raises(PerceptionError, match="rate"):
        PublisherConfig.from_params(lambda n, d: -1 if n == "~rate" else d)
    with pytest.raises(PerceptionError, match="frame_id"):
        PublisherConfig.from_params(lambda n, d: "/" if n == "~frame_id" else d)


def test_launch_file_brings_up_publisher_and_saver():
    """launch/pcd_save.launch: publisher and saver with file, format, rate (and count, out) passed through."""
    roslaunch = pytest.importorskip("roslaunch")
    os.environ.setdefault("ROS_PACKAGE_PATH", str(ROOT.parent))
    try:
        import rospkg

        rospkg.RosPack().get_path("example_pcl")
    except Exception:
        pytest.skip("example_pcl not on ROS_PACKAGE_PATH: source the devel space")
    args = ["file:=/data/in.pcd", "format:=binary", "rate:=30", "count:=0", "out:=/tmp/o.pcd"]
    import roslaunch.config
    import roslaunch.xmlloader

    config = roslaunch.config.ROSLaunchConfig()
    roslaunch.xmlloader.XmlLoader().load(str(ROOT / "launch" / "pcd_save.launch"), config, argv=["roslaunch"] + args,
                                         verbose=False)
    nodes = {n.type: n for n in config.nodes}
    assert set(nodes) == {"pcd_publisher", "pcd_save"}
    params = {k: p.value for k, p in config.params.items()}
    assert params["/pcd_publisher/file"] == "/data/in.pcd" and params["/pcd_publisher/rate"] == 30
    assert params["/pcd_save/format"] == "binary" and params["/pcd_save/count"] == 0
    assert params["/pcd_save/file"] == "/tmp/o.pcd"
    assert nodes["pcd_save"].required
