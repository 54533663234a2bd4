"""Lying cans (issue 13): a cylinder on its side, its axis parallel to the table, in what the
upright search (example_pcl.can_search) leaves of a cluster.

Pure NumPy; knows nothing of ROS. Everything is in the *plane frame* (z up from the table, metres).
A lying can's axis is the horizontal line (direction angle theta about z, lateral offset d, height
zc) from which its side points lie at the radius r. :func:`fit_lying_cylinder` scans theta
(a linear circle fit of the points projected onto the plane perpendicular to each direction: the
right direction collapses the side onto one circle, another one spreads it into an ellipse), then
refines (theta, d, zc, r) by Gauss-Newton on the points near the cylinder. :func:`lying_can`
judges the fit like an upright can's side (docs/can_search.md, "Lying cans"). The tracker's
per-frame refit (example_pcl.local_fit) starts the refinement from the previous frame's cylinder
instead (:func:`refine_lying_cylinder`) and judges it the same way (:func:`judge_lying`).
"""
from dataclasses import dataclass

import numpy as np

from example_pcl import geometry as g


@dataclass(frozen=True, eq=False)
class LyingFit:
    """A horizontal cylinder fitted to points (plane frame, m): unit direction (float64 (2,)) of the
    axis seen from above; origin (float64 (2,)): the points' mean (x, y), from which the axial and
    lateral coordinates are measured; offset: the axis' lateral coordinate (along (-uy, ux)); zc:
    its height; radius; rms: RMS radial residual of the inliers; n_inliers (within r_eps)."""

    direction: np.ndarray
    origin: np.ndarray
    offset: float
    zc: float
    radius: float
    rms: float
    n_inliers: int

    def coordinates(self, points):
        """(axial, lateral, z, distance from the axis) of points (float64 (N, 3)): each (N,) (m)."""
        q = points[:, :2] - self.origin
        ux, uy = self.direction
        axial, lateral = q[:, 0] * ux + q[:, 1] * uy, -q[:, 0] * uy + q[:, 1] * ux
        z = points[:, 2]
        return axial, lateral, z, np.hypot(lateral - self.offset, z - self.zc)

    def point_on_axis(self, axial):
        """The axis' point at an axial coordinate (m): float64 (3,), plane frame."""
        ux, uy = self.direction
        xy = self.origin + axial * self.direction + self.offset * np.array([-uy, ux])
        return np.array([xy[0], xy[1], self.zc])


def _kasa(lateral, z):
    """Kasa circles of (lateral[k], z) per row k (lateral float64 (K, N), z (N,)): (c_l, c_z, r) (K,) each."""
    lm = lateral.mean(axis=1, keepdims=True)
    zm = z.mean()
    u, v = lateral - lm, (z - zm)[None, :]
    s = u * u + v * v
    n = lateral.shape[1]
    A = np.empty((len(lateral), 3, 3))
    A[:, 0, 0], A[:, 0, 1], A[:, 0, 2] = (u * u).sum(1), (u * v).sum(1), u.sum(1)
    A[:, 1, 1], A[:, 1, 2], A[:, 2, 2] = (v * v).sum(1), v.sum(1), n
    A[:, 1, 0], A[:, 2, 0], A[:, 2, 1] = A[:, 0, 1], A[:, 0, 2], A[:, 1, 2]
    b = np.stack([(u * s).sum(1), (v * s).sum(1), s.sum(1)], axis=1)
    with np.errstate(all="ignore"):
        try:
            x = np.linalg.solve(A, b[..., None])[..., 0]
        except np.linalg.LinAlgError:
            x = np.full((len(lateral), 3), np.nan)
        cu, cv = x[:, 0] / 2, x[:, 1] / 2
        r = np.sqrt(x[:, 2] + cu * cu + cv * cv)
    return cu + lm[:, 0], cv + zm, r


