"""Table plane, plane frame, patches and the can's cylinder fit: pure functions on NumPy arrays.

Units are metres and radians. "Sensor" is the camera optical frame the cloud arrives in (x right,
y down, z forward). The *plane frame* has its z axis along the table normal (toward the sensor),
its origin on the table and its x axis as close as possible to the sensor's x axis, so a can
standing on the table is a circle of constant radius in the plane frame's x, y.

Transforms are 4x4 float64 homogeneous matrices named ``T_a_from_b``: ``p_a = T_a_from_b @ p_b``
(example_pcl.transforms applies, inverts and composes them).

Work over whole scenes (transforming, banding, extracting) goes through the compiled core,
``example_pcl._native`` (PCL and Eigen); operator selections and fits are small and stay in NumPy.
Every domain failure raises :class:`~example_pcl.errors.PerceptionError` saying what to do next.
"""
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from example_pcl import _native
from example_pcl import transforms
from example_pcl.errors import PerceptionError

# --- results --------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Plane:
    """A plane ``normal . p + d = 0`` in the sensor frame.

    normal: unit float64 (3,), turned toward the viewpoint (sensor); d: offset (m), the sensor's
    distance from the plane when the viewpoint is the sensor at the origin; centroid: float64 (3,)
    of the points it was fitted to (m); curvature: l0 / (l0 + l1 + l2) of their covariance
    (0 = flat); n_points: how many points it was fitted to.
    """

    normal: np.ndarray
    d: float
    centroid: np.ndarray
    curvature: float
    n_points: int

    @property
    def coefficients(self):
        """[nx, ny, nz, d] as float64 (4,), the layout PCL uses."""
        return np.append(self.normal, self.d)

    def signed_distance(self, points):
        """Signed distance (m) of points (..., 3) from the plane, positive on the normal's side."""
        return np.asarray(points, dtype=float) @ self.normal + self.d

    @classmethod
    def through(cls, normal, centroid, viewpoint, curvature=0.0, n_points=0):
        """The plane through `centroid` (float64 (3,), m) with the unit `normal` turned toward
        `viewpoint` (m, same frame).

        d is computed from the turned normal, so it flips with it and normal . centroid + d = 0
        always holds (the original seed flipped the normal but kept PCL's d).
        """
        if normal @ (viewpoint - centroid) < 0:
            normal = -normal
        return cls(normal=normal, d=float(-normal @ centroid), centroid=centroid,
                   curvature=float(curvature), n_points=int(n_points))


@dataclass(frozen=True, eq=False)
class CylinderFit:
    """The result of a circle fit in the plane frame's x, y (the can seen from above).

    cx, cy: centre (m, plane frame); radius (m; the given one for fit_cylinder_center);
    rms_error: root mean square radial residual of the inliers (m); iterations: taken;
    n_inliers: points with |residual| <= r_eps at the end; converged: the last step was below
    tol; arc_coverage: angular span of the inliers around the centre (rad, 0..2 pi; about pi
    for the visible half of a can); inliers: int64 indices of the inliers into the xy passed in.
    """

    cx: float
    cy: float
    radius: float
    rms_error: float
    iterations: int
    n_inliers: int
    converged: bool
    arc_coverage: float
    inliers: np.ndarray

    @property
    def center(self):
        """(cx, cy) as float64 (2,), metres in the plane frame."""
        return np.array([self.cx, self.cy])


# --- helpers --------------------------------------------------------------------------------------


def as_points_float32(points):
    """points as float32 (N, 3) or (H, W, 3) for the native core; a float32 array is passed as is
    (any strides, no copy). Raises PerceptionError for any other shape."""
    pts = np.asarray(points, dtype=np.float32)
    if pts.ndim not in (2, 3) or pts.shape[-1] != 3:
        raise PerceptionError(f"points must be an array of shape (N, 3) or (H, W, 3), got shape {pts.shape}")
    return pts


def as_vector3(v, name):
    """v as float64 (3,); raises PerceptionError naming `name` unless it is 3 finite numbers."""
    v = np.asarray(v, dtype=float)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise PerceptionError(f"{name} must be 3 finite numbers, got {v!r}")
    return v


def unit_vector(v, name):
    """v / |v| as float64 (3,); raises PerceptionError naming `name` unless it is 3 finite
    numbers, not all zero."""
    v = as_vector3(v, name)
    norm = np.linalg.norm(v)
    if not norm > 0:
        raise PerceptionError(f"{name} must be a non-zero vector, got {v!r}")
    return v / norm


def subsample(points, step):
    """A regular subsample of a cloud, as a strided view (no copy): an organized (H, W, 3) cloud
    keeps every step-th pixel in both directions, an unorganized (N, 3) one every (step * step)-th
    point, so both keep about 1 / step^2 of the points. step: int >= 1."""
    step = max(int(step), 1)
    return points[::step, ::step] if points.ndim == 3 else points[::step * step]


# --- patches and planes ---------------------------------------------------------------------------


def clean_patch(points):
    """The operator's selection, cleaned: float64 (K, 3), metres, sensor frame.

    points: (N, 3) or (H, W, 3), any float dtype. Non-finite points are dropped; then, about
    the centroid of the rest, points whose distance r_i exceeds mean(r) + std(r) are dropped
    (stray points from behind or beside the patch). The rule is on distances, not on squared
    distances: the original seed kept r_i^2 < mean(r^2), which is not "within one standard
    deviation".

    Raises PerceptionError when fewer than 3 points remain: select a larger patch.
    """
    pts = np.asarray(points, dtype=float)
    if pts.size == 0:
        raise PerceptionError("the patch is empty; select a larger patch")
    if pts.shape[-1] != 3:
        raise PerceptionError(f"a patch must be points of shape (N, 3) or (H, W, 3), got shape {pts.shape}")
    pts = pts.reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) < 3:
        raise PerceptionError(f"the patch has {len(pts)} finite point(s); select a larger patch")
    center = pts.mean(axis=0)
    r = np.linalg.norm(pts - center, axis=1)
    # A rounding allowance so equidistant points (std 0) are all kept, at any coordinate size.
    slack = 1e-12 * (np.abs(center).max() + r.mean())
    kept = pts[r <= r.mean() + r.std() + slack]
    if len(kept) < 3:
        raise PerceptionError(f"only {len(kept)} point(s) of the patch are near its centre; select a larger patch")
    return kept


def patch_plane(points, viewpoint=(0.0, 0.0, 0.0), line_ratio=1e-4):
    """Least-squares plane of an operator's patch, normal toward the viewpoint: a Plane.

    points: (N, 3) or (H, W, 3) sensor-frame points (m), cleaned by clean_patch. The plane comes
    from PCL's computePointNormal (native), fed the points relative to their centroid so large
    coordinates keep float32 precision; d follows the normal when it is turned toward
    `viewpoint` (sensor frame, m; the sensor itself by default).

    Raises PerceptionError for fewer than 3 usable points, or when the patch is a line or a
    point: its second-largest covariance eigenvalue is below `line_ratio` times the largest.
    """
    viewpoint = as_vector3(viewpoint, "viewpoint")
    pts = clean_patch(points)
    centroid = pts.mean(axis=0)
    rel = pts - centroid
    eig = np.linalg.eigvalsh(rel.T @ rel / len(rel))  # ascending
    if not eig[2] > 0 or eig[1] <= line_ratio * eig[2]:
        raise PerceptionError("the patch is a line (or a single point); select an area of the surface")
    coefficients, curvature = _native.compute_point_normal(rel.astype(np.float32))
    normal = coefficients[:3].astype(float)
    normal /= np.linalg.norm(normal)
    return Plane.through(normal, centroid, viewpoint, curvature, len(pts))


def plane_frame(normal, origin, sensor_x=(1.0, 0.0, 0.0)):
    """T_sensor_from_plane (4x4 float64) of a plane frame.

    z along `normal` (sensor frame, need not be unit), origin at `origin` (m, sensor frame; a
    point on the plane), x the sensor's x axis `sensor_x` projected onto the plane (so the
    frame is as little rotated from the sensor as the plane allows), y = z x x. When sensor_x
    is (nearly) parallel to the normal, the sensor's y axis is projected instead.
    """
    z = unit_vector(normal, "normal")
    origin = as_vector3(origin, "origin")
    for reference in (unit_vector(sensor_x, "sensor_x"), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])):
        x = reference - (reference @ z) * z
        norm = np.linalg.norm(x)
        if norm > 1e-3:  # more than ~0.06 degrees from the normal: a well-defined direction
            break
    x /= norm
    T = np.eye(4)
    # z x x written out: np.cross costs tens of microseconds, and this runs every tracked frame.
    T[:3, 0], T[:3, 2], T[:3, 3] = x, z, origin
    T[:3, 1] = z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]
    return T


def plane_inliers(points, T_sensor_from_plane, z_eps):
    """Points within z_eps (m) of the plane z = 0 of a plane frame.

    points: float32 (N, 3) or (H, W, 3) sensor-frame cloud (a float32 view is not copied).
    Returns (indices, points_in_plane_frame): int64 indices into the flattened cloud, and the
    whole cloud transformed into the plane frame (float32, same shape; NaN stays NaN).
    """
    pts = as_points_float32(points)
    in_plane = _native.transform_cloud(pts, transforms.invert(T_sensor_from_plane))
    return _native.filter_z_band(in_plane, 0.0, float(z_eps)), in_plane


