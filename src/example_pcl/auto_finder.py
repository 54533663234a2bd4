"""The automatic search (mode 4, ``find_cans``): the table, then every can on it, with no selection.

Pure functions on NumPy arrays; knows nothing of ROS. ``find_cans(xyz)`` takes a Kinect cloud
(float32 (H, W, 3) organized, or (N, 3); sensor frame, metres, NaN holes), finds the support plane
(``find_support_plane``), clusters what stands on it, and searches the clusters for cans: upright,
stacked, partly hidden or lying (``can_search``, the default) or, with ``search="clusters"``,
asks each cluster to be one upright cylinder (the issue 5 finder, ``fit_upright_cylinder``). The
steps and the criterion: docs/can_search.md ("The table and the clusters").
"""
import argparse
import dataclasses
import functools
import json
import sys
import time
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from example_pcl import _native
from example_pcl import can_search
from example_pcl import geometry as g
from example_pcl import lying
from example_pcl import transforms
from example_pcl.can import Can
from example_pcl.errors import PerceptionError, require_positive


# AutoConfig.search: inside clusters (can_search, issue 13), or each cluster one can (issue 5).
SEARCHES = ("cylinders", "clusters")


@dataclass(frozen=True)
class AutoConfig:
    """Parameters of find_cans. Lengths in metres, angles in radians.

    Table: ransac_step (px): RANSAC sees every ransac_step-th pixel in each direction;
    plane_distance: RANSAC inlier distance; max_planes: planes searched at most;
    min_plane_fraction: a plane needs this fraction of the subsampled finite points;
    up: optional (x, y, z) "up" in the sensor frame, then only planes whose normal is within
    max_tilt of it count; refine_step (px), refine_band, refine_iterations: the least-squares
    refinement uses every refine_step-th pixel within refine_band of the plane, up to
    refine_iterations passes (it stops once the plane no longer moves: a RANSAC plane a degree
    off, as on a grazing view, needs more than one); support_step (px),
    min_support: a plane holds objects when at least min_support of every support_step-th
    pixel stand on it.

    Objects: min_height, max_height: the band above the table that objects are taken from;
    cluster_distance: neighbouring points closer than this join a cluster; min_cluster_points:
    smaller clusters are noise and ignored; clustering: "auto" (organized grid when the cloud is
    (H, W, 3), else Euclidean), "organized" or "euclidean".

    Fit: fit_bottom: side points start this high above the table (below it, table noise);
    top_margin: and end this far below the cluster's top (above it, the lid); max_fit_points:
    larger sides are subsampled evenly for the fit; fit_iterations, fit_tolerance (m): the
    Levenberg-Marquardt fit stops after so many iterations or a shorter step;
    noise_coefficient (1/m): the depth noise sigma = noise_coefficient * range^2 (Kinect,
    Khoshelham & Elberink 2012), which widens fit_bottom and top_margin by 3 sigma; r_eps,
    r_eps_sigmas: a side point is an inlier within max(r_eps, r_eps_sigmas * sigma) of the circle.

    Criterion (docs/can_search.md, "The table and the clusters"): max_base_gap, min_can_height,
    min_fit_points, min_radius, max_radius, min_inlier_fraction, max_rms, max_rms_sigmas, shape_bins,
    max_shape_error, min_arc.

    search: "cylinders" (default; can_search: cans inside clusters, stacked, partly hidden, lying,
    with the cup and handle rules) or "clusters" (each cluster one upright can, the issue 5
    finder); cylinders: can_search.CylinderSearchConfig, the former's own parameters.
    """

    ransac_step: int = 8
    plane_distance: float = 0.015
    max_planes: int = 3
    min_plane_fraction: float = 0.05
    up: Optional[Tuple[float, float, float]] = None
    max_tilt: float = 0.35
    refine_step: int = 3
    refine_band: float = 0.01
    refine_iterations: int = 3
    support_step: int = 4
    min_support: int = 10

    min_height: float = 0.015
    max_height: float = 0.4
    cluster_distance: float = 0.02
    min_cluster_points: int = 50
    clustering: str = "auto"

    fit_bottom: float = 0.01
    top_margin: float = 0.01
    max_fit_points: int = 600
    fit_tolerance: float = 1e-5
    fit_iterations: int = 20
    noise_coefficient: float = 1.425e-3
    r_eps: float = 0.006
    r_eps_sigmas: float = 3.0

    max_base_gap: float = 0.03
    min_can_height: float = 0.04
    min_fit_points: int = 30
    min_radius: float = 0.015
    max_radius: float = 0.08
    min_inlier_fraction: float = 0.8
    max_rms: float = 0.003
    max_rms_sigmas: float = 1.0
    shape_bins: int = 8
    max_shape_error: float = 0.001
    min_arc: float = 1.8

    search: str = "cylinders"
    cylinders: can_search.CylinderSearchConfig = can_search.CylinderSearchConfig()

    def depth_sigma(self, point, sensor):
        """The depth noise sigma (m) at point (3,) seen from sensor (3,), one frame, m:
        noise_coefficient x range^2."""
        return self.noise_coefficient * float(np.sum((np.asarray(point) - sensor) ** 2))

    def r_eps_at(self, sigma):
        """The inlier band (m) about a circle where the depth noise is sigma (m): max(r_eps,
        r_eps_sigmas x sigma)."""
        return max(self.r_eps, self.r_eps_sigmas * sigma)

    def validate(self):
        """Raises PerceptionError naming the first value that makes no sense."""
        positive = ("ransac_step", "plane_distance", "max_planes", "refine_step", "refine_band", "refine_iterations",
                    "max_height", "cluster_distance", "min_cluster_points", "max_fit_points", "r_eps", "min_radius",
                    "max_radius", "shape_bins", "min_fit_points")
        require_positive(self, positive)
        if not 0 <= self.min_height < self.max_height:
            raise PerceptionError(f"AutoConfig needs 0 <= min_height < max_height (m), got {self.min_height}, "
                                  f"{self.max_height}")
        if not self.min_radius < self.max_radius:
            raise PerceptionError(f"AutoConfig needs min_radius < max_radius (m), got {self.min_radius}, "
                                  f"{self.max_radius}")
        if self.clustering not in ("auto", "organized", "euclidean"):
            raise PerceptionError("AutoConfig.clustering must be auto, organized or euclidean, "
                                  f"got {self.clustering!r}")
        if self.search not in SEARCHES:
            raise PerceptionError(f"AutoConfig.search must be one of {', '.join(SEARCHES)}, got {self.search!r}")
        self.cylinders.validate()
        if self.up is not None:
            g.unit_vector(self.up, "AutoConfig.up")