def fit_lying_cylinder(points, r_eps, min_radius, max_radius, max_gap, directions=36, iterations=15, max_points=300):
    """The horizontal cylinder best explaining points (float64 (N, 3), plane frame, m): a LyingFit,
    or None when no direction gives a circle of about a radius within [min_radius, max_radius] (m)
    whose centre is about one radius (to within a quarter radius and 2 max_gap, m) above the table.

    Scans `directions` axis directions over 180 degrees (Kasa circle of the projected points,
    scored by the points within r_eps of it), then refines the best three by Gauss-Newton on
    (theta, offset, zc, r) over the points within 2 r_eps, and keeps the one with most inliers.
    At most max_points points (evenly subsampled) are used; rms and n_inliers are theirs."""
    points, origin, q = _centred(points, max_points)
    if len(points) < 3:
        return None
    z = points[:, 2]
    theta = np.arange(directions) * np.pi / directions
    lateral = -q[:, 0][None, :] * np.sin(theta)[:, None] + q[:, 1][None, :] * np.cos(theta)[:, None]
    cl, cz, r = _kasa(lateral, z)
    dist = np.abs(np.hypot(lateral - cl[:, None], z[None, :] - cz[:, None]) - r[:, None])
    # Only circles of about a can's radius that about touch the table are refined.
    ok = (np.isfinite(r) & (r >= 0.5 * min_radius) & (r <= 1.5 * max_radius)
          & (np.abs(cz - r) <= 0.25 * r + 2 * max_gap))
    score = np.where(ok, (dist <= r_eps).sum(axis=1), -1)
    best = None
    for k in np.argsort(-score, kind="stable")[:2]:
        if score[k] < 3:
            break
        fit = _refine(q, z, theta[k], cl[k], cz[k], r[k], r_eps, iterations, np.ones(len(z), bool), max_radius,
                      max_gap)
        if fit is not None and (best is None or fit[5] > best[5]):
            best = fit
    if best is None:
        return None
    return _without_ends(q, z, origin, best, r_eps, iterations, max_radius, max_gap)


def refine_lying_cylinder(points, start, direction, radius, r_eps, max_radius, max_gap, iterations=15,
                          max_points=300):
    """A horizontal cylinder refined from a previous one (a LyingFit) or None, as fit_lying_cylinder
    but without its scan: points (float64 (N, 3), plane frame, m); start (3,): a point of the
    previous axis (its z the axis' height), direction (2,) or (3,): the axis seen from above (need not
    be unit), radius (m). The refined direction keeps the previous one's sense."""
    points, origin, q = _centred(points, max_points)
    if len(points) < 4:
        return None
    theta = float(np.arctan2(direction[1], direction[0]))
    rel = np.asarray(start[:2], dtype=float) - origin
    offset = -rel[0] * np.sin(theta) + rel[1] * np.cos(theta)
    best = _refine(q, points[:, 2], theta, offset, float(start[2]), float(radius), r_eps, iterations,
                   np.ones(len(points), bool), max_radius, max_gap)
    if best is None:
        return None
    return _without_ends(q, points[:, 2], origin, best, r_eps, iterations, max_radius, max_gap)


def _centred(points, max_points):
    """(points evenly subsampled to at most max_points, origin: their mean (x, y), q: their (x, y)
    less the origin): the coordinates the fits work in."""
    if len(points) > max_points:
        points = points[:: int(np.ceil(len(points) / max_points))]
    origin = points[:, :2].mean(axis=0) if len(points) else np.zeros(2)
    return points, origin, points[:, :2] - origin


def _without_ends(q, z, origin, best, r_eps, iterations, max_radius, max_gap):
    """The LyingFit of a refined (theta, d, zc, r, rms, n), refined once more without the ends.

    The ends' discs lie inside the circle near its rim and pull it smaller: refit without the
    slabs of r_eps at both ends of the cylinder's axial extent."""
    t = best[0]
    axial = q[:, 0] * np.cos(t) + q[:, 1] * np.sin(t)
    lo, hi = end_positions(axial, np.hypot(-q[:, 0] * np.sin(t) + q[:, 1] * np.cos(t) - best[1], z - best[2]),
                           best[3], r_eps)
    trimmed = (axial > lo + r_eps) & (axial < hi - r_eps)
    best = _refine(q, z, *best[:4], r_eps, iterations, trimmed, max_radius, max_gap) or best
    t, d, zc, rad, rms, n = best
    return LyingFit(direction=np.array([np.cos(t), np.sin(t)]), origin=origin, offset=d, zc=zc, radius=rad,
                    rms=rms, n_inliers=n)


def end_positions(axial, rho, r, r_eps):
    """The axial coordinates (m) of a cylinder's two ends: the 0.5th and 99.5th percentiles of the
    points within r + 2 r_eps of the axis (rho: their distances from it)."""
    near = rho <= r + 2 * r_eps
    if near.sum() < 2:
        return float(axial.min()), float(axial.max())
    lo, hi = np.percentile(axial[near], [0.5, 99.5])
    return float(lo), float(hi)