def refine_plane(points, plane, z_eps, viewpoint=(0.0, 0.0, 0.0), iterations=3, final_inliers=True):
    """Mode 0's refinement: the table plane from a small or slightly tilted patch plane.

    Each iteration puts a plane frame on the current plane (origin: the current centroid
    projected onto it), takes the cloud's points within z_eps (m) of it, and fits a least-squares
    plane to them (native computePointNormal, in the plane frame where coordinates are small),
    turned toward `viewpoint`. A patch normal off by a few degrees still meets the table in a
    band many centimetres wide, whose points are all table: one pass already corrects most of
    the tilt, the next ones the rest. Stops early once the plane no longer moves.

    points: float32 (N, 3) or (H, W, 3) sensor-frame cloud; plane: the starting Plane;
    iterations: at most this many passes.
    Returns (Plane, T_sensor_from_plane, inlier indices, passes): the refined plane, the plane
    frame on it, the int64 indices (flattened cloud) of the points within z_eps of it (None with
    final_inliers=False, which saves a pass over the cloud), and how many passes ran (the last
    one the pass that found the plane no longer moving, if it stopped).
    Raises PerceptionError when fewer than 3 points lie in the band.
    """
    viewpoint = as_vector3(viewpoint, "viewpoint")
    if not z_eps > 0:
        raise PerceptionError(f"z_eps must be > 0 m, got {z_eps}")
    pts = as_points_float32(points)

    def frame_on(p):
        return plane_frame(p.normal, p.centroid - p.signed_distance(p.centroid) * p.normal)

    passes = 0
    for passes in range(1, max(int(iterations), 1) + 1):
        T = frame_on(plane)
        idx, in_plane = plane_inliers(pts, T, z_eps)
        if len(idx) < 3:
            raise PerceptionError(f"only {len(idx)} point(s) lie within {z_eps} m of the patch plane; "
                                  "select a patch on the table or raise z_eps")
        coefficients, curvature = _native.compute_point_normal(in_plane, idx)
        normal = T[:3, :3] @ coefficients[:3].astype(float)
        normal /= np.linalg.norm(normal)
        centroid = transforms.apply(T, _native.centroid(in_plane, idx))
        previous = plane
        plane = Plane.through(normal, centroid, viewpoint, curvature, len(idx))
        if (abs(plane.d - previous.d) < 1e-7 and plane.normal @ previous.normal > 1 - 1e-12):
            break
    T = frame_on(plane)
    idx = plane_inliers(pts, T, z_eps)[0] if final_inliers else None
    return plane, T, idx, passes


def points_above_plane(points_in_plane_frame, z_threshold, max_height=None):
    """Indices (int64, flattened) of plane-frame points with z > z_threshold (m), and z <=
    max_height when given: what stands on the table, neither table nor floor (below it).

    points_in_plane_frame: float32 (N, 3) or (H, W, 3), e.g. from plane_inliers. NaN never kept.
    """
    pts = as_points_float32(points_in_plane_frame)
    idx = _native.filter_above_z(pts, float(z_threshold))
    if max_height is not None:
        idx = idx[_native.extract(pts, idx)[:, 2] <= max_height]
    return idx


# --- the can --------------------------------------------------------------------------------------


def initial_can_center(patch_centroid_plane, radius, sensor_origin_plane):
    """First guess (cx, cy) (m, plane frame) of a can's axis from a patch on its side.

    The patch lies on the side facing the sensor, so the axis is about one radius further from
    the sensor than the patch: the patch centroid's (x, y) is moved `radius` along the horizontal
    direction from the sensor's projection onto the plane to the centroid. (The seed used the
    centroid itself, a radius short.) sensor_origin_plane: the sensor's position in the plane
    frame, transforms.invert(T_sensor_from_plane)[:3, 3]. Directly below the sensor there is no
    such direction and the centroid is returned.
    """
    c = np.asarray(patch_centroid_plane, dtype=float)[:2]
    away = c - np.asarray(sensor_origin_plane, dtype=float)[:2]
    norm = np.linalg.norm(away)
    if norm < 1e-9:
        return float(c[0]), float(c[1])
    c = c + radius * away / norm
    return float(c[0]), float(c[1])


def make_can_cloud(radius, height, n_around=48, n_along=16, rim_ratio=0.85):
    """Model points of a can in the can frame (origin at the base centre, z up the axis): float32 (N, 3).

    n_along rings of n_around points on the side from z = 0 to z = height (m), plus the lid's
    rim: a ring of n_around points at z = height, rim_ratio * radius from the axis.
    """
    if not (radius > 0 and height > 0 and n_around >= 3 and n_along >= 2):
        raise PerceptionError("a can model needs radius, height > 0 m, n_around >= 3, n_along >= 2")
    angle = np.linspace(0, 2 * np.pi, int(n_around), endpoint=False)
    ring = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    side = [np.column_stack([radius * ring, np.full(len(ring), z)]) for z in np.linspace(0, height, int(n_along))]
    rim = np.column_stack([rim_ratio * radius * ring, np.full(len(ring), height)])
    return np.concatenate(side + [rim]).astype(np.float32)


def can_pose(T_sensor_from_plane, cx, cy, z=0.0):
    """T_sensor_from_can (4x4 float64): the plane frame moved to (cx, cy, z) (m, plane frame), so
    its origin is the centre of the can's base (z above the table: a can standing on something) and
    its z the table normal."""
    shift = np.eye(4)
    shift[:3, 3] = cx, cy, z
    return np.asarray(T_sensor_from_plane, dtype=float) @ shift


def footprint_center(base_center, axis, height, lying):
    """The middle of a can's footprint (m, the frame of base_center and axis): its base centre when
    upright, the middle of its axis when lying (which does not depend on the end its pose starts from)."""
    return np.asarray(base_center, dtype=float) + (0.5 * height * np.asarray(axis, dtype=float) if lying else 0.0)


def lying_can_pose(T_sensor_from_plane, start, direction):
    """T_sensor_from_can (4x4 float64) of a can lying on its side: origin `start` (m, plane frame: the
    centre of one end), z along `direction` (unit, horizontal, plane frame), x up from the table,
    y = z x x."""
    ux, uy = direction[0], direction[1]
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, uy, ux], [0.0, -ux, uy], [1.0, 0.0, 0.0]])
    T[:3, 3] = start
    return np.asarray(T_sensor_from_plane, dtype=float) @ T


def turned_end_for_end(T_sensor_from_can, length):
    """The pose (4x4 float64) of the same cylinder from its other end: origin moved `length` (m)
    along z, z and y reversed, x kept."""
    T = np.asarray(T_sensor_from_can, dtype=float).copy()
    T[:3, 3] += length * T[:3, 2]
    T[:3, 1:3] *= -1.0
    return T


def image_box(depth, step=8):
    """(first row, last row, first column, last column) of the pixels with depth (finite) of a (H, W)
    image: the image's edge as the sensor sees it (a Kinect's registered depth has columns of holes at
    its sides). Rows are judged on every step-th column, columns on every step-th row (a row with
    depth has it in many columns; the tracker marks every frame). None when no pixel has depth."""
    rows = np.flatnonzero(np.isfinite(depth[:, ::step]).any(axis=1))
    cols = np.flatnonzero(np.isfinite(depth[::step, :]).any(axis=0))
    if len(rows) == 0:
        return None
    return int(rows[0]), int(rows[-1]), int(cols[0]), int(cols[-1])


def on_image_edge(indices, width, box, margin=1):
    """Whether each pixel (flattened indices, int (N,), of an image `width` px wide) lies within
    `margin` px of the edge of box (image_box): bool (N,)."""
    rows, cols = np.divmod(np.asarray(indices, dtype=np.int64), width)
    r0, r1, c0, c1 = box
    return (rows <= r0 + margin) | (rows >= r1 - margin) | (cols <= c0 + margin) | (cols >= c1 - margin)


def pinhole(xyz, step=8, max_error=2.0):
    """The pinhole camera of an organized cloud (float (H, W, 3), camera frame, z along the optical
    axis, m), fitted to every step-th pixel with depth: (fx, cx, fy, cy) in its pixels, column =
    fx x / z + cx and row = fy y / z + cy. None when fewer than 10 such pixels, or when they miss
    their pixels by more than max_error px rms (no camera's frame, or no pinhole)."""
    sample = np.asarray(xyz[::step, ::step], dtype=float)
    rows, cols = np.mgrid[0:sample.shape[0], 0:sample.shape[1]] * step
    x, y, z = sample[..., 0], sample[..., 1], sample[..., 2]
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(z) & (z > 0) & np.isfinite(x) & np.isfinite(y)
    if np.count_nonzero(ok) < 10:
        return None
    camera = []
    for ratio, pixel in ((x[ok] / z[ok], cols[ok]), (y[ok] / z[ok], rows[ok])):
        # The least-squares line, in closed form (np.polyfit's general solver costs more than the data).
        dr, dp = ratio - ratio.mean(), pixel - pixel.mean()
        slope = float(dr @ dp) / max(float(dr @ dr), 1e-12)
        offset = float(pixel.mean() - slope * ratio.mean())
        if np.sqrt(np.mean((slope * ratio + offset - pixel) ** 2)) > max_error:
            return None
        camera += [slope, offset]
    return tuple(camera)


def outside_image(points, camera, box, margin=1):
    """Whether each point (float (N, 3), camera frame, m) projects (camera: pinhole's) outside box
    (image_box) or within `margin` px of its edge, or lies behind the camera: bool (N,)."""
    fx, cx, fy, cy = camera
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    r0, r1, c0, c1 = box
    with np.errstate(divide="ignore", invalid="ignore"):
        col, row = fx * p[:, 0] / p[:, 2] + cx, fy * p[:, 1] / p[:, 2] + cy
        inside = (p[:, 2] > 0) & (row > r0 + margin) & (row < r1 - margin) & (col > c0 + margin) & (col < c1 - margin)
    return ~inside