@dataclass(frozen=True, eq=False)
class RejectedCluster:
    """A cluster on the table that is not a can: centroid (float64 (3,), sensor frame, m),
    n_points, reason (the first criterion it failed, with the figures), and the circle fitted
    (radius, m; None when no fit was made)."""

    centroid: np.ndarray
    n_points: int
    reason: str
    radius: Optional[float] = None

    def to_dict(self):
        return {"centroid": self.centroid.tolist(), "n_points": self.n_points, "reason": self.reason,
                "radius": self.radius}


@dataclass(frozen=True, eq=False)
class AutoResult:
    """What find_cans found: the table (Plane, sensor frame) and T_sensor_from_plane (4x4); cans
    best first (most side points in the fit first: the best-measured); rejected clusters;
    candidate_planes: (Plane, points standing on it) per RANSAC plane considered (subsampled
    counts); timings: seconds per stage (table, transform, clusters, fits, total)."""

    table: g.Plane
    T_sensor_from_plane: np.ndarray
    cans: List[Can]
    rejected: List[RejectedCluster]
    candidate_planes: list
    timings: dict

    @property
    def message(self):
        """One line for a log: how many cans (how many of them lying), or why none."""
        if self.cans:
            radii = ", ".join(f"{1e3 * c.radius:.1f}" for c in self.cans)
            lying = sum(1 for c in self.cans if c.lying)
            return f"found {len(self.cans)} can(s){f', {lying} lying' if lying else ''}, radii {radii} mm"
        if self.rejected:
            return f"no can found: {len(self.rejected)} object(s) on the support plane, none a can"
        return "no can found: nothing stands on the support plane"

    def to_dict(self):
        """JSON-able summary."""
        return {"message": self.message,
                "table": {"normal": self.table.normal.tolist(), "d": self.table.d,
                          "n_points": self.table.n_points,
                          "T_sensor_from_plane": self.T_sensor_from_plane.tolist()},
                "cans": [c.to_dict() for c in self.cans],
                "rejected": [r.to_dict() for r in self.rejected],
                "timings_ms": {k: round(1e3 * v, 3) for k, v in self.timings.items()}}


