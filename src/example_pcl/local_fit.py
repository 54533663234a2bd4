"""Fast per-frame refit of a known table and known cans: pure functions on NumPy arrays.

Consecutive frames of a live stream are nearly the same, so a can found in one frame is looked
for only near where it was in the next (issue 12). Given an organized cloud (float32 (H, W, 3),
sensor frame, metres, NaN holes):

1. **Table.** The previous table plane is refined by least squares on every ``table_step``-th
   pixel within ``table_band`` of it (geometry.refine_plane); a plane that tilted more than
   ``max_table_tilt`` or moved more than ``max_table_shift`` is a different scene.
2. **Cans.** Each can is refitted from the pixels of a window around its previous footprint (its
   previous points' bounding box grown by ``roi_margin`` px) that lie, in the new plane frame,
   within its previous radius plus ``region_margin`` of its previous axis and between ``min_height``
   and below its top (plus ``region_margin``; a can keeps the height the full search measured, whose
   lid a cup on it may hide): Tukey's biweight (geometry.fit_circle_robust, as the search refits a
   can touching something) from the previous circle on the side points, then auto_finder's criterion
   on radius, inlier fraction (of the side points within the fitted disc, so a neighbour touching it
   does not count), rms residual, shape error and visible arc (the search's ``min_hidden_arc`` or
   ``min_occluded_arc`` for a can it found partly hidden), plus a radius change of at most
   ``max_radius_change``. A can whose base is hidden and whose side shows too little (the search
   found it by its lid, behind a taller can) is refitted by its lid's rim (geometry.rim_circle), and
   so is one whose side showed over less than ``min_hidden_arc`` when its lid's rim passes (a
   narrow stripe of side does not fix a circle; else its side as above, with the radius kept).
   A lying can (can_search's, on its side) is refitted from the pixels of its window within its
   radius plus ``region_margin`` of its previous axis, between its ends grown by
   ``region_margin``: Gauss-Newton on its horizontal axis and radius (lying.py) from the previous
   cylinder, then lying.judge_lying's criterion and the same radius change.
3. **Scene changed?** On a coarse grid (every ``change_step``-th pixel), the points standing on
   the table (as auto_finder counts support: above ``min_height`` plus 3.5 sigma of depth noise,
   below ``max_height``) that are in no can's region (a lying can's: along its axis) and were not
   already there at the last full search (that mask grown by ``change_dilation`` cells, for a
   slowly moving camera) are counted; ``min_new_points`` or more means something new stands there.

:class:`LocalFinder` strings these together frame after frame and falls back on the full search
(auto_finder.find_cans) on the first frame, every ``search_period`` frames, and whenever the
table or a can is lost or the scene changed. It can also leave that search to its caller
(``process(xyz, search=False)``): the frame keeps what the refit found, and the search's result
(:func:`search_frame`, on that frame's copy) is handed back later with ``adopt`` as the seeds of
the next refit. :class:`BackgroundSearchFinder` does so with the search on an executor (a worker
thread in can_tracker), so the search (20-45 ms a real frame) leaves the frame path. Every length is in metres.
"""
import dataclasses
import math
import time
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import List

import numpy as np
from scipy import ndimage

from example_pcl import _native
from example_pcl import auto_finder as af
from example_pcl import can_search
from example_pcl import geometry as g
from example_pcl import lying
from example_pcl import transforms
from example_pcl.can import Can
from example_pcl.errors import PerceptionError, require_positive


@dataclass(frozen=True)
class LocalFitConfig:
    """Parameters of the local refit (see the module docstring). auto: the full search's
    AutoConfig, whose object band (min_height, max_height), fit (fit_bottom, top_margin, r_eps,
    noise model, iterations) and criterion the local fit shares.

    Table: table_step (px), table_band (m), table_iterations; max_table_tilt (rad),
    max_table_shift (m): how far the plane may move between frames.
    Cans: roi_margin (px), region_margin (m), max_radius_change (m); max_fit_points: larger
    sides are subsampled evenly (fewer than the full search's: the start is already close);
    fit_tolerance (m): the fit stops at a shorter step.
    Change: change_step (px), change_dilation (coarse cells), min_new_points.
    search_period (frames): a full search at least this often (1: every frame).
    """

    auto: af.AutoConfig = field(default_factory=af.AutoConfig)
    table_step: int = 8
    table_band: float = 0.01
    table_iterations: int = 1
    max_table_tilt: float = 0.05
    max_table_shift: float = 0.03
    roi_margin: int = 12
    region_margin: float = 0.015
    max_radius_change: float = 0.005
    max_fit_points: int = 300
    fit_tolerance: float = 1e-4
    change_step: int = 8
    change_dilation: int = 2
    min_new_points: int = 4
    search_period: int = 30

    def validate(self):
        """Raises PerceptionError naming the first value that makes no sense."""
        self.auto.validate()
        require_positive(self, ("table_step", "table_band", "table_iterations", "max_table_tilt", "max_table_shift",
                                "region_margin", "max_radius_change", "max_fit_points", "fit_tolerance",
                                "change_step", "min_new_points", "search_period"))
        for name in ("roi_margin", "change_dilation"):
            if getattr(self, name) < 0:
                raise PerceptionError(f"LocalFitConfig.{name} must be >= 0, got {getattr(self, name)}")