def _xy(xy):
    """xy as float64 (N, 2): the first two columns of an (N, 2) or (N, 3) plane-frame array."""
    xy = np.asarray(xy, dtype=float)
    if xy.ndim != 2 or xy.shape[1] not in (2, 3):
        raise PerceptionError(f"xy must be points of shape (N, 2) or (N, 3), got shape {xy.shape}")
    return xy[:, :2]


def _radial(xy, cx, cy):
    """Distances from (cx, cy) and the unit vectors from the centre to each point (0 at the centre)."""
    delta = xy - (cx, cy)
    dist = np.hypot(delta[:, 0], delta[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where(dist[:, None] > 0, delta / dist[:, None], 0.0)
    return dist, unit


def radial_error(xy, cx, cy, radius):
    """Radial residuals of points about a circle, their sum of squares and its gradient.

    xy: (N, 2) or (N, 3) plane-frame points (m; z ignored). Returns (residuals, E, grad):
    residual_i = |p_i - c| - radius (m, float64 (N,)), E = sum residual_i^2 (m^2), and
    grad = (dE/dcx, dE/dcy) = -2 sum residual_i (p_i - c) / |p_i - c| (m), float64 (2,).
    """
    dist, unit = _radial(_xy(xy), cx, cy)
    residuals = dist - radius
    return residuals, float(residuals @ residuals), -2.0 * residuals @ unit


def arc_coverage(xy, cx, cy):
    """Angular span (rad, 0..2 pi) of points around (cx, cy): 2 pi minus the widest empty gap."""
    xy = _xy(xy)
    return _angular_span(np.arctan2(xy[:, 1] - cy, xy[:, 0] - cx))


def near_half_angles(toward, limb=1.3, samples=13):
    """`samples` angles (rad, float64) spread evenly within `limb` (rad) of `toward`: the places of a
    round side's near half (toward: the direction to the sensor) that unseen_angles looks at."""
    return toward + np.linspace(-limb, limb, samples)


def unseen_angles(seen, toward, limb=1.3, samples=13, tolerance=None):
    """The angles (rad, float64 (K,)) among near_half_angles(toward, limb, samples) that no angle in
    `seen` (rad, (N,)) lies within half a sample spacing of: the parts of a round side's near half
    (toward: the direction to the sensor) that show none of its points. tolerance (rad, per sample):
    within it instead where it is wider (the angle between neighbouring pixels there: sampled_arc)."""
    theta = near_half_angles(toward, limb, samples)
    gap = np.abs((np.asarray(seen)[None, :] - theta[:, None] + np.pi) % (2 * np.pi) - np.pi).min(axis=1, initial=np.pi)
    # Half a spacing: one found a can seen at its limbs ("cluttered table" 88) but made a box of the
    # real learn21 a lying can (docs/can_search.md, Limits).
    half = limb / (samples - 1)
    return theta[gap > (half if tolerance is None else np.maximum(half, tolerance))]


def sampled_arc(theta, cx, cy, r, z, sensor, ray_angle):
    """The angle (rad, float64 (K,)) about the vertical axis (cx, cy) between the places that
    neighbouring columns of a grid `ray_angle` (rad) apart meet on its circle of radius r (m) at
    height z, at the angles theta (rad, (K,)): r dtheta |t x u| / range = ray_angle, t the circle's
    tangent and u the ray from the sensor ((3,), same frame) seen from above (the camera does not
    roll; a side is tall enough for every row). Toward the limbs the side turns away from the sensor
    and one column spans a wider arc: 4 degrees facing it, 15 at 70 degrees from it (r 43 mm, 0.9 m
    away, every 2nd pixel of a Kinect)."""
    theta = np.asarray(theta, dtype=float)
    places = np.column_stack([cx + r * np.cos(theta), cy + r * np.sin(theta), np.full(len(theta), float(z))])
    rays = places - np.asarray(sensor, dtype=float)
    ranges = np.linalg.norm(rays, axis=1)
    level = np.maximum(np.hypot(rays[:, 0], rays[:, 1]), 1e-12)
    tangent_along_ray = (-np.sin(theta) * rays[:, 0] + np.cos(theta) * rays[:, 1]) / level
    across = np.sqrt(np.maximum(1.0 - tangent_along_ray ** 2, 1e-6))
    return ray_angle * ranges / (r * across)


def ray_angle(organized, viewpoint, row_step=48):
    """The angle (rad) between the rays from the viewpoint ((3,), m) to horizontally neighbouring
    finite points of an organized cloud (float (H, W, 3), same frame) near the image's middle, where
    it is widest (a pinhole's 1 / f: 0.9 / f toward the edges): the 90th percentile over every
    row_step-th row (the camera's, the same on every row: a few rows do); 0.0 for an unorganized
    cloud or no such pair."""
    if np.ndim(organized) != 3:
        return 0.0
    rays = np.asarray(organized[::row_step], dtype=float) - np.asarray(viewpoint, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):  # holes (NaN, or zeros at the viewpoint) drop out
        rays /= np.linalg.norm(rays, axis=2, keepdims=True)
    cosine = np.einsum("ijk,ijk->ij", rays[:, 1:], rays[:, :-1])
    cosine = cosine[np.isfinite(cosine)]
    return float(np.arccos(np.clip(np.percentile(cosine, 10), -1.0, 1.0))) if len(cosine) else 0.0


def behind(places, occluders, sensor, cone=0.01, margin=0.01):
    """Which of the places (float (K, 3), m) lie behind one of the occluders (float (N, 3), same frame)
    seen from the sensor ((3,), same frame): one within `cone` (rad) of the sensor's ray to it and at
    least `margin` (m) nearer. bool (K,)."""
    if len(occluders) == 0 or len(places) == 0:
        return np.zeros(len(places), bool)
    q = places - sensor
    q_range = np.linalg.norm(q, axis=1)
    q = q / q_range[:, None]
    rays = occluders - sensor
    ranges = np.linalg.norm(rays, axis=1)
    rays /= ranges[:, None]
    middle = q.sum(axis=0)
    if np.linalg.norm(middle) > 0:
        # Only an occluder within cone of the bundle of rays to the places can hide one (its angle to
        # the bundle's middle at most the bundle's spread plus cone): the rest leave the (N, K) test.
        middle /= np.linalg.norm(middle)
        spread = float(np.arccos(np.clip((q @ middle).min(), -1.0, 1.0)))
        near = rays @ middle >= np.cos(min(spread + cone + 1e-6, np.pi))
        rays, ranges = rays[near], ranges[near]
    close = rays @ q.T >= np.cos(cone)  # (N, K)
    return (close & (ranges[:, None] < q_range[None, :] - margin)).any(axis=0)


def without_depth(places, normals, occluders, sensor, projector=None, cone=0.01):
    """Which of the places (float (K, 3), m) on a surface of outward normals `normals` ((K, 3)) a
    structured-light camera gives no depth for: behind one of the occluders ((N, 3)) seen from the
    camera (`sensor`, (3,)), or, where the IR projector ((3,); None: not known) is known, unlit by it:
    facing away from it (the surface's own shadow) or behind an occluder seen from it (a cast
    shadow); one frame. bool (K,)."""
    places = np.asarray(places, dtype=float).reshape(-1, 3)
    hidden = behind(places, occluders, np.asarray(sensor, dtype=float), cone)
    if projector is None or hidden.all():
        return hidden
    projector = np.asarray(projector, dtype=float)
    hidden |= np.einsum("ij,ij->i", np.asarray(normals, dtype=float).reshape(-1, 3), projector - places) <= 0
    lit = ~hidden
    if lit.any():
        hidden[lit] = behind(places[lit], occluders, projector, cone)
    return hidden


def seen_through(points, sensor, cx, cy, r, z_lo, z_hi):
    """Which of the points (float (K, 3), m, plane frame) are seen from the sensor ((3,), same frame)
    through the solid upright cylinder of axis (cx, cy), radius r and heights z_lo to z_hi (m): their
    sight line passes through it or ends inside it. bool (K,)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    s = np.asarray(sensor, dtype=float)
    d = points - s
    # Where the line s + t d (0 <= t <= 1) is within r of the axis (a t^2 + b t + c <= 0) and between
    # the heights; the two intervals of t overlap.
    ox, oy = s[0] - cx, s[1] - cy
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2.0 * (d[:, 0] * ox + d[:, 1] * oy)
    c = ox * ox + oy * oy - r * r
    disc = b * b - 4.0 * a * c
    ok = (disc > 0) & (a > 0)
    root = np.sqrt(np.where(ok, disc, 0.0))
    a2 = np.where(ok, 2.0 * a, 1.0)
    t0, t1 = (-b - root) / a2, (-b + root) / a2
    with np.errstate(divide="ignore", invalid="ignore"):
        u0, u1 = (z_lo - s[2]) / d[:, 2], (z_hi - s[2]) / d[:, 2]
    # A level sight line stays at the sensor's height: between the heights all along, or never.
    level, between = d[:, 2] == 0, z_lo <= s[2] <= z_hi
    lo = np.where(level, -np.inf if between else np.inf, np.minimum(u0, u1))
    hi = np.where(level, np.inf if between else -np.inf, np.maximum(u0, u1))
    start = np.maximum.reduce([t0, lo, np.zeros(len(points))])
    end = np.minimum.reduce([t1, hi, np.ones(len(points))])
    return ok & (start < end)


def _angular_span(angle):
    """2 pi minus the widest gap between angles (rad, any order): 0 for fewer than 2."""
    return angular_order(angle)[1] if len(angle) >= 2 else 0.0


def angular_order(angle):
    """(order, span): the positions of the angles (rad, any order, at least one) in order around the
    circle starting after the widest gap between them, so an arc seen across the +-pi cut stays in
    one piece, and the arc they span (rad: 2 pi minus that gap)."""
    order = np.argsort(angle)
    a = angle[order]
    gaps = np.append(np.diff(a), a[0] + 2 * np.pi - a[-1])
    widest = int(np.argmax(gaps))
    return np.roll(order, -((widest + 1) % len(a))), float(2 * np.pi - gaps[widest])


def _fit_circle(xy, center0, radius0, free_radius, r_eps, max_iterations, tol, min_inliers, max_shift):
    """Levenberg-Marquardt on the radial residuals of the points within r_eps of the circle.

    The inlier set is re-evaluated at the start of every iteration; within an iteration the step
    is damped (Marquardt's diagonal scaling) until it lowers the inliers' sum of squares.
    Coordinates are taken relative to the start so far-away frames keep their precision.
    Runs once per can per frame in the tracker, so each step works on x and y as flat arrays and
    builds the 2x2 or 3x3 normal equations directly (NumPy's per-call overhead dominates at a
    few hundred points).
    """
    if not r_eps > 0:
        raise PerceptionError(f"r_eps must be > 0 m, got {r_eps}")
    if not radius0 > 0:
        raise PerceptionError(f"the radius must be > 0 m, got {radius0}")
    xy = _xy(xy)
    finite = np.flatnonzero(np.isfinite(xy[:, 0]) & np.isfinite(xy[:, 1]))
    center0 = np.asarray(center0, dtype=float).reshape(2)
    if not np.isfinite(center0).all():
        raise PerceptionError(f"the start centre must be finite, got {center0}")
    min_inliers = max(int(min_inliers), 3 if free_radius else 2)
    if len(finite) < min_inliers:
        raise PerceptionError(f"a circle fit needs at least {min_inliers} finite points, got {len(finite)}; "
                              "select more of the can")
    x = xy[finite, 0] - center0[0]
    y = xy[finite, 1] - center0[1]
    params = np.array([0.0, 0.0, radius0])
    n_free = 3 if free_radius else 2
    max_shift = 3 * radius0 if max_shift is None else max_shift
    tiny = 1e-12 * np.eye(n_free)

    damping, converged, iteration = 1e-3, False, 0
    for iteration in range(1, int(max_iterations) + 1):
        damping = min(damping, 1e6)  # a new inlier set may allow progress a stuck one did not
        dx, dy = x - params[0], y - params[1]
        dist = np.hypot(dx, dy)
        inliers = np.abs(dist - params[2]) <= r_eps
        n_inliers = int(np.count_nonzero(inliers))
        if n_inliers < min_inliers:
            raise PerceptionError(
                f"only {n_inliers} point(s) lie within r_eps = {r_eps} m of the circle at "
                f"({params[0] + center0[0]:.4f}, {params[1] + center0[1]:.4f}); start nearer the can or raise r_eps")
        sx, sy, dist = x[inliers], y[inliers], dist[inliers]
        res = dist - params[2]
        cost = res @ res
        # Rows of the Jacobian (transposed): d res / d (cx, cy, r) = (-ux, -uy, -1), u the unit
        # vector from the centre to the point (0 for a point at the centre).
        # Kept with the opposite sign, (ux, uy, 1): the normal matrix is the same, the gradient flips.
        jac = np.zeros((3, len(res)))
        off_centre = dist > 0
        np.divide(dx[inliers], dist, out=jac[0], where=off_centre)
        np.divide(dy[inliers], dist, out=jac[1], where=off_centre)
        jac[2] = 1.0
        jac = jac[:n_free]
        A, g = jac @ jac.T, -(jac @ res)
        step = np.zeros(n_free)
        while damping < 1e12:
            trial_step = np.linalg.solve(A + damping * (np.diag(np.diag(A)) + tiny), -g)
            trial = params.copy()
            trial[:n_free] += trial_step
            trial_res = np.hypot(sx - trial[0], sy - trial[1]) - trial[2]
            if trial_res @ trial_res <= cost:
                step, params, damping = trial_step, trial, max(damping / 10, 1e-12)
                break
            damping *= 10  # the step overshot: lean toward gradient descent
        # (damping reaching 1e12 means no step lowers the cost: already at the minimum)
        if not (np.isfinite(params).all() and np.hypot(params[0], params[1]) <= max_shift
                and 0 < params[2] <= max(10 * radius0, radius0 + max_shift)):
            raise PerceptionError(f"the circle fit diverged (centre moved more than {1e3 * max_shift:.1f} mm or radius "
                                  "left its range); select a patch on the can's side and check the table plane")
        if np.sqrt(step @ step) < tol:
            converged = True
            break

    dx, dy = x - params[0], y - params[1]
    residuals = np.hypot(dx, dy) - params[2]
    inliers = np.abs(residuals) <= r_eps
    n_inliers = int(np.count_nonzero(inliers))
    if n_inliers < min_inliers:
        raise PerceptionError(f"only {n_inliers} point(s) lie within r_eps = {r_eps} m of the fitted "
                              "circle; raise r_eps or select a patch on the can")
    cx, cy = params[:2] + center0
    kept = residuals[inliers]
    return CylinderFit(cx=float(cx), cy=float(cy), radius=float(params[2]),
                       rms_error=float(np.sqrt(kept @ kept / n_inliers)), iterations=iteration,
                       n_inliers=n_inliers, converged=converged,
                       arc_coverage=_angular_span(np.arctan2(dy[inliers], dx[inliers])),
                       inliers=finite[inliers].astype(np.int64))


def fit_cylinder_center(xy, c0, radius, r_eps, max_iterations=50, tol=1e-6, min_inliers=5, max_shift=None):
    """Mode 3: the axis (cx, cy) of an upright can of known radius, from its points seen from above.

    xy: (N, 2) or (N, 3) plane-frame points of the can's side (m; z ignored; NaN rows ignored),
    e.g. points_above_plane below the can's top; c0: start (cx, cy), e.g. initial_can_center;
    radius (m); r_eps (m): points with |residual| > r_eps are left out, re-decided each iteration.
    Levenberg-Marquardt over (cx, cy) with the analytic Jacobian of the residuals |p_i - c| - r,
    run until a step is shorter than tol (m) or max_iterations. Returns a CylinderFit (radius the
    given one). Raises PerceptionError with fewer than min_inliers inliers, or when the centre
    wanders more than max_shift (m; default 3 radii) from c0.
    """
    return _fit_circle(xy, c0, radius, False, r_eps, max_iterations, tol, min_inliers, max_shift)


def fit_cylinder(xy, c0, r0, r_eps, max_iterations=50, tol=1e-6, min_inliers=5, max_shift=None):
    """fit_cylinder_center with the radius free too: Levenberg-Marquardt over (cx, cy, r) from
    (c0, r0) (m, plane frame). For the automatic mode, where the can's size is not known;
    fit_circle_algebraic gives a start. Returns a CylinderFit with the fitted radius."""
    return _fit_circle(xy, c0, r0, True, r_eps, max_iterations, tol, min_inliers, max_shift)


def fit_circle_algebraic(xy):
    """Kasa's algebraic circle fit: (cx, cy, r) in metres, linear least squares, no start needed.

    xy: (N, 2) or (N, 3) points (z ignored, NaN rows dropped). Minimises sum (|p - c|^2 - r^2)^2,
    which favours small radii on short arcs: a start for fit_cylinder, not a final answer.
    Raises PerceptionError with fewer than 3 finite points or (nearly) collinear points.
    """
    xy = _xy(xy)
    xy = xy[np.isfinite(xy).all(axis=1)]
    if len(xy) < 3:
        raise PerceptionError(f"a circle needs at least 3 finite points, got {len(xy)}; select more of the can")
    mean = xy.mean(axis=0)
    q = xy - mean  # centred, so far-away frames keep their precision
    A = np.column_stack([2 * q, np.ones(len(q))])
    b = (q ** 2).sum(axis=1)
    scale = np.abs(q).max()
    if not scale > 0:
        raise PerceptionError("the points coincide; select more of the can")
    solution, _, rank, sv = np.linalg.lstsq(A / [scale, scale, 1.0], b, rcond=None)
    if rank < 3 or sv[-1] <= 1e-9 * sv[0]:
        raise PerceptionError("the points are collinear, no circle through them; select more of the can")
    a, bb, c = solution[0] / scale, solution[1] / scale, solution[2]
    return float(a + mean[0]), float(bb + mean[1]), float(np.sqrt(c + a * a + bb * bb))


def plane_extent(points, T_sensor_from_plane, band, step=8, quantile=0.01):
    """(x_min, x_max, y_min, y_max) in the plane frame (m) of the points within band (m) of the
    plane z = 0, on a subsample (every step-th pixel, see subsample) and between the quantile
    and 1 - quantile of each coordinate (a few stray points do not stretch it); None when no
    point is that close. points: float32 (N, 3) or (H, W, 3), sensor frame (m)."""
    pts = subsample(as_points_float32(points), step).reshape(-1, 3).astype(float)
    in_plane = transforms.apply(transforms.invert(T_sensor_from_plane), pts)
    with np.errstate(invalid="ignore"):
        near = in_plane[np.abs(in_plane[:, 2]) <= band]
    if len(near) == 0:
        return None
    (x0, y0), (x1, y1) = np.quantile(near[:, :2], [quantile, 1.0 - quantile], axis=0)
    return float(x0), float(x1), float(y0), float(y1)


def shape_error(xy, cx, cy, radius, bins):
    """How far the points bend away from the circle systematically (m): the points are split by
    angle around (cx, cy) into `bins` consecutive arcs of equal count, and the rms of the arcs'
    mean radial residuals is returned. Noise averages out within an arc; a flat face does not."""
    xy = np.asarray(xy, dtype=float)[:, :2]
    if len(xy) < bins:
        return float("inf")
    angle = np.arctan2(xy[:, 1] - cy, xy[:, 0] - cx)
    residual = np.hypot(xy[:, 0] - cx, xy[:, 1] - cy) - radius
    order = angular_order(angle)[0]
    # np.array_split's arcs (the first len % bins one point longer), summed in one call.
    size, longer = divmod(len(order), bins)
    counts = np.full(bins, size)
    counts[:longer] += 1
    means = np.add.reduceat(residual[order], np.cumsum(counts) - counts) / counts
    return float(np.sqrt(means @ means / bins))


def circle_rms(xy, cx, cy, radius):
    """RMS distance (m) of points xy (float (N, 2), m) to the circle of `radius` about (cx, cy) (m)."""
    return np.sqrt(np.mean((np.hypot(xy[:, 0] - cx, xy[:, 1] - cy) - radius) ** 2))


def radius_standard_error(xy, cx, cy, radius):
    """The standard error (m) of a circle's radius (cx, cy, radius: m) fitted to points xy (float (N,
    2), m), from its residuals and Jacobian (linearised: a lower bound over a narrow arc): a fraction of
    a millimetre for a side seen over a wide arc, up to centimetres for a narrow one that hardly fixes
    its curvature. inf for fewer than 4 points or a degenerate fit."""
    xy = np.asarray(xy, dtype=float)[:, :2]
    dx, dy = xy[:, 0] - cx, xy[:, 1] - cy
    dist = np.hypot(dx, dy)
    if len(xy) < 4 or not np.all(dist > 0):
        return float("inf")
    residual = dist - radius
    jacobian = np.column_stack([-dx / dist, -dy / dist, -np.ones(len(xy))])
    try:
        covariance = np.linalg.inv(jacobian.T @ jacobian) * (residual @ residual / (len(xy) - 3))
    except np.linalg.LinAlgError:
        return float("inf")
    return float(np.sqrt(max(covariance[2, 2], 0.0)))


def line_ratio(xy, cx, cy, radius):
    """How much better the circle of `radius` about (cx, cy) (m) explains points (float (N, 2), m)
    than their own best line (dimensionless): the rms distance to that line over the rms distance
    to the circle. Above 1 when the circle's curvature shows through the noise; below 1 for one flat
    face that a circle touches. NaN for fewer than 3 points."""
    xy = np.asarray(xy, dtype=float)[:, :2]
    if len(xy) < 3:
        return float("nan")
    centred = xy - xy.mean(axis=0)
    # The smaller eigenvalue of the 2 x 2 covariance: the mean squared distance to the best line.
    a, b, c = np.mean(centred[:, 0] ** 2), np.mean(centred[:, 0] * centred[:, 1]), np.mean(centred[:, 1] ** 2)
    line = np.sqrt(max(0.5 * (a + c) - np.hypot(0.5 * (a - c), b), 0.0))
    circle = circle_rms(xy, cx, cy, radius)
    return float(line / circle) if circle > 0 else float("inf")


def flat_faces(xy, eps, min_span, min_points, rng, tries=32, max_faces=3, max_gap=0.02, *, radii, lines=False):
    """Which of the points xy (float64 (M, 2), m, seen from above) lie on a flat vertical face (a box's
    or prism's): within eps of a line, a run along it at least min_span (m) long with no gap over
    max_gap (m), of at least min_points points. Up to max_faces lines, each the best of `tries`
    drawn through two points. A can's side is no such run: a line stays within eps of a circle of
    radius r over 2 sqrt(2 r eps) only (44 mm for r = 80 mm, eps = 3 mm); nor part of one, a can's
    front in line with a face past its end (_without_tangent_ends; radii (m): a can's, min and max).
    With lines=True: (which, the faces' runs: (point on the line, unit direction, from, to: m along
    it from the point) each, for on_faces)."""
    face = np.zeros(len(xy), bool)
    runs = []
    for _ in range(max_faces):
        rest = np.flatnonzero(~face)
        if len(rest) < max(min_points, 2):
            break
        a, b = rest[rng.integers(len(rest), size=(2, tries))]
        d = xy[b] - xy[a]
        norm = np.hypot(d[:, 0], d[:, 1])
        ok = norm >= eps
        if not ok.any():
            break
        a, d = a[ok], d[ok] / norm[ok, None]
        # Distance of every rest point from every line (T, R): |cross(d, p - p_a)|.
        px, py = xy[rest, 0], xy[rest, 1]
        off = np.abs(np.outer(d[:, 1], px) - np.outer(d[:, 0], py)
                     - (d[:, 1] * xy[a, 0] - d[:, 0] * xy[a, 1])[:, None])
        best = int(np.argmax((off <= eps).sum(axis=1)))
        on = np.flatnonzero(off[best] <= eps)
        rest_along = (xy[rest] - xy[a[best]]) @ d[best]
        along = rest_along[on]
        order = np.argsort(along)
        along = along[order]
        # The longest run without a gap: two cans' fronts on one tangent line are two short runs.
        breaks = np.flatnonzero(np.diff(along) > max_gap)
        starts, ends = np.r_[0, breaks + 1], np.r_[breaks, len(along) - 1]
        k = int(np.argmax(along[ends] - along[starts]))
        lo, hi = _without_tangent_ends(along, starts[k], ends[k], min_span, 0.5 * max_gap, radii,
                                       (xy[rest], rest_along, off[best]))
        if along[hi] - along[lo] < min_span or hi - lo + 1 < min_points:
            break
        run = rest[on[order[lo:hi + 1]]]
        face[run] = True
        if lines:
            # The run's own line (the one drawn through two noisy points tilts off it toward the ends).
            centre = xy[run].mean(axis=0)
            direction = np.linalg.eigh(np.cov((xy[run] - centre).T))[1][:, 1]
            along_run = (xy[run] - centre) @ direction
            runs.append((centre, direction, along_run.min(), along_run.max()))
    return (face, runs) if lines else face


def on_faces(xy, runs, eps):
    """Which of the points xy (float64 (M, 2), m, seen from above) lie within eps (m) of one of the
    faces' runs (flat_faces' with lines=True), between its ends."""
    on = np.zeros(len(xy), bool)
    for point, direction, start, end in runs:
        rel = xy - point
        along = rel @ direction
        off = np.abs(rel[:, 0] * direction[1] - rel[:, 1] * direction[0])
        on |= (off <= eps) & (along >= start - eps) & (along <= end + eps)
    return on


def _without_tangent_ends(along, lo, hi, min_span, gap, radii, nearby, reach=0.01, min_points=6, min_bend=1.5):
    """The run along[lo..hi] (sorted positions along a line, m) less a piece at either end shorter than
    min_span (m) beyond a gap over `gap` (m) that bends like a can's front, where the rest still spans
    min_span: the front of a can in line with a box's face, which the line stays near over a few
    centimetres a little way past the face's end (fresh 4134 of "can touching box": 32 mm of it 16 mm
    past the face). nearby: (xy float (M, 2), their positions along the line and distances from it,
    m) of every point the line was drawn among. Bends: the points within `reach` (m) of the piece,
    along the line beyond its ends and off it, at least min_points, have their own (algebraic) circle
    of a radius within radii (m), min_bend times closer to them (rms) than their best line
    (line_ratio); a straight piece is the face's, seen past something in front of it."""
    breaks = lo + np.flatnonzero(np.diff(along[lo:hi + 1]) > gap)
    xy, near_along, near_off = nearby

    def bends(a, b):
        # Near the line a can's front is nearly straight (its sagitta within the line's eps): its
        # curve shows where it leaves the line (fresh 7330, r 33 mm: 28 mm within eps, a line ratio of
        # 1.04 there).
        piece = xy[(near_along >= along[a] - reach) & (near_along <= along[b] + reach) & (near_off <= reach)]
        if len(piece) < min_points:
            return False
        kx, ky, kr = (float(v[0]) for v in fit_circles_algebraic(piece))
        return bool(radii[0] <= kr <= radii[1] and line_ratio(piece, kx, ky, kr) >= min_bend)

    # The longest end piece shorter than min_span first: a can's front may have a gap of its own (fresh
    # 6922: 11 mm).
    for b in breaks[::-1]:
        if along[b] - along[lo] < min_span and along[hi] - along[b + 1] >= min_span and bends(lo, b):
            lo = b + 1
            break
    for b in breaks[breaks >= lo]:
        if along[hi] - along[b + 1] < min_span and along[b] - along[lo] >= min_span and bends(b + 1, hi):
            hi = b
            break
    return lo, hi


