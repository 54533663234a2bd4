"""Tests of example_pcl.resources: the package's files found as rospack finds them."""
import pathlib
import sys
import types

from example_pcl import resources


def test_default_scene_is_the_bundled_scene():
    """The default scene is data/test_pcd.pcd inside the package."""
    assert resources.default_scene_path() == resources.package_path("data", "test_pcd.pcd")
    path = pathlib.Path(resources.default_scene_path())
    assert path.parts[-2:] == ("data", "test_pcd.pcd") and (path.parents[1] / "package.xml").is_file()


def test_package_path_asks_rospkg(monkeypatch):
    """The package directory is rospkg's answer (an install space's share/example_pcl, say)."""
    class RosPack:
        def get_path(self, name):
            assert name == "example_pcl"
            return "/opt/ros/share/example_pcl"

    monkeypatch.setitem(sys.modules, "rospkg", types.SimpleNamespace(RosPack=RosPack))
    assert resources.package_path("data", "x.pcd") == "/opt/ros/share/example_pcl/data/x.pcd"


def test_package_path_falls_back_to_the_checkout(monkeypatch):
    """Without the package on ROS_PACKAGE_PATH, the source tree the module was loaded from."""
    class RosPack:
        def get_path(self, name):
            raise LookupError(name)

    monkeypatch.setitem(sys.modules, "rospkg", types.SimpleNamespace(RosPack=RosPack))
    root = pathlib.Path(resources.package_path())
    assert (root / "package.xml").is_file() and (root / "src" / "example_pcl" / "resources.py").is_file()
