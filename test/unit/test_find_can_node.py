"""Tests of example_pcl.find_can_node's pure parts: its configuration (no master)."""
import pytest

from example_pcl.errors import PerceptionError
from example_pcl.find_can_node import FindCanConfig
from example_pcl.resources import package_path


def params(**values):
    return lambda name, default: values.get(name.lstrip("~"), default)


def test_config_defaults():
    """Without params: the bundled scene, frame 'world', no target frame, the issue's defaults."""
    config = FindCanConfig.from_params(params())
    assert config.pcd_file == package_path("data", "test_pcd.pcd")
    assert config.frame_id == "world" and config.target_frame == ""
    assert config.patch_radius == 0.03
    f = config.finder
    assert (f.z_eps, f.z_threshold, f.can_radius, f.can_height, f.r_eps) == (0.01, 0.01, 0.033, 0.122, 0.01)
    assert "z_eps=0.01 m" in config.describe()


def test_config_reads_params(tmp_path, monkeypatch):
    """Params are read; a relative pcd_file resolves against the working directory; leading
    slashes are dropped from frame ids."""
    monkeypatch.chdir(tmp_path)
    config = FindCanConfig.from_params(params(pcd_file="scene.pcd", frame_id="/map", target_frame="/base_link",
                                              z_eps=0.005, can_radius=0.04, max_iterations=7))
    assert config.pcd_file == str(tmp_path / "scene.pcd")
    assert (config.frame_id, config.target_frame) == ("map", "base_link")
    assert (config.finder.z_eps, config.finder.can_radius, config.finder.max_iterations) == (0.005, 0.04, 7)


@pytest.mark.parametrize("bad", [dict(z_eps=0), dict(can_height=-1), dict(patch_radius=0), dict(frame_id=""),
                                 dict(r_eps="wide"), dict(max_iterations=0)])
def test_config_rejects_bad_values(bad):
    """A param that cannot work stops the node with a PerceptionError naming it."""
    with pytest.raises(PerceptionError):
        FindCanConfig.from_params(params(**bad))


def test_config_reads_up_frame():
    """~up_frame defaults to none (no prior), is read without a leading slash and logged."""
    assert FindCanConfig.from_params(params()).up_frame == ""
    assert "up_frame=(none)" in FindCanConfig.from_params(params()).describe()
    config = FindCanConfig.from_params(params(up_frame="/base_link"))
    assert config.up_frame == "base_link" and "up_frame=base_link" in config.describe()