def _halves(xy, cx, cy):
    """The points xy (float (N, 2), m) in two halves, split at the middle of the arc they span around
    (cx, cy) (m): float64 (N1, 2), (N2, 2)."""
    xy = np.asarray(xy, dtype=float)[:, :2]
    angle = np.arctan2(xy[:, 1] - cy, xy[:, 0] - cx)
    order, span = angular_order(angle)
    along = (angle[order] - angle[order[0]]) % (2 * np.pi)
    return xy[order][along < 0.5 * span], xy[order][along >= 0.5 * span]


def half_line_ratios(xy, cx, cy, radius):
    """line_ratio of each half of an arc of points (float (N, 2), m), split at the middle of the arc
    they span around (cx, cy) (m), about the circle of `radius` (m): (first, second), NaN for a half
    of fewer than 3 points. Below 1 for a half on a flat face (a box's edge) that the circle touches."""
    return tuple(line_ratio(half, cx, cy, radius) for half in _halves(xy, cx, cy))


def facet_ratio(xy, cx, cy, radius):
    """How straight the two halves of an arc of points are (dimensionless): the larger of their
    half_line_ratios. Above 1 when the circle's curvature shows through the noise; below 1 on both
    halves for two flat faces meeting at a corner (a box's) that a circle touches. NaN when a half
    holds fewer than 3 points."""
    return float(np.max(half_line_ratios(xy, cx, cy, radius)))


