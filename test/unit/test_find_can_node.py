"""Tests of example_pcl.find_can_node's pure parts: configuration and message building (no master)."""
import numpy as np
import pytest

from example_pcl import geometry
from example_pcl import scene as sc
from example_pcl.errors import PerceptionError
from example_pcl.find_can_node import (FindCanConfig, can_marker, matrix_from_transform, package_path, pose_message,
                                       quaternion_from_matrix, up_vector)


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


def random_rotations(n, seed=0):
    rng = np.random.default_rng(seed)
    out = [np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])]
    for _ in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        out.append(q * np.sign(np.linalg.det(q)))
    return out


@pytest.mark.parametrize("R", random_rotations(20))
def test_quaternion_round_trip(R):
    """matrix_from_transform(quaternion_from_matrix(R)) gives R back, the quaternion unit-length."""
    q = quaternion_from_matrix(R)
    assert np.linalg.norm(q) == pytest.approx(1.0)
    np.testing.assert_allclose(matrix_from_transform((0, 0, 0), q)[:3, :3], R, atol=1e-12)


def test_pose_message_is_the_transform():
    """pose_message carries the transform's origin and rotation in the given frame."""
    T = geometry.plane_frame((0.0, -0.62, -0.78), (0.1, 0.2, 1.0))
    msg = pose_message(T, "world")
    p, q = msg.pose.position, msg.pose.orientation
    assert msg.header.frame_id == "world"
    np.testing.assert_allclose(matrix_from_transform((p.x, p.y, p.z), (q.x, q.y, q.z, q.w)), T, atol=1e-12)


def test_marker_is_a_cylinder_centred_half_a_height_up():
    """can_marker is a CYLINDER of the can's diameter and height whose pose is the cylinder's centre."""
    from visualization_msgs.msg import Marker

    T = geometry.plane_frame((0.0, -0.62, -0.78), (0.0, 0.0, 1.0))
    marker = can_marker(T, 0.033, 0.122, "world")
    assert marker.type == Marker.CYLINDER and marker.action == Marker.ADD
    assert (marker.scale.x, marker.scale.y, marker.scale.z) == (0.066, 0.066, 0.122)
    p = marker.pose.position
    np.testing.assert_allclose([p.x, p.y, p.z], T[:3, 3] + 0.061 * T[:3, 2], atol=1e-12)
    assert marker.header.frame_id == "world" and marker.color.a > 0


def test_config_reads_up_frame():
    """~up_frame defaults to none (no prior), is read without a leading slash and logged."""
    assert FindCanConfig.from_params(params()).up_frame == ""
    assert "up_frame=(none)" in FindCanConfig.from_params(params()).describe()
    config = FindCanConfig.from_params(params(up_frame="/base_link"))
    assert config.up_frame == "base_link" and "up_frame=base_link" in config.describe()


@pytest.mark.parametrize("tilt, yaw", [(0.9, 0.0), (0.5, 0.4), (1.3, -2.0), (np.pi / 2, 1.0)])
def test_up_vector_of_a_tilted_camera_is_the_table_normal(tilt, yaw):
    """The +z of the table frame seen from a camera pitched `tilt` down (the rotation tf2 would
    give from the table frame into the camera's optical frame) is (0, -cos tilt, -sin tilt): up
    is the optical frame's -y turned toward -z, whatever the heading, as the camera does not roll."""
    camera_from_table = np.linalg.inv(sc.camera_pose(sc.SceneSpec(tilt=tilt, yaw=yaw)))
    up = up_vector(quaternion_from_matrix(camera_from_table[:3, :3]))
    np.testing.assert_allclose(up, (0.0, -np.cos(tilt), -np.sin(tilt)), atol=1e-12)
    assert np.linalg.norm(up) == pytest.approx(1.0)


def test_up_vector_identity_scale_and_bad_rotations():
    """The identity gives +z; a quaternion's length does not matter; a zero, non-finite or short
    quaternion is a PerceptionError."""
    np.testing.assert_allclose(up_vector((0.0, 0.0, 0.0, 1.0)), (0.0, 0.0, 1.0))
    half = np.sqrt(0.5)  # 90 deg about x: the frame's +z is -y in the other frame
    np.testing.assert_allclose(up_vector((5 * half, 0.0, 0.0, 5 * half)), (0.0, -1.0, 0.0), atol=1e-12)
    for bad in ((0.0, 0.0, 0.0, 0.0), (np.nan, 0.0, 0.0, 1.0), (0.0, 0.0, 1.0)):
        with pytest.raises(PerceptionError, match="quaternion"):
            up_vector(bad)
