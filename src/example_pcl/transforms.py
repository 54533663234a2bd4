"""Rigid transforms: 4x4 float64 homogeneous matrices, pure NumPy (quaternions through SciPy).

Transforms are named ``T_a_from_b``: ``p_a = T_a_from_b @ p_b``, translations in metres. Every
function taking or returning a quaternion names its order: ROS messages (geometry_msgs, tf2)
use (x, y, z, w), PCD's VIEWPOINT uses (w, x, y, z). Knows nothing of ROS.
"""
import numpy as np
from scipy.spatial.transform import Rotation

from example_pcl.errors import PerceptionError


def as_transform(T):
    """T as a float64 (4, 4) array; raises PerceptionError naming the shape otherwise."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise PerceptionError(f"a transform must be a 4x4 matrix, got shape {T.shape}")
    return T


def apply(T, points):
    """points (..., 3) moved by the 4x4 transform T: R p + t, float64 of the same shape."""
    T = as_transform(T)
    return np.asarray(points, dtype=float) @ T[:3, :3].T + T[:3, 3]


def invert(T):
    """Inverse of a rigid 4x4 transform (float64): [R t] -> [R^T, -R^T t]."""
    T = as_transform(T)
    R, t = T[:3, :3], T[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ t
    return out


def compose(*transforms):
    """The product T_1 @ T_2 @ ... of 4x4 transforms (float64): compose(T_a_from_b, T_b_from_c)
    is T_a_from_c. With none, the identity."""
    out = np.eye(4)
    for T in transforms:
        out = out @ as_transform(T)
    return out


def _quaternion(q, order):
    q = np.asarray(q, dtype=float)
    if q.shape != (4,) or not np.isfinite(q).all() or not np.linalg.norm(q) > 1e-9:
        raise PerceptionError(f"a rotation must be a non-zero quaternion {order}, got {q!r}")
    return q


def matrix_from_quaternion_xyzw(quaternion_xyzw):
    """3x3 float64 rotation of a quaternion (x, y, z, w) (any non-zero length, normalised).
    Raises PerceptionError for a quaternion that is not 4 finite numbers or is zero."""
    return Rotation.from_quat(_quaternion(quaternion_xyzw, "(x, y, z, w)")).as_matrix()


def quaternion_xyzw_from_matrix(R):
    """Unit quaternion (x, y, z, w) of a 3x3 rotation matrix, float64 (4,), w >= 0."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        raise PerceptionError(f"a rotation must be a 3x3 matrix, got shape {R.shape}")
    q = Rotation.from_matrix(R).as_quat()
    return -q if q[3] < 0 else q


def quaternion_wxyz_from_xyzw(quaternion_xyzw):
    """(x, y, z, w) -> (w, x, y, z): ROS order to PCD VIEWPOINT order, float64 (4,)."""
    return np.roll(np.asarray(quaternion_xyzw, dtype=float), 1)


def quaternion_xyzw_from_wxyz(quaternion_wxyz):
    """(w, x, y, z) -> (x, y, z, w): PCD VIEWPOINT order to ROS order, float64 (4,)."""
    return np.roll(np.asarray(quaternion_wxyz, dtype=float), -1)


def from_translation_quaternion_xyzw(translation, quaternion_xyzw):
    """4x4 float64 from a translation (x, y, z) (m) and a quaternion (x, y, z, w), e.g. a tf2
    transform or a geometry_msgs/Pose."""
    T = np.eye(4)
    T[:3, :3] = matrix_from_quaternion_xyzw(quaternion_xyzw)
    T[:3, 3] = translation
    return T


def to_translation_quaternion_xyzw(T):
    """(translation (3,), unit quaternion (x, y, z, w) (4,)) of a 4x4 transform, float64."""
    T = as_transform(T)
    return T[:3, 3].copy(), quaternion_xyzw_from_matrix(T[:3, :3])


def from_translation_quaternion_wxyz(translation, quaternion_wxyz):
    """4x4 float64 from a translation (x, y, z) (m) and a quaternion (w, x, y, z), e.g. a PCD
    VIEWPOINT (origin, orientation)."""
    _quaternion(quaternion_wxyz, "(w, x, y, z)")
    return from_translation_quaternion_xyzw(translation, quaternion_xyzw_from_wxyz(quaternion_wxyz))


def to_translation_quaternion_wxyz(T):
    """(translation (3,), unit quaternion (w, x, y, z) (4,)) of a 4x4 transform, float64: a PCD
    VIEWPOINT's origin and orientation."""
    translation, q = to_translation_quaternion_xyzw(T)
    return translation, quaternion_wxyz_from_xyzw(q)


def up_vector(quaternion_xyzw):
    """The +z axis of a frame A expressed in a frame B, from the rotation (x, y, z, w) of the
    transform that takes A's coordinates into B's (tf2's lookup_transform(target_frame=B,
    source_frame=A)): unit float64 (3,). With A a robot's base_link or world, that is "up" in B.
    Raises PerceptionError for a quaternion that is not 4 finite numbers or is zero."""
    return matrix_from_quaternion_xyzw(quaternion_xyzw)[:, 2]