@dataclass(frozen=True, eq=False)
class Rectangle:
    """A rectangle seen from above (m): centre (2,), axes (2, 2: unit rows along its sides), half (2,:
    half its side lengths), fill: how much of it the convex hull of the points it encloses fills."""

    centre: np.ndarray
    axes: np.ndarray
    half: np.ndarray
    fill: float

    def contains(self, xy, reach=0.0):
        """Which of the points xy (float (N, 2), m) lie inside it grown by reach (m): bool (N,)."""
        local = np.abs((np.asarray(xy, dtype=float)[:, :2] - self.centre) @ self.axes.T)
        return (local <= self.half + reach).all(axis=1)


def enclosing_rectangle(xy):
    """The smallest Rectangle enclosing points (float (N, 2), m), or None for fewer than 3 points or a
    degenerate hull. It has a side along a hull edge (rotating calipers)."""
    xy = np.asarray(xy, dtype=float)
    if len(xy) < 3:
        return None
    try:
        hull = ConvexHull(xy)
    except QhullError:
        return None
    corners = xy[hull.vertices]
    edges = np.diff(np.vstack([corners, corners[:1]]), axis=0)
    u = edges / np.linalg.norm(edges, axis=1, keepdims=True)
    v = np.column_stack([-u[:, 1], u[:, 0]])
    along, across = corners @ u.T, corners @ v.T
    low = np.array([along.min(axis=0), across.min(axis=0)])  # (2, edges): per edge's frame
    high = np.array([along.max(axis=0), across.max(axis=0)])
    area = np.prod(high - low, axis=0)
    k = int(np.argmin(area))
    if not area[k] > 0:
        return None
    axes = np.array([u[k], v[k]])
    return Rectangle(centre=(high[:, k] + low[:, k]) / 2 @ axes, axes=axes, half=(high[:, k] - low[:, k]) / 2,
                     fill=float(hull.volume / area[k]))