def _point(p):
    p = np.asarray(p, dtype=float).reshape(-1)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise PerceptionError(f"the viewpoint must be 3 finite numbers (m), got {p!r}")
    return p


def _organized(xyz):
    pts = np.asarray(xyz)
    if pts.ndim != 3 or pts.shape[2] != 3 or pts.dtype != np.float32:
        raise PerceptionError(f"the local fit needs an organized float32 (H, W, 3) cloud, got {pts.dtype} "
                              f"{pts.shape}")
    return pts


# --- table ----------------------------------------------------------------------------------------


def refit_table(xyz, plane, config=LocalFitConfig(), viewpoint=(0.0, 0.0, 0.0)):
    """The table near the previous plane: (Plane, T_sensor_from_plane).

    xyz: float32 (H, W, 3) sensor frame (m); plane: the previous table Plane. Raises
    PerceptionError when too few points lie near it or it tilted or moved too far.
    """
    pts = _organized(xyz)
    s = int(config.table_step)
    new, T, _, _ = g.refine_plane(pts[::s, ::s], plane, config.table_band, viewpoint,
                                  iterations=config.table_iterations, final_inliers=False)
    tilt = math.acos(min(max(float(new.normal @ plane.normal), -1.0), 1.0))
    shift = abs(float(new.signed_distance(plane.centroid)))
    if tilt > config.max_table_tilt or shift > config.max_table_shift:
        raise PerceptionError(f"the table moved {1e3 * shift:.1f} mm and tilted {tilt:.3f} rad since the last frame")
    return new, T


# --- cans -----------------------------------------------------------------------------------------


def pixel_window(indices, shape, margin):
    """(row_start, row_stop, col_start, col_stop): the bounding box of flattened pixel indices
    (int, into an image of shape (H, W, ...)) grown by margin (px), clipped to the image."""
    height, width = shape[:2]
    indices = np.asarray(indices, dtype=np.int64)
    if indices.size == 0:
        raise PerceptionError("a pixel window needs at least one pixel")
    rows, cols = np.divmod(indices, width)
    m = int(margin)
    return (max(int(rows.min()) - m, 0), min(int(rows.max()) + m + 1, height),
            max(int(cols.min()) - m, 0), min(int(cols.max()) + m + 1, width))


def refit_can(xyz, T_sensor_from_plane, can, config=LocalFitConfig(), viewpoint=(0.0, 0.0, 0.0)):
    """One can refitted near where it was: an example_pcl.can.Can (sensor frame).

    xyz: float32 (H, W, 3) sensor frame (m); T_sensor_from_plane: this frame's table frame; can:
    the previous detection (base_center, radius, indices: flattened pixels of its points).
    Raises PerceptionError saying why when the can is not there any more (too few points, no
    circle, or the criterion fails).
    """
    T_plane_from_sensor = transforms.invert(T_sensor_from_plane)
    sensor = transforms.apply(T_plane_from_sensor, _point(viewpoint))
    return _refit_can(_organized(xyz), T_sensor_from_plane, T_plane_from_sensor, sensor, can, config)