# --- the table ------------------------------------------------------------------------------------


def _finite_rows(points):
    """The finite points of an (N, 3) array: float32 (M, 3) contiguous."""
    return np.ascontiguousarray(points[np.isfinite(points).all(axis=1)], dtype=np.float32)


def find_support_plane(xyz, viewpoint=(0.0, 0.0, 0.0), config=AutoConfig()):
    """The plane the objects stand on (docs/can_search.md, "The table and the clusters").

    xyz: float32 (H, W, 3) or (N, 3), sensor frame (m), NaN allowed; viewpoint: the sensor
    (sensor frame, m); normals are turned toward it. Returns (Plane, T_sensor_from_plane,
    candidates): candidates are (Plane, support) for each RANSAC plane, support being the number
    of subsampled points standing on it. Raises PerceptionError when the cloud has too few finite
    points or no plane is large enough.
    """
    viewpoint = g.as_vector3(viewpoint, "viewpoint")
    pts = g.as_points_float32(xyz)
    step = int(config.ransac_step)
    sub = _finite_rows(g.subsample(pts, step).reshape(-1, 3))
    if len(sub) < 3:
        raise PerceptionError(f"the cloud has {len(sub)} finite point(s) at a {step}-pixel step; no table "
                              "can be found (is the sensor covered or the cloud empty?)")
    min_inliers = max(int(config.min_plane_fraction * len(sub)), 3)
    axis = None if config.up is None else tuple(float(v) for v in g.unit_vector(config.up, "up"))
    planes, remaining = [], sub
    for _ in range(int(config.max_planes)):
        if len(remaining) < min_inliers:
            break
        try:
            coefficients, inliers = _native.segment_plane(remaining, config.plane_distance, axis=axis,
                                                          eps_angle=config.max_tilt)
        except ValueError:
            break
        if len(inliers) < min_inliers:
            break
        normal = coefficients[:3].astype(float)
        normal /= np.linalg.norm(normal)
        centroid = remaining[inliers].mean(axis=0, dtype=float)
        planes.append(g.Plane.through(normal, centroid, viewpoint, 0.0, len(inliers)))
        mask = np.ones(len(remaining), bool)
        mask[inliers] = False
        remaining = remaining[mask]
    if not planes:
        what = "" if axis is None else f" within {config.max_tilt} rad of up = {axis}"
        raise PerceptionError(f"no plane{what} holds {min_inliers} of the {len(sub)} subsampled points; "
                              "is a table in view?")
    # Support is counted on a grid twice as fine as RANSAC's, so a small far can counts. A point
    # stands on a plane when it is off every plane found and above this one by more than
    # min_height plus 3.5 sigma of depth noise at its range (far floor points stray several
    # centimetres off the floor by noise alone), and below max_height.
    grid = g.subsample(pts, config.support_step).reshape(-1, 3)
    grid = grid[np.isfinite(grid).all(axis=1)].astype(float)
    heights = np.stack([p.signed_distance(grid) for p in planes])
    sigma = config.noise_coefficient * np.einsum("ij,ij->i", grid - viewpoint, grid - viewpoint)
    free = (np.abs(heights) > np.maximum(config.plane_distance, 3.5 * sigma)).all(axis=0)
    low = config.min_height + 3.5 * sigma
    candidates = []
    for plane, height in zip(planes, heights):
        support = int(np.count_nonzero(free & (height > low) & (height < config.max_height)))
        candidates.append((plane, support))
    supported = [c for c in candidates if c[1] >= config.min_support]
    best = max(supported, key=lambda c: c[1]) if supported else max(candidates, key=lambda c: c[0].n_points)
    dense = g.subsample(pts, config.refine_step)
    # The band's points are not needed here: no pass over the cloud for them.
    plane, T, _, _ = g.refine_plane(dense, best[0], config.refine_band, viewpoint,
                                    iterations=config.refine_iterations, final_inliers=False)
    return plane, T, candidates


# --- the cans -------------------------------------------------------------------------------------


# The systematic radial deviation (issue 5's criterion, also can_search's): see geometry.shape_error.
shape_error = g.shape_error