def rectangularity(xy):
    """How much of its smallest enclosing rectangle the convex hull of points (float (N, 2), m) fills
    (dimensionless): pi / 4 for a disc (a can's lid), up to about 0.85 for a disc a straight edge cuts
    short, 1 for a rectangle (a box's top). NaN for fewer than 3 points or a degenerate hull."""
    rectangle = enclosing_rectangle(xy)
    return float("nan") if rectangle is None else rectangle.fill


def split_ratio(xy, cx, cy, radius, min_points=6):
    """How much better each half of an arc of points (split as facet_ratio) is explained by a circle
    of its own than by the circle of `radius` about (cx, cy) (m): the larger over the halves of the
    rms distance to that circle over the rms distance to the half's own (Kasa) circle. About 1 for
    one round object; well above 1 where the arc joins two (the fronts of two touching cans on a
    wider circle tangent to both). NaN when a half holds fewer than min_points points."""
    return halves_ratio(split_circles(xy, cx, cy, radius, min_points))


def halves_ratio(halves):
    """split_ratio from split_circles' halves: the larger ratio, 0 when neither half has a circle of its
    own, NaN for None (a half too small)."""
    return float("nan") if halves is None else max((h[0] for h in halves), default=0.0)


def split_circles(xy, cx, cy, radius, min_points=6):
    """split_ratio's halves: a list of (ratio, kx, ky, kr) (m), each half's ratio and own (Kasa)
    circle, for the halves with one (a straight half has none); None when a half holds fewer than
    min_points points."""
    halves = []
    for half in _halves(xy, cx, cy):
        if len(half) < min_points:
            return None
        kx, ky, kr = (float(v[0]) for v in fit_circles_algebraic(half))
        if not np.isfinite(kr):
            continue  # a straight half: no circle of its own (facet_ratio's concern)
        own, circle = circle_rms(half, kx, ky, kr), circle_rms(half, cx, cy, radius)
        halves.append((circle / own if own > 0 else float("inf"), kx, ky, kr))
    return halves


@dataclass(frozen=True)
class RimCircle:
    """The circle of a disc's rim seen from above (rim_circle): centre (cx, cy), radius (m, plane
    frame); outline: float64 (K, 2), the outermost points on the half away from the sensor;
    residual: their distance to the circle fitted to them (m, (K,)), whose radius is the rim's less
    half the sample spacing (m); r_eps (m): the outline points within it of that circle are the rim's
    (arc), and up to two farther inside it the ends of an arc something in front cuts short (rms)."""

    cx: float
    cy: float
    radius: float
    outline: np.ndarray
    residual: np.ndarray
    spacing: float
    r_eps: float

    @property
    def outline_radius(self):
        """The radius (m) of the circle fitted to the outline (the rim's less half the spacing)."""
        return self.radius - 0.5 * self.spacing

    @property
    def kept(self):
        """Which outline points are the rim's (bool (K,)): all but the (at most) two farthest more
        than r_eps inside the circle: where something in front cuts the lid short, the ends of the arc
        seen lie inside the rim (a box's corners stick out)."""
        order = np.argsort(self.residual, kind="stable")
        kept = np.ones(len(self.residual), bool)
        kept[order[:min(2, int(np.count_nonzero(self.residual < -self.r_eps)))]] = False
        return kept

    @property
    def rms(self):
        """RMS of the residuals (m) of the outline points kept."""
        rim = self.residual[self.kept]
        return float(np.sqrt(np.mean(rim ** 2))) if len(rim) else np.inf

    def arc(self, beside=None):
        """The angle (rad) the outline points within r_eps of the circle span around it, together with
        the points beside (float (M, 2+), m: a stripe of side under the lid) when given."""
        rim = self.outline[np.abs(self.residual) <= self.r_eps]
        return arc_coverage(rim if beside is None else np.vstack([rim, _xy(beside)]), self.cx, self.cy)

    def with_side(self, side_xy, from_both=False):
        """The circle refitted to the outline and to side points under the lid (float (M, 2+), m), by
        Tukey's biweight from this one (from_both: from the algebraic circle of both, when the rim is
        seen over too short an arc to fix a start): a lid cut short by what stands in front fixes its
        circle poorly, a stripe of side seen beside that pins it. The outline is moved out by half the
        spacing, where the rim lies. A RimCircle with the same outline, or None when no circle fits."""
        rel = self.outline - (self.cx, self.cy)
        out = self.outline + 0.5 * self.spacing * rel / np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-12)[:, None]
        both = np.vstack([out, _xy(side_xy)])
        cx, cy, r = fit_circle_algebraic(both) if from_both else (self.cx, self.cy, self.radius)
        if not np.isfinite(r):
            return None
        try:
            cx, cy, r, _ = fit_circle_robust(both, (cx, cy), r, self.r_eps)
        except PerceptionError:
            return None
        residual = np.hypot(self.outline[:, 0] - cx, self.outline[:, 1] - cy) - (r - 0.5 * self.spacing)
        return RimCircle(float(cx), float(cy), float(r), self.outline, residual, self.spacing, self.r_eps)

    def touching(self, other):
        """The circle refitted to the outline points kept, touching the circle `other` ((cx, cy, radius),
        m) from outside (fit_circle_touching; the outline lies half the spacing inside the rim): a lid
        the can in front cuts short fixes its circle poorly, and its radius came out up to 3 mm too
        wide, overlapping that can (fresh 4536 of "cans touching", 4006 of "cluttered table"). A
        RimCircle with the same outline, or None when no circle fits."""
        fit = fit_circle_touching(self.outline[self.kept], (self.cx, self.cy), self.outline_radius, other,
                                  gap=0.5 * self.spacing)
        if fit is None:
            return None
        cx, cy, r = fit
        residual = np.hypot(self.outline[:, 0] - cx, self.outline[:, 1] - cy) - r
        return RimCircle(cx, cy, r + 0.5 * self.spacing, self.outline, residual, self.spacing, self.r_eps)

    def fits(self, sigma, min_arc, pinned=False):
        """Whether it is the rim of a can's lid: its rms within max(2 mm, 2 sigma) (sigma: the depth
        noise, m; the outline's samples lie up to a sample spacing inside the rim), or within a
        sample spacing when pinned (a stripe of side fixes its circle, with_side), and seen over at
        least min_arc (rad) within r_eps."""
        return self.rms <= max(0.002, 2 * sigma, self.spacing if pinned else 0.0) and self.arc() >= min_arc