def _refine(q, z, theta, d, zc, r, r_eps, iterations, use, max_radius, max_gap):
    """Gauss-Newton on (theta, d, zc, r) over the points of `use` (bool) within 2 r_eps of the current
    cylinder: (theta, d, zc, r, rms, n_inliers) or None when fewer than 4 points stay near it, the
    radius grows beyond 2 max_radius (m) or the axis leaves the height fit_lying_cylinder allows."""
    for _ in range(iterations):
        c, s = np.cos(theta), np.sin(theta)
        axial, lat = q[:, 0] * c + q[:, 1] * s, -q[:, 0] * s + q[:, 1] * c
        dl, dz = lat - d, z - zc
        rho = np.hypot(dl, dz)
        near = (np.abs(rho - r) <= 2 * r_eps) & use
        if near.sum() < 4:
            return None
        rho_n = np.maximum(rho[near], 1e-9)
        # d rho / d theta = (dl / rho) d lat / d theta, and d lat / d theta = -axial.
        J = np.column_stack([-dl[near] * axial[near] / rho_n, -dl[near] / rho_n, -dz[near] / rho_n,
                             -np.ones(near.sum())])
        try:
            step = np.linalg.solve(J.T @ J, -(J.T @ (rho[near] - r)))
        except np.linalg.LinAlgError:
            return None
        theta, d, zc, r = theta + step[0], d + step[1], zc + step[2], r + step[3]
        if not 0 < r <= 2 * max_radius or abs(zc - r) > 0.25 * r + 2 * max_gap:
            return None
        if np.abs(step[1:]).max() < 1e-5 and abs(step[0]) < 1e-4:
            break
    c, s = np.cos(theta), np.sin(theta)
    lat = -q[:, 0] * s + q[:, 1] * c
    residual = np.hypot(lat - d, z - zc) - r
    inl = (np.abs(residual) <= r_eps) & use
    n = int(inl.sum())
    if n < 3 or not np.isfinite(r):
        return None
    return float(theta), float(d), float(zc), float(r), float(np.sqrt(np.mean(residual[inl] ** 2))), n


@dataclass(frozen=True, eq=False)
class LyingCan:
    """A lying can found (plane frame, m): fit (LyingFit), start (float64 (3,): centre of one end),
    direction (float64 (3,): unit axis, horizontal, from that end), length, inliers (bool (N,) over
    the points: its side within r_eps), mine (bool (N,): its side and ends), rms (of the inliers'
    radial residuals), shape_error, arc (rad: the side's span around the axis)."""

    fit: LyingFit
    rms: float
    start: np.ndarray
    direction: np.ndarray
    length: float
    inliers: np.ndarray
    mine: np.ndarray
    shape_error: float
    arc: float


def lying_can(points, r_eps, sigma, config, search):
    """A lying can among points (float64 (N, 3), plane frame, m): (LyingCan, "") or (None, why not).

    r_eps: inlier distance (m); sigma: depth noise there (m); config: auto_finder.AutoConfig (radius
    range, inlier fraction, rms, shape error, arc, min_can_height as the least length); search:
    can_search.CylinderSearchConfig (lying_gap, lying_directions, max_taper, taper_sigmas)."""
    c, s = config, search
    # A can on its side is at most one diameter high.
    top = float(np.percentile(points[:, 2], 99))
    if top > 2 * c.max_radius + s.lying_gap + 3 * sigma:
        return None, f"lying: {100 * top:.1f} cm high, more than a lying can's {200 * c.max_radius:.0f} cm"
    fit = fit_lying_cylinder(points, r_eps, c.min_radius, c.max_radius, s.lying_gap + 3 * sigma, s.lying_directions,
                             c.fit_iterations, s.fit_points)
    return judge_lying(points, fit, r_eps, sigma, config, search)