def fit_upright_cylinder(points_plane, sensor_plane, config=AutoConfig()):
    """One cluster's upright cylinder, in the plane frame: the issue 5 finder (docs/can_search.md, "The
    table and the clusters").

    points_plane: float (N, 3) cluster points in the plane frame (m, z up from the table);
    sensor_plane: the sensor's position in the plane frame (m), for the noise level.
    Returns (fit, height, shape, n_side, None) when every criterion holds, else
    (fit or None, height, shape or None, n_side, reason): fit a geometry.CylinderFit, height (m),
    shape the shape error (m), n_side the side points fitted, reason the first failed criterion.
    """
    c = config
    pts = np.asarray(points_plane, dtype=float)
    z = pts[:, 2]
    bottom = float(z.min())
    height = float(np.percentile(z, 99))
    if bottom > c.min_height + c.max_base_gap:
        return None, height, None, 0, f"floats {100 * bottom:.1f} cm above the table (not standing on it)"
    if height < c.min_can_height:
        return None, height, None, 0, f"only {100 * height:.1f} cm tall (min {100 * c.min_can_height:.1f} cm)"
    sigma = c.depth_sigma(pts.mean(axis=0), sensor_plane)
    side = pts[(z >= c.fit_bottom + 3 * sigma) & (z <= height - c.top_margin - 3 * sigma)]
    if len(side) < c.min_fit_points:
        return None, height, None, len(side), f"{len(side)} side points (min {c.min_fit_points})"
    r_eps = c.r_eps_at(sigma)
    if len(side) > c.max_fit_points:
        side = side[:: int(np.ceil(len(side) / c.max_fit_points))]
    xy = side[:, :2]
    width = float(np.ptp(xy, axis=0).max())
    if width > 2 * c.max_radius + 2 * r_eps:
        return None, height, None, len(side), (f"{100 * width:.0f} cm wide, wider than a can of radius "
                                               f"{1e3 * c.max_radius:.0f} mm")
    try:
        cx, cy, r0 = g.fit_circle_algebraic(xy)
        if not r0 < 4 * c.max_radius:
            return None, height, None, len(side), f"side is nearly straight (circle radius {100 * r0:.0f} cm)"
        fit = g.fit_cylinder(xy, (cx, cy), r0, r_eps, max_iterations=c.fit_iterations, tol=c.fit_tolerance,
                             min_inliers=c.min_fit_points,
                             max_shift=max(2 * c.max_radius, r0))
    except PerceptionError as e:
        return None, height, None, len(side), f"no circle fits the side ({str(e).split(';')[0]})"
    reason = None
    inlier_fraction = fit.n_inliers / len(side)
    max_rms = max(c.max_rms, c.max_rms_sigmas * sigma)
    shape = shape_error(xy[fit.inliers], fit.cx, fit.cy, fit.radius, c.shape_bins)
    if not c.min_radius <= fit.radius <= c.max_radius:
        reason = (f"radius {1e3 * fit.radius:.1f} mm outside [{1e3 * c.min_radius:.0f}, "
                  f"{1e3 * c.max_radius:.0f}] mm")
    elif inlier_fraction < c.min_inlier_fraction:
        reason = (f"only {100 * inlier_fraction:.0f}% of the side within {1e3 * r_eps:.1f} mm of the circle "
                  f"(min {100 * c.min_inlier_fraction:.0f}%)")
    elif fit.rms_error > max_rms:
        reason = f"rms residual {1e3 * fit.rms_error:.2f} mm > {1e3 * max_rms:.2f} mm"
    elif shape > c.max_shape_error:
        reason = f"shape error {1e3 * shape:.2f} mm > {1e3 * c.max_shape_error:.2f} mm (not round)"
    elif fit.arc_coverage < c.min_arc:
        reason = f"side seen over {fit.arc_coverage:.2f} rad < {c.min_arc:.2f} rad"
    return fit, height, shape, len(side), reason


def _clusters(in_plane, config):
    """Clusters of the points in the band above the table: list of int64 flattened indices."""
    organized = in_plane.ndim == 3
    how = config.clustering if config.clustering != "auto" else ("organized" if organized else "euclidean")
    if how == "organized":
        if not organized:
            raise PerceptionError("organized clustering needs an (H, W, 3) cloud; use clustering='euclidean'")
        return _native.organized_clusters(in_plane, config.cluster_distance, config.min_cluster_points,
                                          z_min=config.min_height, z_max=config.max_height)
    idx = g.points_above_plane(in_plane, config.min_height, config.max_height)
    return _native.euclidean_clusters(in_plane, config.cluster_distance, config.min_cluster_points, indices=idx)