def _refit_can(pts, T_sensor_from_plane, T_plane_from_sensor, sensor_plane, can, config):
    """refit_can on a checked cloud, with the plane frame's inverse and the sensor's position in
    it computed once per frame. Runs once per can per frame, so it keeps to few NumPy calls:
    the window is cropped before anything is transformed, and only the window's points in the
    can's region are gathered."""
    c, a = config, config.auto
    r0, r1, c0, c1 = pixel_window(can.indices, pts.shape, c.roi_margin)
    window = _native.transform_cloud(pts[r0:r1, c0:c1], T_plane_from_sensor).reshape(-1, 3)
    center = T_plane_from_sensor[:3, :3] @ can.T_sensor_from_can[:3, 3] + T_plane_from_sensor[:3, 3]
    # A can standing on an object (can_search) keeps that base height: its side starts there.
    base = float(can.support_height)
    low = a.min_height if base <= 0 else base + a.fit_bottom
    # The top (m above the table) is the search's: its lid may be hidden (a cup on it) or crowded (a
    # narrower can on it, a neighbour within region_margin), which the search looks at and a refit
    # does not.
    bottom = max(base, 0.0)
    top = bottom + can.height
    # NaN compares False: holes fall out of the region without a check of their own.
    dx, dy, z = window[:, 0] - center[0], window[:, 1] - center[1], window[:, 2]
    region = dx * dx + dy * dy <= (can.radius + c.region_margin) ** 2
    region &= z > low
    # A can does not grow: what stands on it (a cup) or rises beside it (a taller can or box) above
    # its top is not its side.
    region &= z <= min(a.max_height, top + c.region_margin)
    flat = np.flatnonzero(region)
    if len(flat) < a.min_fit_points:
        raise PerceptionError(f"{len(flat)} point(s) where the can was (min {a.min_fit_points})")
    points = window[flat].astype(float)
    z = points[:, 2]
    # The mean as a matrix-vector product: NumPy's mean over axis 0 of (N, 3) costs 4x more.
    sigma = a.depth_sigma(np.ones(len(points)) @ points / len(points), sensor_plane)
    r_eps = a.r_eps_at(sigma)
    side = points[(z >= bottom + a.fit_bottom + 3 * sigma) & (z <= top - a.top_margin - 3 * sigma), :2]
    rows, cols = np.divmod(flat, c1 - c0)
    indices = (rows + r0) * pts.shape[1] + (cols + c0)
    # Its side hidden behind something in front (the search found it by its lid), or seen over so narrow
    # a stripe (beside a can in front, or judged on its lid's rim) that it does not fix a circle: the
    # lid's rim, and for the stripe its side where the rim does not pass.
    hidden = len(side) < a.min_fit_points and not can.base_seen
    if hidden or can.arc_coverage < a.cylinders.min_hidden_arc:
        try:
            return _refit_lid(points, indices, T_sensor_from_plane, sensor_plane, can, top, sigma, r_eps, config)
        except PerceptionError:
            if hidden:
                raise
    if len(side) < a.min_fit_points:
        raise PerceptionError(f"{len(side)} side point(s) where the can was (min {a.min_fit_points})")
    if len(side) > c.max_fit_points:
        side = side[:: int(np.ceil(len(side) / c.max_fit_points))]
    # Tukey's biweight from the previous circle, as the search refits a can touching something: a
    # box face or a neighbour can within r_eps of the circle pulls least squares onto itself.
    robust = a.cylinders
    # A stripe of side narrower than min_hidden_arc does not fix a radius: refitted freely frame after
    # frame, the radius wandered by up to 7 mm and the axis up to 4.5 mm (held-out 1207 of "cluttered
    # table"); the search's radius is kept.
    cx, cy, radius, scale = g.fit_circle_robust(side, center[:2], can.radius, r_eps, k=robust.robust_k,
                                                min_scale=robust.robust_min_scale, max_iterations=a.fit_iterations,
                                                tol=c.fit_tolerance, max_shift=c.region_margin,
                                                fixed_radius=can.arc_coverage < robust.min_hidden_arc)
    if not a.min_radius <= radius <= a.max_radius or abs(radius - can.radius) > c.max_radius_change:
        raise PerceptionError(f"radius {1e3 * radius:.1f} mm (was {1e3 * can.radius:.1f} mm)")
    dist = np.hypot(side[:, 0] - cx, side[:, 1] - cy)
    inliers = np.abs(dist - radius) <= min(r_eps, robust.robust_k * scale)
    n_inliers = int(np.count_nonzero(inliers))
    if n_inliers < a.min_fit_points:
        raise PerceptionError(f"{n_inliers} side point(s) on the circle (min {a.min_fit_points})")
    # Of the side points within the disc, as the full search counts them: a neighbour touching the
    # can lies outside it.
    in_disc = int(np.count_nonzero(dist <= radius + r_eps))
    if n_inliers < a.min_inlier_fraction * in_disc:
        raise PerceptionError(f"only {n_inliers} of the {in_disc} side points within its disc on the circle")
    residual = dist[inliers] - radius
    rms = float(np.sqrt(residual @ residual / n_inliers))
    max_rms = max(a.max_rms, a.max_rms_sigmas * sigma)
    if rms > max_rms:
        raise PerceptionError(f"rms residual {1e3 * rms:.2f} mm > {1e3 * max_rms:.2f} mm")
    arc = g.arc_coverage(side[inliers], cx, cy)
    # A can found with less of its side seen (the search saw an object in front of it, or the rest
    # of its near half hidden) keeps the search's lower bound for that case.
    min_arc = (a.min_arc if can.arc_coverage >= a.min_arc else robust.min_hidden_arc
               if can.arc_coverage >= robust.min_hidden_arc else robust.min_occluded_arc)
    if arc < min_arc:
        raise PerceptionError(f"side seen over {arc:.2f} rad < {min_arc:.2f} rad")
    shape = af.shape_error(side[inliers], cx, cy, radius, a.shape_bins)
    if shape > a.max_shape_error:
        raise PerceptionError(f"shape error {1e3 * shape:.2f} mm > {1e3 * a.max_shape_error:.2f} mm (not round)")
    T_can = g.can_pose(T_sensor_from_plane, cx, cy, base)
    return Can(T_sensor_from_can=T_can, radius=radius, height=can.height, rms_error=rms,
               arc_coverage=arc, n_points=len(flat), n_fit_points=n_inliers,
               center_plane=np.array([cx, cy]), shape_error=shape, indices=indices, support=can.support,
               base_seen=can.base_seen, support_height=base)


