"""Tests of example_pcl.transforms: rigid 4x4 transforms and quaternions in both orders (pure NumPy)."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from example_pcl import scene as sc
from example_pcl import transforms
from example_pcl.errors import PerceptionError


def random_rotations(n, seed=0):
    rng = np.random.default_rng(seed)
    out = [np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])]
    for _ in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        out.append(q * np.sign(np.linalg.det(q)))
    return out


def random_rigid(rng):
    """A random rigid transform (4x4)."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = q * np.sign(np.linalg.det(q)), rng.normal(size=3)
    return T


@pytest.mark.parametrize("R", random_rotations(20))
def test_quaternion_xyzw_round_trip(R):
    """matrix_from_quaternion_xyzw(quaternion_xyzw_from_matrix(R)) gives R back, the quaternion
    unit-length with w >= 0."""
    q = transforms.quaternion_xyzw_from_matrix(R)
    assert np.linalg.norm(q) == pytest.approx(1.0)
    assert q[3] >= 0
    assert_allclose(transforms.matrix_from_quaternion_xyzw(q), R, atol=1e-12)
    assert_allclose(transforms.from_translation_quaternion_xyzw((0, 0, 0), q)[:3, :3], R, atol=1e-12)


@pytest.mark.parametrize("R", random_rotations(10, seed=1))
def test_translation_quaternion_round_trips_in_both_orders(R):
    """to/from (translation, quaternion) give the transform back in the ROS order (x, y, z, w) and
    the PCD VIEWPOINT order (w, x, y, z), and the two quaternions are the same one reordered."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, (0.3, -1.2, 2.5)
    t_xyzw, q_xyzw = transforms.to_translation_quaternion_xyzw(T)
    t_wxyz, q_wxyz = transforms.to_translation_quaternion_wxyz(T)
    assert_allclose(t_xyzw, T[:3, 3])
    assert_allclose(t_wxyz, T[:3, 3])
    assert_allclose(q_wxyz, [q_xyzw[3], *q_xyzw[:3]])
    assert_allclose(transforms.from_translation_quaternion_xyzw(t_xyzw, q_xyzw), T, atol=1e-12)
    assert_allclose(transforms.from_translation_quaternion_wxyz(t_wxyz, q_wxyz), T, atol=1e-12)
    assert_allclose(transforms.quaternion_xyzw_from_wxyz(transforms.quaternion_wxyz_from_xyzw(q_xyzw)), q_xyzw)


def test_quaternion_orders_are_not_interchangeable():
    """90 deg about x is (s, 0, 0, s) in (x, y, z, w) order and (s, s, 0, 0) in (w, x, y, z) order:
    each function reads its own order (the identity is (0, 0, 0, 1) vs (1, 0, 0, 0))."""
    s = np.sqrt(0.5)
    about_x = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    assert_allclose(transforms.matrix_from_quaternion_xyzw((s, 0, 0, s)), about_x, atol=1e-12)
    assert_allclose(transforms.from_translation_quaternion_wxyz((0, 0, 0), (s, s, 0, 0))[:3, :3], about_x, atol=1e-12)
    assert_allclose(transforms.from_translation_quaternion_wxyz((1, 2, 3), (1, 0, 0, 0)),
                    [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]])
    assert_allclose(transforms.to_translation_quaternion_wxyz(np.eye(4))[1], (1, 0, 0, 0))
    assert_allclose(transforms.to_translation_quaternion_xyzw(np.eye(4))[1], (0, 0, 0, 1))


def test_invert_is_inverse():
    """invert(T) @ T and T @ invert(T) are the identity; it equals np.linalg.inv."""
    rng = np.random.default_rng(7)
    for _ in range(10):
        T = random_rigid(rng)
        Ti = transforms.invert(T)
        assert_allclose(Ti @ T, np.eye(4), atol=1e-12)
        assert_allclose(T @ Ti, np.eye(4), atol=1e-12)
        assert_allclose(Ti, np.linalg.inv(T), atol=1e-12)


def test_apply_matches_homogeneous_product_and_keeps_shape():
    """apply(T, p) is (T @ [p, 1])[:3] for points of shape (3,), (N, 3) and (H, W, 3); NaN stays NaN."""
    rng = np.random.default_rng(3)
    T = random_rigid(rng)
    for shape in ((3,), (7, 3), (4, 5, 3)):
        p = rng.normal(size=shape)
        homogeneous = np.concatenate([p.reshape(-1, 3), np.ones((p.size // 3, 1))], axis=1) @ T.T
        out = transforms.apply(T, p)
        assert out.shape == shape and out.dtype == np.float64
        assert_allclose(out.reshape(-1, 3), homogeneous[:, :3], atol=1e-12)
    assert np.isnan(transforms.apply(T, [np.nan, 0.0, 0.0])).all()


def test_compose_chains_frames():
    """compose(T_a_b, T_b_c) maps c-frame points as applying T_b_c then T_a_b; no argument is the identity."""
    rng = np.random.default_rng(4)
    T_ab, T_bc, T_cd = (random_rigid(rng) for _ in range(3))
    p = rng.normal(size=(6, 3))
    assert_allclose(transforms.apply(transforms.compose(T_ab, T_bc), p),
                    transforms.apply(T_ab, transforms.apply(T_bc, p)), atol=1e-12)
    assert_allclose(transforms.compose(T_ab, T_bc, T_cd), T_ab @ T_bc @ T_cd, atol=1e-12)
    assert_allclose(transforms.compose(), np.eye(4))
    assert_allclose(transforms.compose(T_ab, transforms.invert(T_ab)), np.eye(4), atol=1e-12)


@pytest.mark.parametrize("bad", [np.eye(3), np.zeros(16), np.eye(4)[:3]])
def test_transforms_must_be_4x4(bad):
    """A transform of another shape raises PerceptionError naming the shape."""
    for f in (transforms.invert, lambda T: transforms.apply(T, (0, 0, 0)), transforms.compose):
        with pytest.raises(PerceptionError, match="4x4"):
            f(bad)


@pytest.mark.parametrize("tilt, yaw", [(0.9, 0.0), (0.5, 0.4), (1.3, -2.0), (np.pi / 2, 1.0)])
def test_up_vector_of_a_tilted_camera_is_the_table_normal(tilt, yaw):
    """The +z of the table frame seen from a camera pitched `tilt` down (the rotation tf2 would
    give from the table frame into the camera's optical frame) is (0, -cos tilt, -sin tilt): up
    is the optical frame's -y turned toward -z, whatever the heading, as the camera does not roll."""
    camera_from_table = np.linalg.inv(sc.camera_pose(sc.SceneSpec(tilt=tilt, yaw=yaw)))
    up = transforms.up_vector(transforms.quaternion_xyzw_from_matrix(camera_from_table[:3, :3]))
    assert_allclose(up, (0.0, -np.cos(tilt), -np.sin(tilt)), atol=1e-12)
    assert np.linalg.norm(up) == pytest.approx(1.0)


def test_up_vector_identity_scale_and_bad_rotations():
    """The identity gives +z; a quaternion's length does not matter; a zero, non-finite or short
    quaternion is a PerceptionError."""
    assert_allclose(transforms.up_vector((0.0, 0.0, 0.0, 1.0)), (0.0, 0.0, 1.0))
    half = np.sqrt(0.5)  # 90 deg about x: the frame's +z is -y in the other frame
    assert_allclose(transforms.up_vector((5 * half, 0.0, 0.0, 5 * half)), (0.0, -1.0, 0.0), atol=1e-12)
    for bad in ((0.0, 0.0, 0.0, 0.0), (np.nan, 0.0, 0.0, 1.0), (0.0, 0.0, 1.0)):
        with pytest.raises(PerceptionError, match="quaternion"):
            transforms.up_vector(bad)
    with pytest.raises(PerceptionError, match=r"\(w, x, y, z\)"):
        transforms.from_translation_quaternion_wxyz((0, 0, 0), (0.0, 0.0, 0.0, 0.0))