def _grid_indices(flat, grid_shape, full_shape, step):
    """Flattened indices into the searched grid (every step-th pixel) as flattened indices into
    the whole cloud (organized (H, W) or unorganized (N,))."""
    flat = np.asarray(flat, dtype=np.int64)
    if len(full_shape) == 1:
        return flat * (step * step)
    rows, cols = np.divmod(flat, grid_shape[1])
    return rows * step * full_shape[1] + cols * step


def _search_cylinders(pts, T, viewpoint, config):
    """Step 2 and 3 by can_search (cans inside clusters): (cans, rejected, stage timings)."""
    t0 = time.perf_counter()
    step = int(config.cylinders.grid_step)
    grid = g.subsample(pts, step)
    T_plane_from_sensor = transforms.invert(T)
    in_plane = _native.transform_cloud(grid, T_plane_from_sensor)
    viewpoint = g.as_vector3(viewpoint, "viewpoint")
    sensor_plane = transforms.apply(T_plane_from_sensor, viewpoint)
    t1 = time.perf_counter()
    # The grid has 1 / step^2 of the points: so has a cluster.
    grid_config = dataclasses.replace(config, min_cluster_points=max(int(config.min_cluster_points / step ** 2), 3))
    clusters = _clusters(in_plane, grid_config)
    standing_idx = g.points_above_plane(in_plane, config.min_height, config.max_height)
    standing = _native.extract(in_plane, standing_idx)
    t2 = time.perf_counter()
    points = [_native.extract(in_plane, idx).astype(float) for idx in clusters]
    box = g.image_box(grid[..., 2]) if grid.ndim == 3 else None
    edge = None if box is None else standing[g.on_image_edge(standing_idx, grid.shape[1], box)].astype(float)
    ray_angle = g.ray_angle(grid, viewpoint)
    found, rejections = can_search.search(points, standing, T, sensor_plane, config, ray_angle=ray_angle,
                                          image_edge=edge,
                                          beyond_image=None if box is None else _beyond_image(grid, T, box))
    projector = can_search.projector_in_plane(T_plane_from_sensor, config.cylinders)
    found = [(k, _with_hidden_ends(can, in_plane, standing_idx, clusters[k], T_plane_from_sensor, sensor_plane,
                                   projector, config, ray_angle) if can.lying else can) for k, can in found]
    cans = [dataclasses.replace(can, indices=_grid_indices(clusters[k][can.indices], in_plane.shape[:-1],
                                                            pts.shape[:-1], step)) for k, can in found]
    rejected = [RejectedCluster(centroid=transforms.apply(T, rj.centroid), n_points=rj.n_points, reason=rj.reason,
                                radius=rj.radius) for _, rj in rejections]
    cans.sort(key=lambda c: -c.n_fit_points)
    t3 = time.perf_counter()
    return cans, rejected, {"transform": t1 - t0, "clusters": t2 - t1, "fits": t3 - t2}


def _beyond_image(grid, T_sensor_from_plane, box):
    """Which places (float (K, 3), plane frame, m) project beyond the edge of the organized grid's
    image (box: geometry.image_box of it) or onto it: bool (K,). Its pinhole camera is fitted at the
    first call (few searches ask); none fitted, none lies beyond."""
    camera = functools.cache(lambda: g.pinhole(grid))

    def beyond(places):
        if camera() is None:
            return np.zeros(len(places), bool)
        return g.outside_image(transforms.apply(T_sensor_from_plane, places), camera(), box)
    return beyond


def _with_hidden_ends(can, in_plane, standing, cluster, T_plane_from_sensor, sensor_plane, projector, config,
                      ray_angle=0.0):
    """A lying Can with its ends_hidden: which of its ends an object in front hides (lying.hidden_ends),
    among the points standing on the table (standing: flat indices into in_plane, the searched grid in
    the plane frame, m) but its cluster's (cluster: flat indices): an object touching the can's end
    is in its cluster and bounds it there ("lying can touching box"); one standing apart in front of
    the end hides it ("cluttered table" 3531, 3542), or its shadow from the IR projector does (6847;
    projector: its place in the plane frame, None: not known); ray_angle (rad): between neighbouring
    rays of the grid (0: not known). The cluster's points show where the can's side goes on past an end."""
    flat = in_plane.reshape(-1, 3)
    occluders = flat[np.setdiff1d(standing, cluster)].astype(float)
    start = transforms.apply(T_plane_from_sensor, can.base_center)
    u = T_plane_from_sensor[:3, :3] @ can.axis
    r_eps = config.r_eps_at(config.depth_sigma(start + 0.5 * can.height * u, sensor_plane))
    hidden = lying.hidden_ends(start, u, can.height, can.radius, r_eps, sensor_plane, occluders, projector=projector,
                               own=flat[cluster].astype(float), ray_angle=ray_angle)
    return dataclasses.replace(can, ends_hidden=hidden)