def rim_outline(disc_xy, sensor, sectors=36):
    """The outline of a disc of points seen from above (a can's lid) on the half away from the sensor,
    where its rim is seen against what lies behind (the near half may be hidden): the outermost
    point in each of `sectors` sectors around the points' centroid. disc_xy: float (N, 2+) (m);
    sensor: (2+,), the sensor in the same frame. float (K, 2)."""
    xy = _xy(disc_xy)
    centroid = xy.mean(axis=0)
    rel = xy - centroid
    reach = np.hypot(rel[:, 0], rel[:, 1])
    sector = ((np.arctan2(rel[:, 1], rel[:, 0]) + np.pi) / (2 * np.pi) * sectors).astype(np.int64) % sectors
    order = np.lexsort((reach, sector))
    outline = xy[order[np.r_[sector[order][1:] != sector[order][:-1], True]]]
    return outline[(outline - centroid) @ (np.asarray(sensor, dtype=float)[:2] - centroid) < 0]


def on_hull(disc_xy, outline, max_inside):
    """Which outline points (float (K, 2+), m) lie within max_inside (m) of the boundary of the convex
    hull of the disc's points (float (N, 2+)): bool (K,). A sparse disc (a lid far away, a few
    points per sector) leaves sectors whose outermost point lies well inside its rim; all of them
    when the hull is degenerate."""
    xy, outline = _xy(disc_xy), _xy(outline)
    try:
        facets = ConvexHull(xy).equations  # (a, b, c): a x + b y + c <= 0 inside
    except QhullError:
        return np.ones(len(outline), bool)
    inside = -(outline @ facets[:, :2].T + facets[:, 2])
    return inside.min(axis=1) <= max_inside