def _refit_lid(points, indices, T_sensor_from_plane, sensor_plane, can, top, sigma, r_eps, config):
    """A can whose side is hidden, refitted by its lid's rim (geometry.rim_circle on the region's
    points within max(5 mm, 3 sigma) of its top; plane frame, m): the search's criterion for a can
    seen by its lid (can_search._lid_only) on rms and the rim's arc, and the radius change."""
    c, a = config, config.auto
    lid = can_search.lid_points(points, top, sigma)
    if len(lid) < a.min_fit_points:
        raise PerceptionError(f"{len(lid)} side or lid point(s) where the can was (min {a.min_fit_points})")
    rim = g.rim_circle(lid, sensor_plane[:2], r_eps)
    if rim is None or abs(rim.radius - can.radius) > c.max_radius_change:
        raise PerceptionError("its lid's rim fits no circle of its radius")
    if not rim.fits(sigma, a.cylinders.lid_arc):
        raise PerceptionError(f"its lid's rim: rms {1e3 * rim.rms:.2f} mm, seen over {rim.arc():.2f} rad")
    T_can = g.can_pose(T_sensor_from_plane, rim.cx, rim.cy, can.support_height)
    return dataclasses.replace(can, T_sensor_from_can=T_can, radius=rim.radius, rms_error=rim.rms,
                               n_points=len(points), n_fit_points=len(rim.outline),
                               center_plane=np.array([rim.cx, rim.cy]), indices=indices)


def refit_lying_can(xyz, T_sensor_from_plane, can, config=LocalFitConfig(), viewpoint=(0.0, 0.0, 0.0), others=()):
    """A lying can (Can with lying=True) refitted near where it was: a Can (sensor frame), as
    refit_can does for an upright one. others: the other cans known in this frame (Can list,
    sensor frame), whose points are not this one's. Raises PerceptionError saying why when it is
    not there any more (too few points, no horizontal cylinder, or lying.judge_lying's criterion
    fails)."""
    T_plane_from_sensor = transforms.invert(T_sensor_from_plane)
    sensor = transforms.apply(T_plane_from_sensor, _point(viewpoint))
    return _refit_lying(_organized(xyz), T_sensor_from_plane, T_plane_from_sensor, sensor, can, config, others)