def _cut_by_image_edge(cans, xyz, reach, margin=1):
    """The cans (Can, indices: flattened pixels of xyz, float32 (H, W, 3) camera frame, m, or None:
    no image) with what the image's edge or an object in front cuts: an end is cut when some of the
    can's pixels lie within margin px of the edge (geometry.image_box) and its axis, `reach` m beyond
    that end, leaves the image (the can may go on there unseen), or, a lying can's, when its
    ends_hidden says an object in front hides it. end_seen False when it cuts the far end (the top;
    a lying can's other end). A lying can cut at its origin's end only is turned end for end, so
    that its origin is the end seen; cut at both, base_seen False."""
    if not cans:
        return cans
    # The camera is fitted once, and only when a can touches the edge (None: the cloud has no pinhole).
    box, camera, fitted = None if xyz is None else g.image_box(xyz[..., 2]), None, False
    out = []
    for can in cans:
        near = far = False
        # A can the edge cuts shows pixels on it: most cans are nowhere near it.
        if box is not None and g.on_image_edge(can.indices, xyz.shape[1], box, margin).any():
            if not fitted:
                camera, fitted = g.pinhole(xyz), True
            if camera is not None:
                beyond = can.base_center + np.outer([-reach, can.height + reach], can.axis)
                near, far = (bool(v) for v in g.outside_image(beyond, camera, box, margin))
                near = near and can.lying  # an upright can's base is on its support, not beyond it
        if can.lying:
            near, far = near or can.ends_hidden[0], far or can.ends_hidden[1]
            if near and not far:
                turned = g.turned_end_for_end(can.T_sensor_from_can, can.height)
                can = dataclasses.replace(can, T_sensor_from_can=turned, ends_hidden=can.ends_hidden[::-1])
                near, far = False, True
            out.append(dataclasses.replace(can, end_seen=not far, base_seen=not near))
        else:
            out.append(dataclasses.replace(can, end_seen=not far))
    return out


def mark_unseen_ends(cans, xyz, config=AutoConfig()):
    """The cans (indices: flattened pixels of xyz, sensor frame, m) marked where an end may go on
    unseen, as find_cans marks them (_cut_by_image_edge): beyond the image's edge (2 r_eps of config
    beyond the ends, within the searched grid's step of the edge; an unorganized (N, 3) cloud has no
    edge) or, a lying can's, behind an object in front (its ends_hidden, from the search)."""
    return _cut_by_image_edge(cans, xyz if np.ndim(xyz) == 3 else None, 2 * config.r_eps,
                              margin=int(config.cylinders.grid_step))