def judge_lying(points, fit, r_eps, sigma, config, search):
    """A horizontal cylinder fitted to points (a LyingFit, or None: none fitted) judged as a lying
    can, as lying_can judges its own fit: (LyingCan, "") or (None, why not). Arguments as lying_can's."""
    c, s = config, search
    if fit is None:
        return None, "lying: no horizontal cylinder fits its points"
    r = fit.radius
    if not c.min_radius <= r <= c.max_radius:
        return None, (f"lying: radius {1e3 * r:.1f} mm outside [{1e3 * c.min_radius:.0f}, {1e3 * c.max_radius:.0f}] mm "
                      "(a lying tin or pot, not a can)")
    # On its side on the table, a can's axis is one radius above it.
    gap = fit.zc - r
    if abs(gap) > s.lying_gap + 3 * sigma:
        return None, (f"lying: its axis is {1e3 * fit.zc:.0f} mm above the table, {1e3 * gap:+.0f} mm off its radius "
                      f"(max {1e3 * (s.lying_gap + 3 * sigma):.0f}; not a cylinder lying on the table)")
    axial, lateral, z, rho = fit.coordinates(points)
    a_lo, a_hi = end_positions(axial, rho, r, r_eps)
    # The side without the slabs of r_eps at the ends, where the ends' discs meet it.
    inner = (axial > a_lo + r_eps) & (axial < a_hi - r_eps)
    side = (np.abs(rho - r) <= r_eps) & inner
    body = (axial >= a_lo - r_eps) & (axial <= a_hi + r_eps) & (rho <= r + r_eps)
    n_side = int(side.sum())
    if n_side < c.min_fit_points:
        return None, f"lying: {n_side} points on a horizontal cylinder (min {c.min_fit_points})"
    fraction = n_side / max(int((body & inner).sum()), 1)
    if fraction < c.min_inlier_fraction:
        return None, (f"lying: only {100 * fraction:.0f}% of its points within {1e3 * r_eps:.1f} mm of a horizontal "
                      f"cylinder (min {100 * c.min_inlier_fraction:.0f}%)")
    max_rms = max(c.max_rms, c.max_rms_sigmas * sigma)
    rms = float(np.sqrt(np.mean((rho[side] - r) ** 2)))
    if rms > max_rms:
        return None, f"lying: rms residual {1e3 * rms:.2f} mm > {1e3 * max_rms:.2f} mm"
    section = np.column_stack([lateral[side], z[side]])
    shape = g.shape_error(section, fit.offset, fit.zc, r, c.shape_bins)
    if shape > c.max_shape_error:
        return None, f"lying: shape error {1e3 * shape:.2f} mm > {1e3 * c.max_shape_error:.2f} mm (not round)"
    arc = g.arc_coverage(section, fit.offset, fit.zc)
    if arc < c.min_arc:
        return None, f"lying: side seen over {arc:.2f} rad < {c.min_arc:.2f} rad"
    length = float(a_hi - a_lo)
    if length < c.min_can_height:
        return None, f"lying: {100 * length:.1f} cm long (min {100 * c.min_can_height:.1f} cm)"
    why = _bulging(axial[side], rho[side], a_lo, length, sigma, s)
    if why:
        return None, why
    ux, uy = fit.direction
    return LyingCan(fit=fit, rms=rms, start=fit.point_on_axis(a_lo), direction=np.array([ux, uy, 0.0]), length=length,
                    inliers=side, mine=body, shape_error=shape, arc=arc), ""


def plane_from_can(start, direction):
    """T_plane_from_can (4x4 float64) of a lying can: origin `start` (m, plane frame: the centre of
    one end), z along `direction` (unit, horizontal), x up from the table, y = z x x."""
    ux, uy = direction[0], direction[1]
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, uy, ux], [0.0, -ux, uy], [1.0, 0.0, 0.0]])
    T[:3, 3] = start
    return T


def _bulging(axial, rho, a_lo, length, sigma, s):
    """Why the radius is not the same along the axis (a bowl or a pot on its side, a sphere), or "":
    the side's median distance from the axis in its first, middle and last third differ by more than
    max_taper x the distance between the thirds' middles and taper_sigmas standard errors."""
    third = np.minimum(((axial - a_lo) / max(length, 1e-9) * 3).astype(int), 2)
    counts = np.bincount(np.clip(third, 0, 2), minlength=3)
    if (counts < 3).any():
        return ""
    med = np.array([np.median(rho[third == k]) for k in range(3)])
    change = float(med.max() - med.min())
    noise = s.taper_sigmas * 1.25 * sigma * np.sqrt(2.0 / counts.min())
    if change <= max(s.max_taper * 2 * length / 3, noise):
        return ""
    return (f"lying: the radius changes by {1e3 * change:.1f} mm along its {100 * length:.0f} cm (a bowl or pot, "
            "not a can)")