def _refit_lying(pts, T_sensor_from_plane, T_plane_from_sensor, sensor_plane, can, config, others=()):
    """refit_lying_can on a checked cloud (see _refit_can). The points are those of the window
    within the previous radius plus region_margin of the previous axis and along it within
    region_margin of its ends, in this frame's plane frame, less those within r_eps of another
    can (a can standing near an end would otherwise lengthen it frame after frame: no cluster
    separates them here); Gauss-Newton (lying.refine_lying_cylinder) starts from the previous
    cylinder, then lying.judge_lying and a radius change of at most max_radius_change."""
    c, a = config, config.auto
    r0, r1, c0, c1 = pixel_window(can.indices, pts.shape, c.roi_margin)
    window = _native.transform_cloud(pts[r0:r1, c0:c1], T_plane_from_sensor).reshape(-1, 3)
    start = transforms.apply(T_plane_from_sensor, can.base_center)
    u = T_plane_from_sensor[:3, :3] @ can.axis
    u = u[:2] / max(float(np.hypot(u[0], u[1])), 1e-9)  # the table may have tilted a little: seen from above
    # NaN compares False: holes fall out of the region without a check of their own.
    dx, dy, dz = window[:, 0] - start[0], window[:, 1] - start[1], window[:, 2] - start[2]
    along = dx * u[0] + dy * u[1]
    across = -dx * u[1] + dy * u[0]
    region = (along >= -c.region_margin) & (along <= can.height + c.region_margin)
    region &= across * across + dz * dz <= (can.radius + c.region_margin) ** 2
    region &= (window[:, 2] > a.min_height) & (window[:, 2] <= a.max_height)
    flat = np.flatnonzero(region)
    if len(others):
        flat = flat[~in_can_regions(window[flat], T_plane_from_sensor, others, a.r_eps)]
    if len(flat) < a.min_fit_points:
        raise PerceptionError(f"{len(flat)} point(s) where the lying can was (min {a.min_fit_points})")
    points = window[flat].astype(float)
    sigma = a.depth_sigma(np.ones(len(points)) @ points / len(points), sensor_plane)
    r_eps = a.r_eps_at(sigma)
    s = a.cylinders
    fit = lying.refine_lying_cylinder(points, start, u, can.radius, r_eps, a.max_radius, s.lying_gap + 3 * sigma,
                                      a.fit_iterations, c.max_fit_points, sensor_plane)
    # A can the search found with less of its side seen (behind another) keeps the search's lower bound.
    min_arc = a.min_arc if can.arc_coverage >= a.min_arc else s.min_occluded_arc
    found, why = lying.judge_lying(points, fit, r_eps, sigma, a, s, sensor_plane, min_arc=min_arc)
    if found is None:
        raise PerceptionError(why)
    if abs(found.fit.radius - can.radius) > c.max_radius_change:
        raise PerceptionError(f"radius {1e3 * found.fit.radius:.1f} mm (was {1e3 * can.radius:.1f} mm)")
    begin, direction = found.start, found.direction
    if direction[:2] @ u < 0:  # the same end as before is the can's origin, so its pose does not jump
        begin, direction = begin + found.length * direction, -direction
    T_can = g.lying_can_pose(T_sensor_from_plane, begin, direction)
    middle = begin + 0.5 * found.length * direction
    rows, cols = np.divmod(flat[found.mine], c1 - c0)
    indices = (rows + r0) * pts.shape[1] + (cols + c0)
    return dataclasses.replace(can, T_sensor_from_can=T_can, radius=found.fit.radius, height=found.length,
                               rms_error=found.rms, arc_coverage=found.arc, n_points=int(found.mine.sum()),
                               n_fit_points=int(found.inliers.sum()), center_plane=middle[:2].copy(),
                               shape_error=found.shape_error, indices=indices)


# --- scene change ---------------------------------------------------------------------------------


def standing_grid(xyz, T_sensor_from_plane, config=LocalFitConfig(), viewpoint=(0.0, 0.0, 0.0)):
    """Which pixels of the coarse grid (every change_step-th pixel) stand on the table: bool
    (ceil(H / step), ceil(W / step)), and those points in the plane frame (float32, same grid)."""
    pts = _organized(xyz)
    s, a = int(config.change_step), config.auto
    sample = pts[::s, ::s]
    grid = _native.transform_cloud(sample, transforms.invert(T_sensor_from_plane))
    v = sample - _point(viewpoint).astype(np.float32)
    sigma = a.noise_coefficient * np.einsum("ijk,ijk->ij", v, v)  # float32: a noise level needs no more
    # NaN compares False: holes never stand.
    standing = (grid[..., 2] > a.min_height + 3.5 * sigma) & (grid[..., 2] < a.max_height)
    return standing, grid