def find_cans(xyz, viewpoint=(0.0, 0.0, 0.0), config=AutoConfig()):
    """Every can on the support plane of a cloud (upright, stacked or lying), with no selection: an AutoResult.

    xyz: float32 (H, W, 3) organized (fast path) or (N, 3) cloud, sensor frame (m), NaN holes;
    viewpoint: the sensor's position in that frame (m). The steps and the rejection criterion:
    docs/can_search.md. An empty result (no can) is not an error; a cloud without a
    usable plane raises PerceptionError.
    """
    config.validate()
    t0 = time.perf_counter()
    pts = g.as_points_float32(xyz)
    plane, T, candidates = find_support_plane(pts, viewpoint, config)
    t1 = time.perf_counter()
    if config.search == "cylinders":
        cans, rejected, stages = _search_cylinders(pts, T, viewpoint, config)
        cans = mark_unseen_ends(cans, pts, config)
        t4 = time.perf_counter()
        timings = {"table": t1 - t0, **stages, "total": t4 - t0}
        return AutoResult(table=plane, T_sensor_from_plane=T, cans=cans, rejected=rejected,
                          candidate_planes=candidates, timings=timings)
    T_plane_from_sensor = transforms.invert(T)
    in_plane = _native.transform_cloud(pts, T_plane_from_sensor)
    sensor_plane = transforms.apply(T_plane_from_sensor, g.as_vector3(viewpoint, "viewpoint"))
    t2 = time.perf_counter()
    clusters = _clusters(in_plane, config)
    t3 = time.perf_counter()
    cans, rejected = [], []
    for idx in clusters:
        cluster = _native.extract(in_plane, idx).astype(float)
        fit, height, shape, n_side, reason = fit_upright_cylinder(cluster, sensor_plane, config)
        if reason is not None:
            rejected.append(RejectedCluster(centroid=transforms.apply(T, cluster.mean(axis=0)), n_points=len(idx),
                                            reason=reason, radius=None if fit is None else fit.radius))
            continue
        cans.append(Can(T_sensor_from_can=g.can_pose(T, fit.cx, fit.cy), radius=fit.radius, height=height,
                        rms_error=fit.rms_error, arc_coverage=fit.arc_coverage, n_points=len(idx),
                        n_fit_points=fit.n_inliers, center_plane=fit.center, shape_error=shape, indices=idx))
    cans = mark_unseen_ends(sorted(cans, key=lambda c: -c.n_fit_points), pts, config)
    t4 = time.perf_counter()
    timings = {"table": t1 - t0, "transform": t2 - t1, "clusters": t3 - t2, "fits": t4 - t3, "total": t4 - t0}
    return AutoResult(table=plane, T_sensor_from_plane=T, cans=cans, rejected=rejected,
                      candidate_planes=candidates, timings=timings)


# --- command line ---------------------------------------------------------------------------------


def _parser():
    d = AutoConfig()
    p = argparse.ArgumentParser(
        prog="find_cans",
        description="Find every can on the table (upright, on an object on it, or lying) in a PCD scene "
                    "(no selection) and print them as JSON (sensor frame, metres), each with its fit rms, "
                    "visible arc, points, support and whether its base was seen. Exits 0 also when there is none.")
    p.add_argument("scene", metavar="SCENE.pcd", help="an organized (or unorganized) x y z PCD file")
    p.add_argument("--min-radius", type=float, default=d.min_radius, help="m (default %(default)s)")
    p.add_argument("--max-radius", type=float, default=d.max_radius, help="m (default %(default)s)")
    p.add_argument("--max-height", type=float, default=d.max_height,
                   help="objects are looked for up to this height above the table, m (default %(default)s)")
    p.add_argument("--up", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="the up direction in the sensor frame; the table's normal must be within "
                        "--max-tilt of it (default: no prior, the plane with most on it)")
    p.add_argument("--max-tilt", type=float, default=d.max_tilt, help="rad (default %(default)s)")
    p.add_argument("--clustering", choices=("auto", "organized", "euclidean"), default=d.clustering,
                   help="organized grid connected components or PCL's Euclidean clusters (default %(default)s)")
    p.add_argument("--search", choices=SEARCHES, default=d.search,
                   help="cylinders: cans inside clusters, stacked, partly hidden (issue 13); clusters: each "
                        "cluster one upright can (issue 5) (default %(default)s)")
    p.add_argument("--indent", type=int, default=2, help="JSON indent (default %(default)s)")
    return p


def main(argv=None):
    """find_cans SCENE.pcd [options]: prints the result as JSON (in the file's frame, the sensor at
    its VIEWPOINT); returns the exit status (0 also when no can is found, 1 when the file cannot be
    read or holds no table)."""
    args = _parser().parse_args(argv)
    from example_pcl.pcd import read_pcd  # the extension reads PCD; keep --help free of it

    config = AutoConfig(min_radius=args.min_radius, max_radius=args.max_radius, max_height=args.max_height,
                        up=None if args.up is None else tuple(args.up), max_tilt=args.max_tilt,
                        clustering=args.clustering, search=args.search)
    try:
        config.validate()
        cloud = read_pcd(args.scene)
        # PCD's VIEWPOINT records where the sensor was: normals turn toward it and the depth noise
        # grows with the range from it, also for a scene saved in a fixed frame.
        result = find_cans(cloud.xyz, viewpoint=cloud.origin, config=config)
    except (PerceptionError, OSError) as e:
        print(f"find_cans: {args.scene}: {e}", file=sys.stderr)
        return 1
    out = {"scene": args.scene, **result.to_dict()}
    print(json.dumps(out, indent=args.indent or None))
    print(f"find_cans: {result.message}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