def rim_circle(disc_xy, sensor_xy, r_eps, sectors=36, outline=None):
    """The circle of the rim of a disc of points seen from above (a can's lid), from its outline
    (rim_outline; or `outline`, float (K, 2), a part of it the caller chose), fitted algebraically,
    then by Tukey's biweight (fit_circle_robust; r_eps, m). The outermost samples lie on average
    half a sample spacing inside the rim (the median distance from some points to their nearest
    neighbour): added to the radius. disc_xy: float (N, 2+) (m); sensor_xy: (2+,). RimCircle, or
    None when fewer than 3 outline points or no circle fits."""
    xy = _xy(disc_xy)
    outline = rim_outline(xy, sensor_xy, sectors) if outline is None else _xy(outline)
    if len(outline) < 3:
        return None
    cx, cy, r = fit_circle_algebraic(outline)
    if not np.isfinite(r):
        return None
    try:
        # A few iterations do: the outline holds 36 points at most.
        cx, cy, r, _ = fit_circle_robust(outline, (cx, cy), r, r_eps, max_iterations=5, tol=1e-5)
    except PerceptionError:
        return None
    probe = xy[:: max(1, len(xy) // 16)]
    gaps = np.hypot(probe[:, None, 0] - xy[None, :, 0], probe[:, None, 1] - xy[None, :, 1])
    spacing = float(np.median(np.where(gaps > 0, gaps, np.inf).min(axis=1)))
    spacing = spacing if np.isfinite(spacing) else 0.0
    residual = np.hypot(outline[:, 0] - cx, outline[:, 1] - cy) - r
    return RimCircle(float(cx), float(cy), float(r + 0.5 * spacing), outline, residual, spacing, float(r_eps))


def shadowed(xy, z, occluders, sensor, reach, directions=8, cone=0.01):
    """Which of the places xy (float (K, 2), m) at height z (m) have a place `reach` (m) beside
    them, in one of `directions` directions, hidden behind one of the occluders (float (N, 3)) seen
    from the sensor ((3,), same frame; behind, within `cone`, rad): the edge of that occluder's
    shadow. bool (K,)."""
    angle = np.linspace(0.0, 2 * np.pi, directions, endpoint=False)
    around = (_xy(xy)[:, None, :] + reach * np.c_[np.cos(angle), np.sin(angle)][None]).reshape(-1, 2)
    hidden = behind(np.c_[around, np.full(len(around), z)], occluders, np.asarray(sensor, dtype=float), cone=cone)
    return hidden.reshape(len(xy), directions).any(axis=1)


def _from_start(xy, c0):
    """(xy, c0, u, v): the points (N, 2), the start centre c0 (2,) and the points' coordinates relative
    to it (m), so far-away frames keep their precision in the circle fits."""
    xy = _xy(xy)
    c0 = np.asarray(c0, dtype=float).reshape(2)
    return xy, c0, xy[:, 0] - c0[0], xy[:, 1] - c0[1]


def fit_circles_algebraic(xy, weights=None):
    """fit_circle_algebraic (Kasa) of many subsets of the same points at once, by its normal equations.

    xy: float64 (N, 2) or (N, 3) points (m, plane frame; z ignored, finite); weights: (K, N) 0/1
    masks (or weights) choosing K subsets, or None for one subset of all points. Returns (cx, cy, r)
    float64 (K,) each (m); NaN for a subset of fewer than 3 points or (nearly) collinear ones. One
    matrix product for all subsets: for searches that refine many circles (can_search).
    """
    xy = _xy(xy)
    mean = xy.sum(axis=0) / max(len(xy), 1)
    u, v = xy[:, 0] - mean[0], xy[:, 1] - mean[1]  # centred, so far-away frames keep their precision
    s = u * u + v * v
    features = np.empty((9, len(xy)))
    features[0], features[1], features[2], features[3], features[4] = 1.0, u, v, u * u, u * v
    features[5], features[6], features[7], features[8] = v * v, u * s, v * s, s
    if weights is None:
        # One circle: the closed form on Python floats, without NumPy's per-call cost on 1-element arrays.
        a, b, r = kasa_from_sums(*features.sum(axis=1).tolist())
        return np.array([a + mean[0]]), np.array([b + mean[1]]), np.array([r])
    a, b, r = kasa_from_sums(*(features @ np.atleast_2d(np.asarray(weights, dtype=float)).T))
    return a + mean[0], b + mean[1], r


def kasa_from_sums(n, su, sv, suu, suv, svv, sus, svs, ss):
    """Kasa circles (centre (a, b), radius r; arrays of the sums' shape, m) from the sums over each
    subset of points (u, v) (m): of 1, u, v, u^2, uv, v^2, u s, v s and s (s = u^2 + v^2). NaN for a
    subset of fewer than 3 points or (nearly) collinear ones. The 3 x 3 normal equations of rows
    (u, v, 1) (2a, 2b, c) = s, c = r^2 - a^2 - b^2, are solved in closed form (Cramer): for the
    batches of the searches, LAPACK's per-system overhead costs more than the arithmetic."""
    # The symmetric matrix [[suu, suv, su], [suv, svv, sv], [su, sv, n]]: cofactors, determinant.
    c00, c01, c02 = svv * n - sv * sv, sv * su - suv * n, suv * sv - svv * su
    c11, c12, c22 = suu * n - su * su, suv * su - suu * sv, suu * svv - suv * suv
    det = suu * c00 + suv * c01 + su * c02
    # Collinear or too few points: singular relative to its scale (n x spread^4).
    spread = np.maximum(suu + svv, 1e-300)
    good = (n >= 3) & (np.abs(det) > 1e-12 * np.maximum(n, 1) * spread * spread)
    inverse = 1.0 / np.where(good, det, 1.0)
    a = 0.5 * (c00 * sus + c01 * svs + c02 * ss) * inverse
    b = 0.5 * (c01 * sus + c11 * svs + c12 * ss) * inverse
    c = (c02 * sus + c12 * svs + c22 * ss) * inverse
    with np.errstate(invalid="ignore"):
        r = np.sqrt(c + a * a + b * b)
    nan = np.where(good, 0.0, np.nan)
    return a + nan, b + nan, r + nan


def fit_circle_geometric(xy, c0, r0, r_eps, max_iterations=50, tol=1e-6, min_inliers=5, max_shift=None):
    """fit_cylinder's circle (least squares on the radial residuals of the points within r_eps,
    re-decided every iteration; Levenberg-Marquardt from (c0, r0)) with a fraction of its
    overhead: (cx, cy, r) in metres. For searches that fit many circles (can_search).

    xy: float64 (N, 2) or (N, 3) finite points (m, plane frame; z ignored). Same stopping rules and
    errors as fit_cylinder: PerceptionError with fewer than min_inliers inliers or when the centre
    moves more than max_shift (m; default 3 r0) from c0 or the radius leaves its range.
    """
    if not (r_eps > 0 and r0 > 0):
        raise PerceptionError(f"r_eps and the radius must be > 0 m, got {r_eps}, {r0}")
    xy, c0, u, v = _from_start(xy, c0)
    a = b = 0.0
    r = float(r0)
    max_shift = 3 * r0 if max_shift is None else max_shift
    min_inliers = max(int(min_inliers), 3)
    damping = 1e-3
    for _ in range(int(max_iterations)):
        damping = min(damping, 1e6)
        du, dv = u - a, v - b
        d = np.sqrt(du * du + dv * dv)
        inliers = np.abs(d - r) <= r_eps
        n = int(np.count_nonzero(inliers))
        if n < min_inliers:
            raise PerceptionError(f"only {n} point(s) lie within r_eps = {r_eps} m of the circle at "
                                  f"({a + c0[0]:.4f}, {b + c0[1]:.4f})")
        du, dv, d = du[inliers], dv[inliers], np.maximum(d[inliers], 1e-12)
        rows = np.empty((4, n))
        rows[0], rows[1], rows[2], rows[3] = du / d, dv / d, 1.0, d - r
        sums = rows @ rows.T  # J^T J (J = -(unit, 1)), -J^T residual, and the cost, at once
        A, minus_g, cost = sums[:3, :3], sums[:3, 3], sums[3, 3]
        step = np.zeros(3)
        while damping < 1e12:
            damped = A.copy()
            damped.flat[::4] += damping * (A.flat[::4] + 1e-12)
            trial = np.linalg.solve(damped, minus_g)
            res = np.hypot(du - trial[0], dv - trial[1]) - (r + trial[2])
            if res @ res <= cost:
                step, damping = trial, max(damping / 10, 1e-12)
                break
            damping *= 10  # the step overshot: lean toward gradient descent
        a, b, r = a + step[0], b + step[1], r + step[2]
        if not (np.isfinite((a, b, r)).all() and np.hypot(a, b) <= max_shift
                and 0 < r <= max(10 * r0, r0 + max_shift)):
            raise PerceptionError(f"the circle fit diverged (centre moved more than {1e3 * max_shift:.1f} mm or radius "
                                  "left its range)")
        if np.sqrt(step @ step) < tol:
            break
    n = int(np.count_nonzero(np.abs(np.hypot(u - a, v - b) - r) <= r_eps))
    if n < min_inliers:
        raise PerceptionError(f"only {n} point(s) lie within r_eps = {r_eps} m of the fitted circle")
    return float(a + c0[0]), float(b + c0[1]), float(r)


def fit_circle_robust(xy, c0, r0, r_eps, k=4.685, min_scale=5e-4, max_iterations=20, tol=1e-6, max_shift=None,
                      fixed_radius=False):
    """A circle by Tukey's biweight M-estimator (iteratively reweighted Gauss-Newton) from (c0, r0):
    (cx, cy, r, scale) in metres.

    Points of another surface near the circle (a box face or a neighbour can touching the can)
    pull a least-squares fit; the biweight gives points beyond k x scale no weight at all. The
    scale is re-estimated every iteration as 1.4826 x the median absolute residual of the points
    within r_eps (m), floored at min_scale (m: depth quantization can make the median vanish).
    xy: float64 (N, 2) or (N, 3) finite points (m, plane frame; z ignored). Raises PerceptionError
    when fewer than 3 points keep a weight or the centre moves more than max_shift (default r0).
    fixed_radius: the radius stays r0, only the centre is fitted (a stripe of side too narrow to fix
    a radius, of a can whose radius is known).
    """
    if not (r_eps > 0 and r0 > 0 and k > 0 and min_scale > 0):
        raise PerceptionError(f"r_eps, r0, k and min_scale must be > 0, got {r_eps}, {r0}, {k}, {min_scale}")
    xy, c0, u, v = _from_start(xy, c0)
    a = b = 0.0
    r = float(r0)
    max_shift = r0 if max_shift is None else max_shift
    scale = min_scale
    rows = np.empty((4, len(xy)))
    for _ in range(int(max_iterations)):
        du, dv = u - a, v - b
        d = np.maximum(np.sqrt(du * du + dv * dv), 1e-12)
        res = d - r
        size = np.abs(res)
        near = size[size <= r_eps]
        if len(near) < 3:
            raise PerceptionError(f"only {len(near)} point(s) within r_eps = {r_eps} m of the circle")
        half = len(near) // 2
        near.partition(half)  # the median by a partial sort (upper median for an even count)
        scale = max(1.4826 * float(near[half]), min_scale)
        t = size * (1.0 / (k * scale))
        w = np.maximum(1.0 - t * t, 0.0) ** 2
        if np.count_nonzero(w) < 3:
            raise PerceptionError("fewer than 3 points keep a weight in the robust circle fit")
        rows[0], rows[1], rows[2], rows[3] = du / d, dv / d, 1.0, res  # -J and the residual
        sums = (rows * w) @ rows.T
        n = 2 if fixed_radius else 3
        try:
            step = np.linalg.solve(sums[:n, :n] + 1e-12 * np.eye(n), sums[:n, 3])
        except np.linalg.LinAlgError:
            raise PerceptionError("the robust circle fit is singular (the points are collinear)") from None
        step = np.append(step, 0.0) if fixed_radius else step
        a, b, r = a + step[0], b + step[1], r + step[2]
        if not (np.isfinite((a, b, r)).all() and np.hypot(a, b) <= max_shift and r > 0):
            raise PerceptionError(f"the robust circle fit diverged (centre moved more than {1e3 * max_shift:.1f} mm)")
        if np.sqrt(step @ step) < tol:
            break
    return float(a + c0[0]), float(b + c0[1]), float(r), scale


def fit_circle_touching(xy, c0, r0, other, gap=0.0, max_iterations=20, tol=1e-7):
    """The least-squares circle through points xy (float (N, 2+), m) that touches the circle `other`
    ((cx, cy, radius), m) from outside, its radius plus `gap` (m) from it: (cx, cy, r) in metres, from
    the side of `other` where c0 ((2,), m) lies, radius r0 (m); None when it does not converge or its
    radius is not positive. Two solid objects do not share space: what a circle through a short arc
    leaves open, the other's surface fixes."""
    xy = _xy(xy)
    fx, fy, fr = (float(v) for v in other)
    phi, r = math.atan2(c0[1] - fy, c0[0] - fx), float(r0)
    for _ in range(int(max_iterations)):
        # The centre lies on the circle of radius r + gap + fr about the other's centre, at angle phi.
        u, t = np.array([math.cos(phi), math.sin(phi)]), np.array([-math.sin(phi), math.cos(phi)])
        rel = xy - ((fx, fy) + (r + gap + fr) * u)
        d = np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-12)
        normal = rel / d[:, None]
        jacobian = np.column_stack([-(r + gap + fr) * (normal @ t), -(normal @ u) - 1.0])
        step = np.linalg.lstsq(jacobian, r - d, rcond=None)[0]
        phi, r = phi + float(step[0]), r + float(step[1])
        if not (np.isfinite(r) and r > 0):
            return None
        if abs(step[0]) * (r + fr) < tol and abs(step[1]) < tol:
            centre = (fx, fy) + (r + gap + fr) * np.array([math.cos(phi), math.sin(phi)])
            return float(centre[0]), float(centre[1]), r
    return None


def biweight_loss(xy, cx, cy, r, cutoff):
    """Tukey's biweight loss sum (each point 0..1) of points about a circle, with cutoff (m) the
    residual beyond which a point costs 1: compares circles fitted by fit_circle_robust at one scale."""
    xy = _xy(xy)
    t = np.minimum(np.abs(np.hypot(xy[:, 0] - cx, xy[:, 1] - cy) - r) / cutoff, 1.0)
    return float(np.sum(1.0 - (1.0 - t * t) ** 3))


def band_run(band_on, band_inside, fraction, min_points, max_gap, blocked=None, starts=3, across=None):
    """The run of bands along a cylinder's axis that its circle explains: (first, last) band, or None.

    band_on, band_inside: points per band on the circle and inside its disc (height bands of an
    upright can in can_search, bands along a lying can's axis in lying). A run starts at the band
    with most points on the circle and grows while a band has at least max(min_points, fraction x
    the start's) on it and no more inside than on it, over gaps of at most max_gap bands; a band
    `blocked` (bool, per band; None: none) ends it, no gap (another object is seen there). Of the
    runs from the fullest band and from the fullest beyond the runs before it (up to `starts`), the
    one with most points on the circle; then up over longer gaps that across(first, last) (bands;
    None: none) says the side is hidden over, to the run beyond each."""
    # A start is a band with no more inside than on the circle (not the lid's band).
    side_like = band_inside <= band_on
    candidates = np.where(side_like, band_on, -1)
    ends = np.zeros(len(band_on), bool) if blocked is None else np.asarray(blocked, bool)
    # A copy: the runs found block the next ones.
    blocked = ends.copy()
    best, most, best_good = None, -1, None
    for _ in range(starts):
        start = int(np.argmax(candidates))
        need = max(min_points, fraction * band_on[start])
        if candidates[start] < need:
            break
        good = (band_on >= need) & side_like
        run = (_last_good(good, blocked, start, range(start - 1, -1, -1), max_gap),
               _last_good(good, blocked, start, range(start + 1, len(good)), max_gap))
        total = int(band_on[run[0]:run[1] + 1][good[run[0]:run[1] + 1]].sum())
        if total > most:
            best, most, best_good = run, total, good
        # The next run starts beyond this one and does not reach into it.
        candidates[run[0]:run[1] + 1] = -1
        blocked[run[0]:run[1] + 1] = True
    if best is None or across is None:
        return best
    # Not down: below a gap lie the surface a can stands on and what stands beside its base.
    lo, hi = best
    while True:
        beyond = hi + 1
        while beyond < len(best_good) and not (best_good[beyond] or ends[beyond]):
            beyond += 1
        if beyond == len(best_good) or ends[beyond] or beyond - hi - 1 <= max_gap or not across(hi + 1, beyond - 1):
            return lo, hi
        hi = _last_good(best_good, ends, beyond, range(beyond + 1, len(best_good)), max_gap)


def _last_good(good, blocked, start, order, max_gap):
    """The last good band met walking `order` from start, over gaps of at most max_gap bands, up to
    a blocked band."""
    last, gap = start, 0
    for b in order:
        if blocked[b]:
            break
        if good[b]:
            last, gap = b, 0
        else:
            gap += 1
            if gap > max_gap:
                break
    return last