def in_can_regions(grid, T_plane_from_sensor_cans, cans, margin):
    """bool mask of plane-frame points (..., 3) within radius + margin (m) of any can's axis seen
    from above (a lying can's: of its axis between its ends, each end grown by margin too).
    T_plane_from_sensor_cans: 4x4 taking the cans' sensor-frame poses into the plane frame."""
    inside = np.zeros(grid.shape[:-1], bool)
    R, t = T_plane_from_sensor_cans[:3, :3], T_plane_from_sensor_cans[:3, 3]
    with np.errstate(invalid="ignore"):
        for can in cans:
            cx, cy, _ = R @ np.asarray(can.base_center, dtype=float) + t
            dx, dy = grid[..., 0] - cx, grid[..., 1] - cy
            if not can.lying:
                inside |= dx * dx + dy * dy <= (can.radius + margin) ** 2
                continue
            ux, uy, _ = R @ np.asarray(can.axis, dtype=float)
            norm = max(float(np.hypot(ux, uy)), 1e-9)
            along = (dx * ux + dy * uy) / norm
            inside |= ((along >= -margin) & (along <= can.height + margin)
                       & (np.abs(dy * ux - dx * uy) / norm <= can.radius + margin))
    return inside


def new_standing_points(standing, grid, T_plane_from_sensor, cans, known, config=LocalFitConfig()):
    """How many coarse-grid points stand on the table outside every can's region and outside
    `known` (bool, the standing mask of the last full search without its cans; None: nothing
    known) grown by change_dilation cells."""
    new = standing & ~in_can_regions(grid, T_plane_from_sensor, cans, config.region_margin)
    if known is not None and known.shape == new.shape and known.any():
        if config.change_dilation > 0:
            known = ndimage.binary_dilation(known, iterations=int(config.change_dilation))
        new &= ~known
    return int(np.count_nonzero(new))


# --- frame after frame ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FrameFit:
    """One frame's result. cans: example_pcl.can.Can list (sensor frame); table: Plane;
    T_sensor_from_plane: 4x4; searched: whether the full search ran on this frame; reason: why
    the search was wanted ("" when not: "first frame", "periodic", "table lost: ...", "can k lost:
    ...", "scene changed: ..."; with searched False, the search was left to the caller and the
    cans are the refit's, the lost ones left out); adopted: whether a search of an earlier frame
    seeded this frame's refit; timings: seconds per stage (table, cans, change, search, copy,
    background search, total; a stage not run is absent)."""

    cans: List[Can]
    table: g.Plane
    T_sensor_from_plane: np.ndarray
    searched: bool
    reason: str
    timings: dict
    adopted: bool = False


@dataclass(frozen=True, eq=False)
class SceneSearch:
    """The full search on one frame, as LocalFinder keeps it: table (Plane), T_sensor_from_plane
    (4x4), cans (Can list, sensor frame), known (bool coarse grid: the points standing on the
    table outside every can, see new_standing_points), seconds (wall time of the search)."""

    table: g.Plane
    T_sensor_from_plane: np.ndarray
    cans: List[Can]
    known: np.ndarray
    seconds: float


def search_frame(xyz, config=LocalFitConfig(), viewpoint=(0.0, 0.0, 0.0)):
    """The full search (auto_finder.find_cans) on an organized frame: a SceneSearch. xyz: float32
    (H, W, 3), any strides, sensor frame (m). Raises PerceptionError when it finds no table."""
    t0 = time.perf_counter()
    pts = _organized(xyz)
    viewpoint = _point(viewpoint)
    # The refit reads a strided view (x, y, z inside XYZRGB points) as fast as a copy; the search,
    # many passes over the whole cloud, is faster on a contiguous one: copied only here.
    result = af.find_cans(np.ascontiguousarray(pts), viewpoint, config.auto)
    T, cans = result.T_sensor_from_plane, list(result.cans)
    standing, grid = standing_grid(pts, T, config, viewpoint)
    known = standing & ~in_can_regions(grid, transforms.invert(T), cans, config.region_margin)
    return SceneSearch(table=result.table, T_sensor_from_plane=T, cans=cans, known=known,
                       seconds=time.perf_counter() - t0)


class LocalFinder:
    """Finds the table and the cans frame after frame: the local refit where it holds, the full
    search (auto_finder.find_cans) where it does not (see the module docstring). epoch counts the
    times its state was replaced other than by adopt (reset, a search of its own): a search begun
    in an earlier epoch is older than what the finder knows."""

    def __init__(self, config=LocalFitConfig(), viewpoint=(0.0, 0.0, 0.0)):
        config.validate()
        self.config = config
        self.viewpoint = _point(viewpoint)
        self.epoch = 0
        self.reset()

    def reset(self):
        """Forgets the table and the cans: the next frame runs the full search."""
        self._table = None
        self._T = None
        self._cans = []
        self._known = None
        self._since_search = 0
        self.epoch += 1

    def process(self, xyz, search=True):
        """One organized frame (float32 (H, W, 3), any strides, sensor frame, m): a FrameFit. Raises
        PerceptionError (and forgets everything) when even the full search finds no table.

        search=False: when the refit of a known table holds but the full search is wanted anyway
        (periodic, a can lost, the scene changed), the frame's result is the refit's (the lost cans
        left out; FrameFit.searched False, reason set) and the search is the caller's, handed back
        with adopt. Without a table (first frame, table lost) the search runs here all the same.
        """
        t0 = time.perf_counter()
        pts = _organized(xyz)
        timings = {}
        reason, refitted = self._local(pts, timings, defer=not search)
        if refitted:
            self._since_search += 1
        else:
            t = time.perf_counter()
            try:
                self._take(search_frame(pts, self.config, self.viewpoint))
            except PerceptionError:
                self.reset()
                raise
            self.epoch += 1
            timings["search"] = time.perf_counter() - t
        timings["total"] = time.perf_counter() - t0
        return FrameFit(cans=list(self._cans), table=self._table, T_sensor_from_plane=self._T,
                        searched=not refitted, reason=reason, timings=timings)

    def adopt(self, found):
        """Takes a SceneSearch (of this frame or an earlier one) as the seeds of the next refit: its
        table, its cans and its scene-change mask. A can that the refits since that frame have
        followed (an upright can of the search whose base centre is within its radius of a
        refitted one, or a lying can whose axis' middle is) keeps its fresher fit, so a can moved
        meanwhile is looked for where it is; an upright one with the search's height and radius
        (the refit keeps the height it was given, and the radius of a can seen over a narrow arc)."""
        cans = []
        for can in found.cans:
            here = can.footprint_center
            near = [c for c in self._cans if c.lying == can.lying
                    and np.linalg.norm(c.footprint_center - here) < can.radius]
            if not near:
                cans.append(can)
                continue
            fresher = min(near, key=lambda c: np.linalg.norm(c.footprint_center - here))
            cans.append(fresher if can.lying else dataclasses.replace(fresher, height=can.height, radius=can.radius))
        self._take(dataclasses.replace(found, cans=cans))

    def _take(self, found):
        self._table, self._T, self._cans, self._known = found.table, found.T_sensor_from_plane, list(found.cans), \
            found.known
        self._since_search = 0

    def _local(self, pts, timings, defer):
        """Refits; returns (why the full search is wanted or "", whether the refit was kept). The
        refit is kept when nothing calls for the search, or with defer when the table held."""
        c = self.config
        if self._table is None or (self._known is not None and self._known.shape != self._grid_shape(pts)):
            return "first frame", False
        periodic = "periodic" if self._since_search + 1 >= c.search_period else ""
        if periodic and not defer:
            return periodic, False
        t = time.perf_counter()
        try:
            table, T = refit_table(pts, self._table, c, self.viewpoint)
        except PerceptionError as e:
            return f"table lost: {e}", False
        finally:
            timings["table"] = time.perf_counter() - t
        t = time.perf_counter()
        T_plane_from_sensor = transforms.invert(T)
        sensor = transforms.apply(T_plane_from_sensor, self.viewpoint)
        lost = ""
        # Upright cans first: a lying can's refit leaves their points out (_refit_lying).
        refitted = {}
        for k in sorted(range(len(self._cans)), key=lambda k: self._cans[k].lying):
            can = self._cans[k]
            try:
                if can.lying:
                    others = [refitted.get(j, other) for j, other in enumerate(self._cans) if j != k]
                    refitted[k] = _refit_lying(pts, T, T_plane_from_sensor, sensor, can, c, others)
                else:
                    refitted[k] = _refit_can(pts, T, T_plane_from_sensor, sensor, can, c)
            except PerceptionError as e:
                lost = lost or f"can {k} lost: {e}"
                if not defer:
                    timings["cans"] = time.perf_counter() - t
                    return lost, False
        cans = af.mark_unseen_ends([refitted[k] for k in sorted(refitted)], pts, c.auto)
        timings["cans"] = time.perf_counter() - t
        t = time.perf_counter()
        standing, grid = standing_grid(pts, T, c, self.viewpoint)
        n_new = new_standing_points(standing, grid, T_plane_from_sensor, cans, self._known, c)
        timings["change"] = time.perf_counter() - t
        changed = f"scene changed: {n_new} new point(s) stand on the table" if n_new >= c.min_new_points else ""
        reason = lost or changed or periodic
        if reason and not defer:
            return reason, False
        self._table, self._T, self._cans = table, T, cans
        return reason, True

    def _grid_shape(self, pts):
        s = int(self.config.change_step)
        return (-(-pts.shape[0] // s), -(-pts.shape[1] // s))


def _run_now(function, *args):
    """An executor's submit that runs function at once: a finished Future."""
    future = Future()
    try:
        future.set_result(function(*args))
    except Exception as e:  # noqa: BLE001 - handed over, as an executor would
        future.set_exception(e)
    return future


class BackgroundSearchFinder:
    """A LocalFinder whose full search, once a table is known, runs beside the frames.

    executor: an object with submit(function, *args) -> concurrent.futures.Future, e.g. a
    ThreadPoolExecutor of one worker (its own thread, so the node owns its lifetime); None runs
    each search at once (deterministic, for tests and replays). process(xyz) refits every frame
    (LocalFinder.process with search=False); a frame that wants the full search hands itself (a
    copy unless its memory never changes) to the executor unless a search is already under way;
    the first frame after that search finished adopts its result (LocalFinder.adopt) and refits
    from it. A search begun before a reset or a search of the finder's own is dropped; one that
    found no table resets the finder (the next frame searches at once). With search_period 1
    (every frame) or no table known, the search runs on the frame itself, as LocalFinder's does.
    """

    def __init__(self, config=LocalFitConfig(), viewpoint=(0.0, 0.0, 0.0), executor=None):
        self.finder = LocalFinder(config, viewpoint)
        self.executor = executor
        self._pending = None  # (Future of a SceneSearch, the finder's epoch when it began)

    @property
    def config(self):
        return self.finder.config

    @property
    def searching(self):
        """Whether a search is under way (submitted, its result not adopted yet)."""
        return self._pending is not None

    def reset(self):
        """Forgets the table and the cans (the next frame runs the full search); a search under way
        is dropped."""
        self.finder.reset()
        self._pending = None

    def process(self, xyz, frozen=False):
        """One organized frame (float32 (H, W, 3), any strides, sensor frame, m): a FrameFit (see
        the class docstring). frozen: xyz views memory that never changes (a received message's
        bytes), so the search may read it later without a copy here. Raises PerceptionError when
        a search on this frame finds no table."""
        t0 = time.perf_counter()
        found = self._finished()
        if found is not None:
            self.finder.adopt(found)
        fit = self.finder.process(xyz, search=self.config.search_period <= 1)
        timings = dict(fit.timings)
        if fit.reason and not fit.searched and self._pending is None:
            t = time.perf_counter()
            # The search's own copy of a frame that may change; search_frame makes it contiguous anyway.
            frame = xyz if frozen else np.array(xyz, dtype=np.float32, order="C")
            t1 = time.perf_counter()
            submit = self.executor.submit if self.executor is not None else _run_now
            self._pending = (submit(search_frame, frame, self.config, self.finder.viewpoint), self.finder.epoch)
            timings["copy"], timings["search" if self.executor is None else "submit"] = t1 - t, time.perf_counter() - t1
        if found is not None:
            timings["background search"] = found.seconds
        timings["total"] = time.perf_counter() - t0
        return dataclasses.replace(fit, timings=timings, adopted=found is not None)

    def _finished(self):
        """The result of a search that finished and is still current, else None."""
        if self._pending is None or not self._pending[0].done():
            return None
        future, epoch = self._pending
        self._pending = None
        if epoch != self.finder.epoch:
            return None
        try:
            return future.result()
        except PerceptionError:
            self.finder.reset()  # as a search on the frame would: no table there, nothing kept
            return None
