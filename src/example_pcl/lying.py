"""Lying cans (issue 13): cylinders on their side, their axis parallel to the table, in a cluster
of points that may hold other objects touching them (a box, an upright can, another lying can).

Pure NumPy; knows nothing of ROS. Everything is in the *plane frame* (z up from the table, metres).
A lying can's axis is the horizontal line (direction angle theta about z, lateral offset d, height
zc) from which its side points lie at the radius r. :func:`fit_lying_cylinders` scans theta (a
linear circle fit of the points projected onto the plane perpendicular to each direction: the
right direction collapses the side onto one circle, another one spreads it into an ellipse), for
all the points and for pieces of them around seeds (a can's own points), refines the distinct
best by a robust Gauss-Newton on the half facing the sensor, and keeps the run along the axis that
the circle explains. :func:`lying_can` judges them like an upright can's side, :func:`lying_cans`
takes the cans found out one after another (docs/can_search.md, "Lying cans"). The tracker's
per-frame refit (example_pcl.local_fit) starts the refinement from the previous frame's cylinder
instead (:func:`refine_lying_cylinder`) and judges it the same way (:func:`judge_lying`).
"""
import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from example_pcl import geometry as g


@dataclass(frozen=True, eq=False)
class LyingFit:
    """A horizontal cylinder fitted to points (plane frame, m): unit direction (float64 (2,)) of the
    axis seen from above; origin (float64 (2,)): the points' mean (x, y), from which the axial and
    lateral coordinates are measured; offset: the axis' lateral coordinate (along (-uy, ux)); zc:
    its height; radius; rms: RMS radial residual of the inliers; n_inliers (within r_eps); extent: the
    axial coordinates (m) of the part of the axis its circle explains."""

    direction: np.ndarray
    origin: np.ndarray
    offset: float
    zc: float
    radius: float
    rms: float
    n_inliers: int
    extent: tuple = (-np.inf, np.inf)

    @property
    def theta(self):
        """The axis' direction seen from above (rad, from the plane frame's x)."""
        return float(np.arctan2(self.direction[1], self.direction[0]))

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


def _kasa(q, z, theta, weights):
    """Kasa circles of the points (lateral, z) per direction theta[d] (rad; lateral: q's coordinate
    across it, q float64 (N, 2), m) and subset k (weights (K, N) 0/1 masks, z (N,), m). Returns (c_l,
    c_z, r), each (K, D); NaN for a subset of fewer than 3 points or (nearly) collinear ones.

    A direction's sums (of u, u^2, uv, u s, v s; u = lateral, v = z, centred; s = u^2 + v^2) are
    polynomials in its sine and cosine whose coefficients are the subset's moments of x, y and v up
    to the third order: one product over the points for all directions, not one per direction."""
    xm, ym, zm = q[:, 0].mean(), q[:, 1].mean(), z.mean()
    x, y = q[:, 0] - xm, q[:, 1] - ym  # centred, for precision
    v = z - zm
    xx, xy, yy, vv = x * x, x * y, y * y, v * v
    moments = np.einsum("kn,fn->fk", np.asarray(weights, dtype=float),
                        np.stack([np.ones(len(x)), x, y, v, xx, xy, yy, x * v, y * v, vv, xx * x, xx * y, xy * y,
                                  yy * y, x * vv, y * vv, xx * v, xy * v, yy * v, vv * v]))[:, :, None]  # (20, K, 1)
    count, mx, my, mv, mxx, mxy, myy, mxv, myv, mvv, mxxx, mxxy, mxyy, myyy, mxvv, myvv, mxxv, mxyv, myyv, mvvv = moments
    a, b = -np.sin(theta), np.cos(theta)  # lateral = a x + b y
    aa, ab, bb = a * a, a * b, b * b
    su, suu, suv = a * mx + b * my, aa * mxx + 2 * ab * mxy + bb * myy, a * mxv + b * myv
    sus = aa * a * mxxx + 3 * aa * b * mxxy + 3 * a * bb * mxyy + bb * b * myyy + a * mxvv + b * myvv
    svs = aa * mxxv + 2 * ab * mxyv + bb * myyv + mvvv
    cu, cv, r = g.kasa_from_sums(count, su, mv, suu, suv, mvv, sus, svs, suu + mvv)
    return cu + a * xm + b * ym, cv + zm, r


def _subsets(xy, radius, seeds):
    """0/1 masks (K, N) of subsets of the points xy (float64 (N, 2), m): all of them, then those
    within `radius` of each of up to `seeds` seeds spread over them (farthest-point sampling, from
    the point farthest from their mean, until every point is within radius / 2 of a seed)."""
    masks = [np.ones(len(xy), bool)]
    far = np.hypot(*(xy - xy.mean(axis=0)).T)
    nearest = np.full(len(xy), np.inf)
    for _ in range(seeds):
        seed = int(np.argmax(far))
        to_seed = np.hypot(xy[:, 0] - xy[seed, 0], xy[:, 1] - xy[seed, 1])
        masks.append(to_seed <= radius)
        nearest = np.minimum(nearest, to_seed)
        far = nearest
        if far.max() <= radius / 2:
            break
    return np.array(masks)


def _distinct(members, score, count, attempt=None, max_attempts=None, max_overlap=0.5, scan=64):
    """Up to `count` of the best-scoring hypotheses (members: bool (H, N), each one's points within
    r_eps; score (H,): 0 never, nor one of fewer than 3 members), each sharing at most max_overlap of
    the smaller one's points with one taken before: the same can seen from several subsets counts
    once. attempt(h): what hypothesis h gives, or None when it fails (then it hides none of its
    duplicates); tried at most max_attempts times (None: no limit). Returns what the ones taken gave
    (without attempt: their positions)."""
    order = [int(h) for h in np.argsort(-score, kind="stable")[:scan] if score[h] > 0]
    if not order:
        return []
    chosen = members[order]
    size = np.count_nonzero(chosen, axis=1)
    # Each hypothesis taken shares points with every other one: counted once it is taken (at most
    # `count` times), not for every pair (a matrix product, slow on the reference BLAS).
    taken, shared, gave = [], [], []
    attempts = 0
    for i in range(len(order)):
        if len(taken) == count or attempts == max_attempts:
            break
        if size[i] < 3 or any(with_j[i] > max_overlap * min(size[j], size[i]) for j, with_j in zip(taken, shared)):
            continue
        attempts += 1
        out = order[i] if attempt is None else attempt(order[i])
        if out is None:
            continue
        taken.append(i)
        shared.append(np.count_nonzero(chosen & chosen[i], axis=1))
        gave.append(out)
    return gave


def _taller_box(q, z, eps, at=None, min_width=0.03, reach=0.005, min_beside=15, taller=0.004,
                min_rectangularity=0.9, max_bend=3.0):
    """Which of a cluster's points (q: (x, y) float (N, 2), z (N,), plane frame, m) belong to a box
    standing taller than what touches it, or None: the points under its top, within `reach` (m) of
    the top's smallest enclosing rectangle seen from above; which of the points `at` ((x, y) float
    (M, 2), m) when given (a subsample of them). Its top: the fullest level face wider than
    min_width (m) every way (_level_face, eps), the cluster's highest, filling at least
    min_rectangularity of that rectangle (a can's lid fills pi / 4) and flat across it (its heights'
    parabola across bending down by less than max_bend, 1/m: a lying can's top strip, within eps of
    level, bends 1 / (2 r)); at least min_beside points lie outside it, below the top, and the box
    rises at least `taller` (m) above all of them."""
    top = _level_face(q, z, eps, min_width)
    if not top.any():
        return None
    z_top = z[top].mean()
    # Its top is the cluster's: nothing stands higher (whose side, at the top's height, would join it).
    if z.max() > z_top + 2 * eps:
        return None
    rectangle = g.enclosing_rectangle(q[top])
    if rectangle is None or rectangle.fill < min_rectangularity:
        return None
    # A lying can's top within eps of level is a strip 2 sqrt(2 r eps) wide (3 cm and more), as
    # rectangular as a narrow box's top (fresh 8845 of "lying can touching box": 4.4 cm deep).
    across = (q[top] - rectangle.centre) @ rectangle.axes[int(np.argmin(rectangle.half))]
    if np.polyfit(across, z[top], 2)[0] < -max_bend:
        return None
    box = rectangle.contains(q, reach)
    beside = ~box & (z < z_top - eps)
    if np.count_nonzero(beside) < min_beside or z.max() - z[~box].max() < taller:
        return None
    return box if at is None else rectangle.contains(at, reach)


def _level_face(xy, z, eps, min_width, bin_width=0.002, min_points=10):
    """Which of the points (xy float (N, 2), z (N,), m) lie within eps (m) of the height most of them
    share (in bin_width bins), when they are at least min_points and span at least min_width (m) every
    way seen from above (a box's top; the minor axis of their spread): bool (N,)."""
    face = np.zeros(len(z), bool)
    if len(z) < min_points:
        return face
    bins = ((z - z.min()) / bin_width).astype(np.int64)
    level = z[bins == np.argmax(np.bincount(bins))].mean()
    on = np.flatnonzero(np.abs(z - level) <= eps)
    if len(on) < min_points:
        return face
    spread = xy[on] - xy[on].mean(axis=0)
    minor = np.linalg.eigvalsh(spread.T @ spread / len(on))[0]
    # A uniform strip of width w has variance w^2 / 12 across it.
    if np.sqrt(12 * max(minor, 0.0)) >= min_width:
        face[on] = True
    return face


def fit_lying_cylinders(points, r_eps, min_radius, max_radius, max_gap, directions=36, iterations=15,
                        max_points=300, count=3, subset_radius=0.05, band=0.01, band_fraction=0.2, min_band_points=3,
                        max_band_gap=1, sensor=None, min_own=0.6, occluders=None, projector=None,
                        without_taller_box=False, max_turns=3, ray_angle=0.0):
    """Up to `count` distinct horizontal cylinders explaining points (float64 (N, 3), plane frame, m)
    of a lying can and maybe other objects touching it: LyingFits, most inliers first.

    Circles of about a radius within [min_radius, max_radius] (m) whose centre is about one radius
    above the table (to within a quarter radius and 2 max_gap above, max_gap below, m): a Kasa
    circle of the points projected along each of `directions` axis directions over 180 degrees, for
    all the points and for the points within subset_radius (m, seen from above) of seeds spread over
    them (a can's own points, with little of a neighbour's). Of those that hold at least min_own of
    their subset within r_eps, the distinct ones whose points within r_eps lie closest to the circle
    are refined by Gauss-Newton on (theta, offset, zc, r) over the points within 2 r_eps; then only
    the run of `band`-long bands along the axis that the circle explains (geometry.band_run: each
    with at least band_fraction of the fullest band's points on it and no more inside: not a
    neighbour's top) is kept (the fit's extent), refitted on it without the slabs of r_eps at its
    ends, and, while that turns the axis by more than a degree or moves the radius by more than r_eps /
    2 (and leaves a can's radius on the table; at most max_turns times), the run is found again along
    it and refitted. With the sensor
    ((x, y, z), plane frame, m) given, only the points on a cylinder's half facing it count
    (_facing), and with occluders (float (M, 3), plane frame, m) the run goes on over bands where the
    rest of that half is hidden behind them, or unlit by the IR projector (`projector`, (3,), plane
    frame, m; None: not known; _through_hidden; ray_angle, rad: between neighbouring rays of the grid
    searched, 0: not known). At most max_points points (evenly subsampled) are
    fitted; rms and n_inliers are theirs. The run along the axis is counted on all the points.
    without_taller_box: the circles are drawn from the subsets, and refined along their run, without
    the points of a box standing taller than what touches it (_taller_box; none: no fits)."""
    every = points
    points, origin, q, z, sq = _centred(points, max_points, sensor)
    if len(points) < 3:
        return []
    # The run along the axis is counted on every point: a stride through the raster leaves some bands
    # nearly empty.
    q_every, z_every = every[:, :2] - origin, every[:, 2]
    box = None
    if without_taller_box:
        # A box taller than a lying can touching its side has points in every subset of the can's,
        # which pull its circles off (fresh 7144 of "lying can touching box") or wide around both (7710).
        # Told on every point: a subsample's sparse top fills less of its rectangle (fresh 7830 of
        # "lying can touching box": 0.89 on the 59 of 249 points, 0.98 on all 659).
        box = _taller_box(q_every, z_every, 0.5 * r_eps, at=q)
        if box is None:
            return []
    # The fits' refinements along the run: without the box's points too (its face along the can's side,
    # within 2 r_eps of its circle on the half facing the sensor, pulled it 3 mm wide and low: fresh 8400
    # of "lying can touching box").
    q_fit, z_fit = (q, z) if box is None else (q[~box], z[~box])
    theta = np.arange(directions) * np.pi / directions
    lateral = -q[:, 0][None, :] * np.sin(theta)[:, None] + q[:, 1][None, :] * np.cos(theta)[:, None]

    def can_sized(fit):  # (theta, offset, zc, r, ...): a can's radius, its axis one radius above the table
        return min_radius <= fit[3] <= max_radius and abs(fit[2] - fit[3]) <= max_gap

    def explained(fit):
        return _explained(q_every, z_every, fit, r_eps, sq, band, band_fraction, min_band_points, max_band_gap,
                          occluders, origin, projector, ray_angle)

    def without_ends(fit, run):
        return _without_ends(q_fit, z_fit, origin, fit, r_eps, iterations, max_radius, max_gap, sq, run, band)

    def scan(subsets):  # the distinct fits of the circles drawn from these subsets
        cl, cz, r = _kasa(q, z, theta, subsets)  # (K, D) each
        # Only circles of about a can's radius that about touch the table are scored and refined. Kasa
        # fits a partial arc too small, floating above the table; one reaching under it is no can's (and
        # a failed hypothesis still hides its duplicates).
        with np.errstate(invalid="ignore"):
            ok = np.flatnonzero((np.isfinite(r) & (r >= 0.5 * min_radius) & (r <= 1.5 * max_radius)
                                 & (cz - r <= 0.25 * r + 2 * max_gap) & (r - cz <= max_gap)).ravel())
        k_ok, d_ok = np.divmod(ok, directions)
        r_ok = r[k_ok, d_ok, None]
        rho2 = (lateral[d_ok] - cl[k_ok, d_ok, None]) ** 2 + (z - cz[k_ok, d_ok, None]) ** 2
        members = (rho2 <= (r_ok + r_eps) ** 2) & (rho2 >= np.maximum(r_ok - r_eps, 0.0) ** 2)
        # A piece of a can lies on its circle: a circle that leaves most of its subset off is none.
        own = (members & subsets[k_ok]).sum(axis=1) / np.maximum(subsets[k_ok].sum(axis=1), 1)
        # Ranked by how close to its circle its members lie (each weighs (1 - (residual / r_eps)^2)^2),
        # not how many: over neighbouring directions a subset's circles hold about as many points, and
        # the one nearest the axis lets the refinement reach the can.
        score = np.zeros(len(own))
        held = np.flatnonzero(own >= min_own)
        weight = (1 - (np.sqrt(rho2[held]) - r_ok[held]) ** 2 / r_eps ** 2) ** 2
        score[held] = np.where(members[held], weight, 0.0).sum(axis=1)

        def attempt(h):  # the refined fit of hypothesis h, or None
            k, d = k_ok[h], d_ok[h]
            # First on its subset (a piece of one can), then on the run of bands along the axis it explains.
            fit = _refine(q, z, theta[d], cl[k, d], cz[k, d], r[k, d], r_eps, iterations, subsets[k], max_radius,
                          max_gap, sq)
            # No can's radius, or not on the table: the refits below would not make it one.
            if fit is None or not can_sized(fit):
                return None
            # Only the part of the axis the circle explains: not a neighbour's face beyond its end.
            run = explained(fit)
            if run is None:
                return None
            refit = without_ends(fit, run)
            # A fit on a piece of the can may point a few degrees off its axis, and its circle explains a
            # shorter run along it: again along the refitted axis (if it can be a can's) until it turns no
            # more. Once was not enough: fresh 8801 of "lying cans touching" turned 8 then 4 degrees, and
            # the run of the second axis, cut short 4 cm from the end, stood. So too when the radius
            # grows: a circle drawn over a can and a lower box's top at its end met the top along its
            # flanks, and the run went on over it; the refit's holds it inside (fresh 10917 of "lying
            # can touching box", r 28 -> 32 mm on one axis, 44 mm too long).
            for _ in range(max_turns):
                turned = (refit.theta, refit.offset, refit.zc, refit.radius, refit.rms, refit.n_inliers)
                same_axis = abs(np.sin(refit.theta - fit[0])) <= np.sin(np.radians(1))
                if (same_axis and abs(refit.radius - fit[3]) <= 0.5 * r_eps) or not can_sized(turned):
                    break
                again = explained(turned)
                if again is None or again == run:
                    break
                fit, run, refit = turned, again, without_ends(turned, again)
            return refit

        # A hypothesis that fails hides none of its duplicates: another subset's circle on the same
        # points may reach the can (fresh 8312 of "lying can touching box": a circle drawn over a can's
        # top and a box's top beside it failed, and hid those of the can's own end).
        return _distinct(members, score, count, attempt, max_attempts=count)

    subsets = _subsets(q, subset_radius, seeds=8)
    if box is not None:
        subsets = subsets & ~box
        subsets = subsets[np.count_nonzero(subsets, axis=1) >= 3]
    return sorted(scan(subsets), key=lambda f: -f.n_inliers)


def fit_lying_cylinder(points, r_eps, min_radius, max_radius, max_gap, directions=36, iterations=15, max_points=300):
    """The horizontal cylinder best explaining points (fit_lying_cylinders' first), or None."""
    fits = fit_lying_cylinders(points, r_eps, min_radius, max_radius, max_gap, directions, iterations, max_points)
    return fits[0] if fits else None


def refine_lying_cylinder(points, start, direction, radius, r_eps, max_radius, max_gap, iterations=15,
                          max_points=300, sensor=None):
    """A horizontal cylinder refined from a previous one (a LyingFit) or None, as fit_lying_cylinders
    but without its scan: points (float64 (N, 3), plane frame, m); start (3,): a point of the
    previous axis (its z the axis' height), direction (2,) or (3,): the axis seen from above (need not
    be unit), radius (m); sensor as fit_lying_cylinders'. The refined direction keeps the previous
    one's sense. Refitted once more without the slabs of r_eps at the ends (their discs pull it small)."""
    points, origin, q, z, sq = _centred(points, max_points, sensor)
    if len(points) < 4:
        return None
    theta = float(np.arctan2(direction[1], direction[0]))
    rel = np.asarray(start[:2], dtype=float) - origin
    offset = -rel[0] * np.sin(theta) + rel[1] * np.cos(theta)
    fit = _refine(q, z, theta, offset, float(start[2]), float(radius), r_eps, iterations, np.ones(len(points), bool),
                  max_radius, max_gap, sq)
    if fit is None:
        return None
    return _without_ends(q, z, origin, fit, r_eps, iterations, max_radius, max_gap, sq)


def _centred(points, max_points, sensor):
    """(points evenly subsampled to at most max_points, origin: their mean (x, y), q: their (x, y) less
    the origin, z, the sensor less the origin or None): the coordinates the fits work in."""
    if len(points) > max_points:
        points = points[:: int(np.ceil(len(points) / max_points))]
    origin = points[:, :2].mean(axis=0) if len(points) else np.zeros(2)
    sq = _from_origin(sensor, origin)
    return points, origin, points[:, :2] - origin, points[:, 2], sq


def _without_ends(q, z, origin, fit, r_eps, iterations, max_radius, max_gap, sensor, extent=(-np.inf, np.inf),
                  band=0.0):
    """The LyingFit of a refined (theta, d, zc, r, rms, n), refitted without the slabs of r_eps at both
    ends of its axial extent (end_positions within `extent`): the ends' discs lie inside the circle
    near its rim and pull it smaller."""
    axial, lateral = _on_axis(q, fit[0])
    lo, hi = end_positions(axial, np.hypot(lateral - fit[1], z - fit[2]), fit[3], r_eps, extent, band, z)
    trimmed = (axial > lo + r_eps) & (axial < hi - r_eps)
    t, off, zc, rad, rms, n = _refine(q, z, *fit[:4], r_eps, iterations, trimmed, max_radius, max_gap, sensor) or fit
    return LyingFit(direction=np.array([np.cos(t), np.sin(t)]), origin=origin, offset=off, zc=zc, radius=rad,
                    rms=rms, n_inliers=n, extent=extent)


def _from_origin(points, origin):
    """Points (the sensor (3,) or occluders (N, 3), plane frame, m; or None) in the fits' coordinates:
    x and y less the origin ((2,), m). float64, or None."""
    return None if points is None else np.asarray(points, dtype=float) - (origin[0], origin[1], 0.0)


def _on_axis(q, theta):
    """(axial, lateral) coordinates (m, each (N,)) of points q (float64 (N, 2), m) along and across the
    direction theta (rad)."""
    c, s = math.cos(theta), math.sin(theta)  # a scalar: math's, without NumPy's per-call cost
    return q[:, 0] * c + q[:, 1] * s, q[:, 1] * c - q[:, 0] * s


def _explained(q, z, fit, r_eps, sensor, band, fraction, min_points, max_gap, occluders=None, origin=(0.0, 0.0),
               projector=None, ray_angle=0.0):
    """The axial extent (lo, hi) (m) of the run of `band`-long bands along the axis of the cylinder fit
    ((theta, offset, zc, r, ...)) that its circle explains (geometry.band_run), or None.

    A band where at least as many points (and min_points) lie inside the cylinder or just outside it
    (within 3 r_eps, on its half facing the sensor) as on it ends the run: another object's surface
    is seen there (a box at its end, wider or lower than it, or as wide, its face then meeting the
    circle along one stripe and going on beyond it); so does one where as many lie inside as on it in
    its crown (the upper side within half a radius of the axis, seen from above: a lower box's top at
    its end, as wide as the can, meets its circle on both flanks); a gap whose edge shows an end's disc
    parts it (_apart_at_seen_end). With occluders ((M, 3), m, plane frame; q is measured from
    `origin`, (x, y)), the run goes on over the bands beyond it whose facing half is seen where it is
    not hidden behind them or unlit by the projector ((3,), plane frame, m; None: not known;
    _through_hidden, ray_angle as there), and loses the bands at its ends that show only a stripe of
    that half where the rest would be in view (_without_bare_ends: a lower box's edge). The run then
    loses the bands at one end where no can's side is seen (_without_flat_end: a box's top as high as
    the can) or whose crown is level (_without_level_crown: a lower box's top, narrower than the can)."""
    t, d, zc, r = fit[:4]
    axial, lateral = _on_axis(q, t)
    dl, dz = lateral - d, z - zc
    rho = np.hypot(dl, dz)
    a0 = float(axial.min())
    bands = ((axial - a0) / band).astype(np.int64)
    nb = int(bands.max()) + 1
    facing = _facing(dl, dz, t, d, zc, sensor)
    on = (np.abs(rho - r) <= r_eps) & facing
    band_on = np.bincount(bands[on], minlength=nb)
    band_inside = np.bincount(bands[rho < r - r_eps], minlength=nb)
    band_out = np.bincount(bands[facing & (rho > r + r_eps) & (rho <= r + 3 * r_eps)], minlength=nb)
    other = band_inside + band_out
    # The crown (the upper side within half a radius of the axis, seen from above): a lower object's
    # top beyond the can's end lies inside the circle there, a can's side on it.
    crown = (np.abs(dl) <= 0.5 * r) & (dz > 0)
    crown_on = np.bincount(bands[on & crown], minlength=nb)
    crown_inside = np.bincount(bands[crown & (rho < r - r_eps)], minlength=nb)
    run = g.band_run(band_on, band_inside, fraction, min_points, max_gap,
                     blocked=(other >= np.maximum(min_points, band_on))
                     | (crown_inside >= np.maximum(min_points, crown_on)))
    if run is None:
        return None
    run = _apart_at_seen_end(run, band_on, band_inside, bands, axial, dl, dz, rho < r - r_eps, a0, band, fraction,
                             min_points)
    if occluders is not None and sensor is not None:
        may_join = (band_on >= min_points) & (band_inside <= band_on) & (other < min_points)
        run = _through_hidden(run, may_join, bands, on, dl, dz, fit, a0, band, r_eps, sensor, occluders, origin,
                              projector, ray_angle)
        run = _without_bare_ends(run, bands, on, dl, dz, fit, a0, band, r_eps, sensor, occluders, origin, projector,
                                 ray_angle, min_points=min_points)
        if run is None:
            return None
    near = facing & (np.abs(rho - r) <= 3 * r_eps)
    # Up the flank toward the sensor, 30-65 degrees from the top: a box's corner there lies off
    # the circle (a square's around it), a can's side on it.
    fl = _toward_sensor(t, d, zc, sensor)[0]
    toward = dl * fl > 0 if abs(fl) > 1e-6 else np.ones(len(dl), bool)
    angle = np.arctan2(np.abs(dl), dz)
    diagonal = toward & (angle >= np.radians(30)) & (angle <= np.radians(65))
    near_bands, near_residual = bands[near], (rho - r)[near]
    run = _without_flat_end(near_bands, near_residual, diagonal[near], run, r_eps)
    run = _without_level_crown(run, near_bands, dl[near], dz[near], near_residual, r)
    return a0 + run[0] * band, a0 + (run[1] + 1) * band


def _apart_at_seen_end(run, band_on, band_inside, bands, axial, dl, dz, inside, a0, band, fraction, min_points):
    """The run (first, last band) cut at a gap within it (bands with fewer points on the circle than
    band_run grows over) where an end's disc is seen at the gap's edge: min_points or more points
    inside the circle (`inside`, bool) in the half of the band next to it, spread across the axis
    more than along it. One object ends there and another lies beyond (fresh 9503 of "cluttered
    table": a lying can's near end 2 cm from a bowl's far wall, which crosses its circle and made it
    33 mm too long); the run keeps the side with more points on the circle. bands, axial (m), dl, dz
    (m, lateral and vertical offsets from the axis): per point; a0, band (m): the bands' origin and
    length."""
    first, last = run
    side_like = band_inside[first:last + 1] <= band_on[first:last + 1]
    need = max(min_points, fraction * band_on[first:last + 1][side_like].max())
    good = (band_on >= need) & (band_inside <= band_on)
    gaps = [b for b in range(first + 1, last) if not good[b]]
    if not gaps:
        return run

    def disc_toward(b, low_half):  # whether band b shows a disc in its half on the gap's side
        start = a0 + b * band
        mine = inside & (bands == b)
        mine &= (axial < start + 0.5 * band) if low_half else (axial >= start + 0.5 * band)
        return (np.count_nonzero(mine) >= min_points
                and np.std(axial[mine]) < max(np.std(dl[mine]), np.std(dz[mine])))

    pieces, lo = [], first
    for b in gaps:
        if (good[b - 1] and disc_toward(b - 1, False)) or (good[b + 1] and disc_toward(b + 1, True)):
            pieces.append((lo, b - 1))
            lo = b + 1
    if not pieces:
        return run
    pieces.append((lo, last))
    pieces = [(p, q) for p, q in pieces if q >= p]
    return max(pieces, key=lambda piece: band_on[piece[0]:piece[1] + 1][good[piece[0]:piece[1] + 1]].sum())


def _not_its_own(occluders, origin, fit, r_eps):
    """The occluders ((M, 3), m, plane frame) farther than r + r_eps from the axis of the cylinder fit
    ((theta, offset, zc, r, ...), measured from `origin`, (x, y)), in its coordinates: not the can
    itself (its own near side would hide its far parts)."""
    t, d, zc, r = fit[:4]
    occ = _from_origin(occluders, origin)
    return occ[np.hypot(_on_axis(occ[:, :2], t)[1] - d, occ[:, 2] - zc) > r + r_eps]


def _through_hidden(run, may_join, bands, on, dl, dz, fit, a0, band, r_eps, sensor, occluders, origin, projector=None,
                    ray_angle=0.0):
    """The run (first, last band) grown over the bands beyond its ends that may join it (may_join, per
    band: enough points on the circle, no more inside, nothing else just outside) and whose facing half
    lies, where its points on the circle (`on`, bool, with bands, dl and dz: each point's band and
    lateral and vertical offsets from the axis, m) show none, behind the occluders ((M, 3), m, plane
    frame, but the can's own: _not_its_own; the fit's coordinates are measured from `origin`, (x, y))
    seen from the sensor: a can lying behind a lower object shows only its top there, fewer points
    than band_run asks ("cluttered table" 1602, a cup in front of one end). ray_angle: as
    _hidden_where_unseen's."""
    first, last = run
    if not (first > 0 and may_join[first - 1]) and not (last + 1 < len(may_join) and may_join[last + 1]):
        return run  # most runs end at an empty band: the occluders are not looked at
    occ = _not_its_own(occluders, origin, fit, r_eps)
    lit_from = _from_origin(projector, origin)

    def hidden(b):
        if not (0 <= b < len(may_join) and may_join[b]):
            return False
        mine = on & (bands == b)
        return _hidden_where_unseen(fit, [a0 + (b + 0.5) * band], np.arctan2(dz[mine], dl[mine]), sensor, occ, lit_from,
                                    ray_angle)

    while hidden(first - 1):
        first -= 1
    while hidden(last + 1):
        last += 1
    return first, last


def _without_bare_ends(run, bands, on, dl, dz, fit, a0, band, r_eps, sensor, occluders, origin, projector=None,
                       ray_angle=0.0, min_bands=2, min_points=3):
    """The run (first, last band; None if none is left) without the bands at its ends, min_bands or
    more in a row, whose points on the circle (`on`, bool; bands, dl, dz as _through_hidden's) come
    near fewer than half the places of its facing half (geometry.unseen_angles) and leave some of
    the rest where the sensor would see the can's side (not behind the occluders nor unlit:
    _hidden_where_unseen, arguments as _through_hidden's), where min_points or more lie off the
    circle beyond them: a lower box's top beyond a can's end meets its circle only along its edge
    (fresh 10928 of "lying can touching box", 35 mm too long)."""
    first, last = run
    fl, fz = _toward_sensor(*fit[:3], sensor)
    toward = math.atan2(fz, fl)
    half = (len(g.near_half_angles(toward)) + 1) // 2

    def seen(b):
        mine = on & (bands == b)
        return np.arctan2(dz[mine], dl[mine])

    def bare_from(ends):  # how many bands in a row from one end are bare, if min_bands or more
        sparse = []  # (band, its angles seen)
        for b in ends:
            angles = seen(b)
            if len(g.unseen_angles(angles, toward)) < half:
                break
            sparse.append((b, angles))
        if len(sparse) < min_bands:
            return 0  # the occluders are not looked at: most runs end at a band that shows its side
        others, lit_from = _not_its_own(occluders, origin, fit, r_eps), _from_origin(projector, origin)
        n = 0
        for b, angles in sparse:
            if _hidden_where_unseen(fit, [a0 + (b + 0.5) * band], angles, sensor, others, lit_from, ray_angle):
                break
            n += 1
        # One such band is the can's own last one, its end within it: seen over its top only.
        return n if n >= min_bands else 0

    # Only where another object lies beyond the run, min_points of it off the circle (a box's top goes
    # on past its edge): the image's edge across a can leaves only the can's side there, in bands
    # that show less and less of it (development 5 of "lying can", cut at column 330).
    other = ~on
    lo, hi = first, last
    if np.count_nonzero(other & (bands < first)) >= min_points:
        lo += bare_from(range(first, last + 1))
    if np.count_nonzero(other & (bands > last)) >= min_points:
        hi -= bare_from(range(last, lo - 1, -1))
    return (lo, hi) if lo <= hi else None


def _hidden_where_unseen(fit, axial, seen, sensor, occluders, projector=None, ray_angle=0.0):
    """Whether the places on the half of the cylinder fit ((theta, offset, zc, r, ...)) facing the
    sensor, at the axial coordinates `axial` (m), that no angle in `seen` (rad, from the lateral axis)
    comes near (geometry.unseen_angles: within half their spacing or, with ray_angle, rad, between
    neighbouring rays of the grid searched, 0: not known, within the arc between neighbouring samples
    there, _sample_arc) all have no depth (geometry.without_depth): behind one of the occluders ((M,
    3), m) seen from the sensor, or unlit by the IR projector ((3,), None: not known); sensor,
    projector, occluders and fit in one frame (the fits' coordinates)."""
    t, d, zc, r = fit[:4]
    fl, fz = _toward_sensor(t, d, zc, sensor)
    toward = np.arctan2(fz, fl)
    on_axis = [(a * np.cos(t) - d * np.sin(t), a * np.sin(t) + d * np.cos(t), zc) for a in axial]
    tolerance = None
    if ray_angle > 0 and len(seen):
        # The top of a can lying across the view, seen from above, is sampled sparsely where it turns
        # away: 19 degrees apart at its far limb (fresh 10001 of "cluttered table", r 38 mm at 0.9 m).
        distance = float(np.linalg.norm(np.mean(on_axis, axis=0) - np.asarray(sensor, dtype=float)))
        tolerance = _sample_arc(g.near_half_angles(toward), toward, r, distance, ray_angle)
    unseen = g.unseen_angles(seen, toward, tolerance=tolerance)
    if len(unseen) == 0:
        return True
    # Outward normals: the lateral axis is (-sin t, cos t, 0), the vertical (0, 0, 1).
    outward = np.column_stack([-np.cos(unseen) * np.sin(t), np.cos(unseen) * np.cos(t), np.sin(unseen)])
    places = np.vstack([r * outward + point for point in on_axis])
    return bool(g.without_depth(places, np.tile(outward, (len(axial), 1)), occluders, sensor, projector).all())


def _without_flat_end(bands, residual, diagonal, run, r_eps, min_bands=2, min_count=10, ratio=3.0, floor=1 / 3,
                      off=0.5, off_distance=0.5, min_diagonal=3):
    """The run (first, last band) without the bands at one end where no can's side is seen: a box's
    top beyond the can's end, about as high as the can, meets the circle only along a stripe near
    its top (its face toward the sensor, as wide as the can, near its side) and leaves it between.
    bands, residual (m) and `diagonal` (bool: on the flank toward the sensor, 30-65 degrees from the
    top) of the points within 3 r_eps of the circle on its facing half. Of the splits with at least
    min_bands bands and min_count points beyond, the one with the largest ratio of the rms residuals
    beyond and before it (less the run's band at the other end), if at least `ratio` and the rms
    beyond at least floor r_eps, where at least `off` of the diagonal points beyond (and
    min_diagonal) lie more than off_distance r_eps outside the circle and at most off / 2 of the
    rest's (a box's corner is off the circle there, a can's side on it: a neighbour along part of the
    can's side scatters too, but leaves that flank on it). The bands next to the split scattering no
    more than `ratio` x the rest's rms stay, and one more with less than `off` of its diagonal
    points off (the can's last band), and at least min_bands must go (docs/can_search.md, "Lying
    cans")."""
    first, last = run
    keep = (bands >= first) & (bands <= last)
    b, sq = bands[keep] - first, residual[keep] ** 2
    diagonal, outside = diagonal[keep], residual[keep] > off_distance * r_eps
    count = np.bincount(b, minlength=last - first + 1)
    band_sq = np.bincount(b, sq, minlength=len(count))
    band_rms = np.sqrt(band_sq / np.maximum(count, 1))
    per_band = np.stack([count, band_sq, np.bincount(b[diagonal], minlength=len(count)),
                         np.bincount(b[diagonal & outside], minlength=len(count))])
    # Sums over the bands below each split and from it on (points, squared residuals, diagonal points,
    # those outside): each split is judged on them, not on the points again.
    zero = np.zeros((4, 1))
    below = np.hstack([zero, np.cumsum(per_band, axis=1)])
    from_on = np.hstack([np.cumsum(per_band[:, ::-1], axis=1)[:, ::-1], zero])
    # The rest less its band at the other end of the run: that end's disc's rim scatters there as
    # much as a box ("lying can touching box", fresh seed 3834).
    best, split = ratio, None
    for c in range(min_bands, len(count) - min_bands + 1):
        for beyond, rest, at_end in ((from_on[:, c], below[:, c] - per_band[:, 0], True),
                                     (below[:, c], from_on[:, c] - per_band[:, -1], False)):
            (n_beyond, sq_beyond, d_beyond, out_beyond), (n_rest, sq_rest, d_rest, out_rest) = beyond, rest
            if n_beyond < min_count or n_rest < min_count:
                continue
            rms_beyond, rms_rest = math.sqrt(sq_beyond / n_beyond), math.sqrt(sq_rest / n_rest)
            if rms_beyond < floor * r_eps or rms_beyond <= best * rms_rest:
                continue
            if d_beyond < min_diagonal or out_beyond < off * d_beyond or out_rest > 0.5 * off * max(d_rest, 1):
                continue
            best, split = rms_beyond / max(rms_rest, 1e-9), (c, at_end, rms_rest)
    if split is None:
        return run
    c, at_end, rms_rest = split
    scatters = (band_rms > ratio * rms_rest) & (count > 0)
    # A band whose flank lies on the circle is the can's, however it scatters: its last band holds its
    # end's disc's rim (held-out 1403 of "lying can touching box" lost it, 1 cm, to the box beyond).
    flank_on = per_band[3] < off * per_band[2]
    gone = np.arange(c, len(count)) if at_end else np.arange(c - 1, -1, -1)
    # Give back the bands next to the split that scatter no more than the can's side, and one more
    # that lies on its flank (a neighbour's round side beyond the end has its flank on the circle too).
    end_band = False
    while len(gone) and (not scatters[gone[0]] or (flank_on[gone[0]] and not end_band)):
        end_band |= bool(scatters[gone[0]])
        gone = gone[1:]
    if np.count_nonzero(scatters[gone]) < min_bands:
        return run
    return (first, first + int(gone[0]) - 1) if at_end else (first + int(gone[0]) + 1, last)


def _without_level_crown(run, bands, dl, dz, residual, r, min_bands=2, min_points=10, bend=0.5, ratio=3.0):
    """The run (first, last band) without the bands at one end whose crown is level: a lower box's top
    beyond the can's end, narrower than it, lies within r_eps of its circle all across, but flat where
    a can's side bends down by 1 / (2 r) (1/m). At least min_bands in a row at an end, each with
    min_points in its crown (within r / 2 of the axis seen from above, above it) spread across it,
    bending down by less than `bend` of a can's, together scattering more than `ratio` x the rest of
    the run (less its band at the other end: its disc's rim) and the rest's crown bending as a can's.
    bands, dl, dz (m: from the axis) and residual (m: radial) of the points near the circle on its
    facing half."""
    first, last = run
    n = last - first + 1
    if n <= min_bands:
        return run
    keep = (bands >= first) & (bands <= last)
    b, x, y = bands[keep] - first, dl[keep], dz[keep]
    count = np.bincount(b, minlength=n)
    sq = np.bincount(b, residual[keep] ** 2, minlength=n)
    crown = (np.abs(x) <= 0.5 * r) & (y > 0)
    bc, xc, yc = b[crown], x[crown], y[crown]
    # Per band, the sums a least-squares parabola y = a x^2 + b x + c across the crown is solved from.
    sums = np.stack([np.bincount(bc, xc ** k, minlength=n) for k in range(5)]
                    + [np.bincount(bc, yc * xc ** k, minlength=n) for k in range(3)])

    def bends(s):
        """Whether the crown of the sums s bends down as a can's; None when too few points or spread
        over less than half the crown's width (a uniform spread of width w has variance w^2 / 12)."""
        if s[0] < min_points or s[2] / s[0] - (s[1] / s[0]) ** 2 < (0.5 * r) ** 2 / 12:
            return None
        m = np.array([[s[4], s[3], s[2]], [s[3], s[2], s[1]], [s[2], s[1], s[0]]])
        try:
            return bool(np.linalg.solve(m, s[[7, 6, 5]])[0] < -bend / (2 * r))
        except np.linalg.LinAlgError:  # two lateral places only: no parabola
            return None

    for at_end in (True, False):
        order = np.arange(n - 1, -1, -1) if at_end else np.arange(n)
        level = 0
        while level < n - 1 and bends(sums[:, order[level]]) is False:
            level += 1
        if level < min_bands:
            continue
        gone, rest = order[:level], order[level:-1]
        if bends(sums[:, rest].sum(axis=1)) is not True:  # (and so the rest holds points)
            continue
        rms_gone = math.sqrt(sq[gone].sum() / max(count[gone].sum(), 1))
        if rms_gone > ratio * math.sqrt(sq[rest].sum() / count[rest].sum()):
            return (first, first + int(gone[-1]) - 1) if at_end else (first + int(gone[-1]) + 1, last)
    return run


def end_positions(axial, rho, r, r_eps, extent=(-np.inf, np.inf), band=0.0, z=None):
    """The axial coordinates (m) of a cylinder's two ends: the 0.5th and 99.5th percentiles of the
    points within r + 2 r_eps of the axis (rho: their distances from it) within the extent (lo, hi)
    its circle explains, and of the points inside its circle (an end's disc) within `band` (m)
    beyond it: the band holding an end's disc is no side band, but a neighbour's side touching
    the end, seen beyond it, is not the can's. With their heights z (m) given, the points inside
    beyond an end count only if they stand across the axis rather than lie along it (a disc, not
    a lower box's top touching the end)."""
    inside = (axial >= extent[0]) & (axial <= extent[1])
    near = (rho <= r + 2 * r_eps) & inside
    for beyond in ((axial < extent[0]) & (axial >= extent[0] - band),
                   (axial > extent[1]) & (axial <= extent[1] + band)):
        disc = beyond & (rho < r - r_eps)
        # A disc spreads in height, a box's top along the axis ("lying can touching box", development
        # seeds 1 and 7: a box 41-47 mm high at the end made the can 10-17 mm too long).
        if z is None or np.count_nonzero(disc) < 3 or np.std(z[disc]) > np.std(axial[disc]):
            near |= disc
    if near.sum() < 2:
        return float(axial.min()), float(axial.max())
    lo, hi = np.percentile(axial[near], [0.5, 99.5])
    return float(lo), float(hi)


def _refine(q, z, theta, d, zc, r, r_eps, iterations, use, max_radius, max_gap, sensor=None, k=4.685, min_scale=5e-4):
    """Iteratively reweighted Gauss-Newton on (theta, d, zc, r) over the points of `use` (bool) (and on
    the cylinder's half facing the sensor, (x, y, z) relative to the origin of q, when given), with
    Tukey's biweight: a point beyond the cut-off gets no weight, and the cut-off is k x the scale
    (1.4826 x the median absolute residual of the points within r_eps, at least min_scale, m),
    re-estimated every iteration, but at most 2 r_eps. So a neighbour's face touching the can,
    millimetres off its circle, does not pull it. Returns (theta, d, zc, r, rms, n_inliers) or None
    when fewer than 4 points stay near it, the radius grows beyond 2 max_radius (m) or the axis
    leaves the height fit_lying_cylinder allows."""
    q, z = q[use], z[use]  # once, not in every iteration
    for _ in range(iterations):
        axial, lateral = _on_axis(q, theta)
        dl, dz = lateral - d, z - zc
        rho = np.hypot(dl, dz)
        residual = rho - r
        mine = _facing(dl, dz, theta, d, zc, sensor)
        within = np.abs(residual[mine])
        within = within[within <= r_eps]
        scale = 1.4826 * float(np.partition(within, len(within) // 2)[len(within) // 2]) if len(within) else np.inf
        cutoff = min(2 * r_eps, k * max(scale, min_scale))
        near = np.flatnonzero((np.abs(residual) < cutoff) & mine)
        if len(near) < 4:
            return None
        # The Jacobian's rows and the residual in one array: one product gives J^T W J and J^T W residual
        # (the iteration's time is NumPy's per-call cost). d rho / d theta = (dl / rho) d lat / d theta,
        # and d lat / d theta = -axial.
        rows = np.empty((5, len(near)))
        inverse = -1.0 / np.maximum(rho[near], 1e-9)
        np.multiply(dl[near], inverse, out=rows[1])
        np.multiply(dz[near], inverse, out=rows[2])
        rows[3] = -1.0
        np.multiply(rows[1], axial[near], out=rows[0])
        rows[4] = residual[near]
        w = (1 - (rows[4] / cutoff) ** 2) ** 2
        normal = (rows * w) @ rows.T
        try:
            step = np.linalg.solve(normal[:4, :4], -normal[:4, 4])
        except np.linalg.LinAlgError:
            return None
        theta, d, zc, r = theta + step[0], d + step[1], zc + step[2], r + step[3]
        if not 0 < r <= 2 * max_radius or abs(zc - r) > 0.25 * r + 2 * max_gap:
            return None
        if max(abs(step[1]), abs(step[2]), abs(step[3])) < 2e-5 and abs(step[0]) < 2e-4:
            break
    dl, dz = _on_axis(q, theta)[1] - d, z - zc
    residual = np.hypot(dl, dz) - r
    inl = (np.abs(residual) <= r_eps) & _facing(dl, dz, theta, d, zc, sensor)
    n = int(inl.sum())
    if n < 3 or not np.isfinite(r):
        return None
    return float(theta), float(d), float(zc), float(r), float(np.sqrt(np.mean(residual[inl] ** 2))), n


def _facing(dl, dz, theta, d, zc, sensor):
    """Whether points (dl, dz: lateral and vertical offsets from the axis (theta, d, zc), m) lie on the
    half of the cylinder facing the sensor ((x, y, z) in the frame of the lateral coordinates; None:
    all do): the only half of a can's side a sensor sees. Points near the circle on the far half
    are another object's (the face of a box touching it behind, seen past it)."""
    if sensor is None:
        return np.ones(len(dl), bool)
    fl, fz = _toward_sensor(theta, d, zc, sensor)
    return dl * fl + dz * fz > 0.0


def _toward_sensor(theta, d, zc, sensor):
    """Unit vector (lateral, z) from the axis (theta, d, zc) toward the sensor across it ((x, y, z) in
    the frame of the lateral coordinates, m; None: straight up)."""
    if sensor is None:
        return 0.0, 1.0
    fl = -sensor[0] * math.sin(theta) + sensor[1] * math.cos(theta) - d
    fz = sensor[2] - zc
    norm = max(math.hypot(fl, fz), 1e-9)
    return fl / norm, fz / norm


@dataclass(frozen=True, eq=False)
class LyingCan:
    """A lying can found (plane frame, m): fit (LyingFit), start (float64 (3,): centre of one end),
    direction (float64 (3,): unit axis, horizontal, from that end), length, inliers (bool (N,) over
    the points: its side within r_eps), mine (bool (N,): its side and ends), rms (of the inliers'
    radial residuals), shape_error, arc (rad: the side's span around the axis), rims (bool (N,): the
    rims of its ends' discs on the half away from the sensor, not in mine)."""

    fit: LyingFit
    rms: float
    start: np.ndarray
    direction: np.ndarray
    length: float
    inliers: np.ndarray
    mine: np.ndarray
    shape_error: float
    arc: float
    rims: np.ndarray


def lying_cans(points, r_eps, sigma, config, search, sensor=None, occluders=None, projector=None, ray_angle=0.0):
    """Every lying can among points (float64 (N, 3), plane frame, m), which may hold other objects
    touching them: (list of LyingCan, each one's masks over `points`; why the rest is no lying can).

    Found one at a time (lying_can), each taking its side and ends out of the points for the next."""
    free = np.ones(len(points), bool)
    found, why = [], ""
    while np.count_nonzero(free) >= config.min_fit_points and len(found) < search.max_rounds:
        idx = np.flatnonzero(free)
        can, why = lying_can(points[idx], r_eps, sigma, config, search, sensor, occluders, projector, ray_angle)
        if can is None:
            break
        inliers, mine, rims = (np.zeros(len(points), bool) for _ in range(3))
        inliers[idx[can.inliers]], mine[idx[can.mine]], rims[idx[can.rims]] = True, True, True
        found.append(dataclasses.replace(can, inliers=inliers, mine=mine, rims=rims))
        free &= ~mine
    return found, why


def lying_can(points, r_eps, sigma, config, search, sensor=None, occluders=None, projector=None, ray_angle=0.0):
    """A lying can among points (float64 (N, 3), plane frame, m): (LyingCan, "") or (None, why not).

    r_eps: inlier distance (m); sigma: depth noise there (m); config: auto_finder.AutoConfig (radius
    range, inlier fraction, rms, shape error, arc, min_can_height as the least length); search:
    can_search.CylinderSearchConfig (lying_gap, lying_directions, fit_points, the bands along the
    axis, max_taper, taper_sigmas, max_facet_ratio: a section no rounder than a line); sensor: (x,
    y, z), plane frame (m), or None: only the points on a cylinder's half facing it are its side
    (_facing); occluders (float (N, 3), plane frame, m, or None): every point standing on the
    table, what may hide part of its side; projector: the IR projector ((3,), plane frame, m; None:
    not known): the parts of the side it does not light have no depth (_rest_hidden); ray_angle (rad):
    between neighbouring rays of the grid searched (0: not known; _through_hidden). The distinct
    cylinders of fit_lying_cylinders are judged in turn on their extent; the first that passes is the
    can. When none does, those drawn without a taller box's points are judged the same way; else the
    first one's reason is why not."""
    c, s = config, search
    # A can on its side is at most one diameter high: the points above are another object's.
    limit = 2 * c.max_radius + s.lying_gap + 3 * sigma
    low = points[:, 2] <= limit
    if np.count_nonzero(low) < c.min_fit_points:
        top = float(np.percentile(points[:, 2], 99))
        return None, f"lying: {100 * top:.1f} cm high, more than a lying can's {200 * c.max_radius:.0f} cm"
    why = ""
    for without_taller_box in (False, True):
        fits = fit_lying_cylinders(points[low], r_eps, c.min_radius, c.max_radius, s.lying_gap + 3 * sigma,
                                   s.lying_directions, min(c.fit_iterations, 10), s.fit_points, band=s.band_height,
                                   band_fraction=s.band_fraction, min_band_points=s.min_band_points,
                                   max_band_gap=s.max_band_gap, sensor=sensor, occluders=occluders,
                                   projector=projector, without_taller_box=without_taller_box, ray_angle=ray_angle)
        for k, fit in enumerate(fits):
            can, reason = judge_lying(points, fit, r_eps, sigma, c, s, sensor, occluders, projector=projector)
            if can is not None:
                return _tighter(points, can, fits[k + 1:], r_eps, sigma, c, s, sensor, occluders, projector), ""
            why = why or reason
    return None, why or "lying: no horizontal cylinder fits its points"


def _tighter(points, can, others, r_eps, sigma, config, search, sensor, occluders, projector=None, ratio=2.0):
    """can, or a shorter one of the other fits on the same side (sharing more than half its side
    points) whose circle explains it more than `ratio` x better (rms): a box at a can's end as high
    and as wide as it draws a circle around both, whose compromise keeps the flank test from
    cutting it off (docs/can_search.md, "Lying cans")."""
    for fit in others:
        if fit.rms * ratio >= can.rms:
            continue
        other, _ = judge_lying(points, fit, r_eps, sigma, config, search, sensor, occluders, projector=projector)
        if (other is not None and other.length < can.length and other.rms * ratio < can.rms
                and (other.inliers & can.inliers).sum() > 0.5 * min(other.inliers.sum(), can.inliers.sum())):
            can = other
    return can


def judge_lying(points, fit, r_eps, sigma, config, search, sensor=None, occluders=None, min_arc=None,
                projector=None):
    """fit (a LyingFit, or None: none fitted) judged as a lying can on the points of its extent, as
    lying_can judges its own fits: (LyingCan, "") or (None, why). Arguments as lying_can's; min_arc
    (rad): the least arc of side seen (None: config's; the tracker keeps a hidden can's lower bound)."""
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
    a_lo, a_hi = end_positions(axial, rho, r, r_eps, fit.extent, s.band_height, z)
    # The side without the slabs of r_eps at the ends, where the ends' discs meet it.
    inner = (axial > a_lo + r_eps) & (axial < a_hi - r_eps)
    # Points near the circle on its far half are another object's (a box's face behind it).
    sq = _from_origin(sensor, fit.origin)
    mine = _facing(lateral - fit.offset, z - fit.zc, fit.theta, fit.offset, fit.zc, sq) | (rho < r - r_eps)
    side = (np.abs(rho - r) <= r_eps) & inner & mine
    body = (axial >= a_lo - r_eps) & (axial <= a_hi + r_eps) & (rho <= r + r_eps) & mine
    # Its ends' discs to their rims on the far half too: the upright search does not see them
    # (can_search), the search for more lying cans does (a second part of a can split by an object
    # across it, fitted on a subsample, came out another way without them).
    rims = (axial >= a_lo - r_eps) & (axial <= a_hi + r_eps) & (rho <= r + r_eps) & ~inner & ~body
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
    shape = g.shape_error(section, fit.offset, fit.zc, r, 2 * c.shape_bins)
    if shape > c.max_shape_error:
        return None, f"lying: shape error {1e3 * shape:.2f} mm > {1e3 * c.max_shape_error:.2f} mm (not round)"
    # A box's face whose upper part something in front hides (the real learn21 with its columns
    # reversed: 38 mm of a box's front under an overhanging box, 0.71 rad of a circle of r 32 mm) is
    # as near a circle's short arc as its noise: a can's side bends away from a line.
    straight = g.line_ratio(section, fit.offset, fit.zc, r)
    if straight < s.max_facet_ratio:
        return None, (f"lying: its side lies closer to a line than to the circle (rms ratio {straight:.2f} < "
                      f"{s.max_facet_ratio:.2f}; a flat face)")
    # Nor two: a box's top and the strip of its face under the edge (fresh 8146 of "lying can touching
    # box": r 31 mm about a box 63 mm high, its axis along the box's top, shape error 0.76 mm, 3.7 times
    # closer to the circle than to one line), as the upright search's test of a box's corner (facet_ratio).
    facets = g.facet_ratio(section, fit.offset, fit.zc, r)
    if facets < s.max_facet_ratio:
        return None, (f"lying: two flat faces: each half of its side lies closer to a line than to the circle "
                      f"(rms ratio {facets:.2f} < {s.max_facet_ratio:.2f}; a box's edge)")
    arc = g.arc_coverage(section, fit.offset, fit.zc)
    min_arc = c.min_arc if min_arc is None else min_arc
    # A can behind another, touching it, shows only the part of its side above the front one. What is
    # seen of it counts up to its ends: past the front can's end, its side may show lower within the
    # end's slab only (fresh 4535 of "lying cans touching").
    seen = (np.abs(rho - r) <= r_eps) & mine & (axial >= a_lo) & (axial <= a_hi)
    if arc < min_arc and not (arc >= s.min_occluded_arc and occluders is not None and sensor is not None
                              and _rest_hidden(fit, lateral[seen], z[seen], a_lo, a_hi, r_eps, sensor, occluders,
                                               projector)):
        return None, f"lying: side seen over {arc:.2f} rad < {min_arc:.2f} rad"
    # Its arc is seen all along it, not pieced together from a rim along its top and a few points at
    # its ends (the real learn43 with depth noise of a sigma added: a round tin's rim, 105 points, r 29.9 mm
    # over 2.13 rad, each 1 cm band spanning 0.23 rad at the median; lying cans of the development
    # and held-out seeds: 0.51 of their arc or more).
    band_arc = _band_arc(axial[side], np.arctan2(z[side] - fit.zc, lateral[side] - fit.offset), s.band_height)
    if band_arc < s.min_band_arc * arc:
        return None, (f"lying: its side's arc is not seen along it (median {band_arc:.2f} rad a "
                      f"{100 * s.band_height:.0f} cm band, < {s.min_band_arc:.2f} x {arc:.2f} rad: a rim or an edge)")
    length = float(a_hi - a_lo)
    if length < c.min_can_height:
        return None, f"lying: {100 * length:.1f} cm long (min {100 * c.min_can_height:.1f} cm)"
    why = _bulging(axial[side], rho[side], a_lo, length, sigma, s)
    if why:
        return None, why
    ux, uy = fit.direction
    return LyingCan(fit=fit, rms=rms, start=fit.point_on_axis(a_lo), direction=np.array([ux, uy, 0.0]), length=length,
                    inliers=side, mine=body, shape_error=shape, arc=arc, rims=rims), ""


def _band_arc(axial, angle, band):
    """The median over the `band`-long bands along an axis (axial positions, m) holding 2 points or
    more of the arc (rad) the points' angles about it (rad) span in each; 0 when none does."""
    which = np.floor((axial - axial.min()) / band).astype(np.int64)
    order = np.argsort(which, kind="stable")
    bands = np.split(angle[order], np.flatnonzero(np.diff(which[order])) + 1)
    spans = [g.angular_order(a)[1] for a in bands if len(a) >= 2]
    return float(np.median(spans)) if spans else 0.0


def hidden_ends(start, direction, length, radius, r_eps, sensor, occluders, reach=(0.01, 0.02), projector=None,
                own=None, ray_angle=0.0):
    """Which ends of a lying can an object in front hides: (origin's end, other end), bools.

    start: the centre of one end (3,), direction: horizontal (3,) or (2,), length, radius, r_eps (m);
    sensor (3,), projector (3,: the IR projector; None: not known) and occluders (float (N, 3)),
    every point standing on the table; all in the plane frame. An end is hidden when the places of
    the side's half facing the sensor `reach` (m) beyond it all lie behind occluders other than the
    can's own points, seen from the sensor, or are unlit by the projector (_hidden_where_unseen): the
    can may go on there unseen ("cluttered table" 3531, 3542: a tall box in front of one end; fresh
    6847: a tall can in front, beside whose silhouette the end lies in its shadow). But for those
    where its side is seen going on past the end (own: float (K, 3), plane frame, m, its cluster's
    points; those on its cylinder's facing half, more than r_eps and at most the farthest reach past
    it; ray_angle as _hidden_where_unseen's): fresh 10024 of "cluttered table", a lying can going on
    behind an upright can, a strip of its top seen over it, too narrow for its run to grow over."""
    u = np.asarray(direction, dtype=float)[:2]
    fit = LyingFit(direction=u / np.linalg.norm(u), origin=np.asarray(start, dtype=float)[:2], offset=0.0,
                   zc=float(start[2]), radius=float(radius), rms=0.0, n_inliers=0)
    others = _others(fit, np.asarray(occluders, dtype=float).reshape(-1, 3), 0.0, length, r_eps)
    axis, seen_from = (fit.theta, 0.0, fit.zc, fit.radius), _from_origin(sensor, fit.origin)
    lit_from = _from_origin(projector, fit.origin)
    origin_end, other_end = ([-d for d in reach], [length + d for d in reach])  # axial coordinates (m)
    beyond_origin = beyond_other = np.zeros(0)
    if own is not None and len(own):
        axial, lateral, z, rho = fit.coordinates(np.asarray(own, dtype=float).reshape(-1, 3))
        on = (np.abs(rho - fit.radius) <= r_eps) & _facing(lateral, z - fit.zc, fit.theta, 0.0, fit.zc, seen_from)
        angle, farthest = np.arctan2(z - fit.zc, lateral), max(reach)
        beyond_origin = angle[on & (axial < -r_eps) & (axial >= -farthest)]
        beyond_other = angle[on & (axial > length + r_eps) & (axial <= length + farthest)]
    return (_hidden_where_unseen(axis, origin_end, beyond_origin, seen_from, others, lit_from, ray_angle),
            _hidden_where_unseen(axis, other_end, beyond_other, seen_from, others, lit_from, ray_angle))


def _others(fit, occluders, a_lo, a_hi, r_eps):
    """The occluders (float (N, 3), plane frame, m) but the lying can's own points (within r_eps of
    its cylinder fit or inside it, between its ends at the axial coordinates a_lo..a_hi, m), in the
    fit's coordinates (_from_origin)."""
    axial, _, _, rho = fit.coordinates(occluders)
    own = (rho <= fit.radius + r_eps) & (axial >= a_lo - r_eps) & (axial <= a_hi + r_eps)
    return _from_origin(occluders[~own], fit.origin)


def _sample_arc(angles, toward, radius, distance, ray_angle):
    """The angle (rad, (K,)) between neighbouring samples of a grid `ray_angle` (rad) apart on the circle
    of a lying cylinder (radius, m) `distance` (m) from the sensor, at the angles (rad, (K,)) from its
    lateral axis up: ray_angle * distance / (radius cos(angle - toward)), toward the direction to the
    sensor across the axis (the samples' spacing across the cylinder's silhouette is the grid's)."""
    return ray_angle * distance / (radius * np.maximum(np.cos(np.asarray(angles) - toward), 1e-3))


def _rest_hidden(fit, side_lateral, side_z, a_lo, a_hi, r_eps, sensor, occluders, projector=None):
    """Whether every part of the near half of a lying can's side (fit, its ends at the axial
    coordinates a_lo..a_hi, m) that shows none of its side points (lateral and z coordinates) lies
    behind one of the occluders (float (N, 3), plane frame, m) seen from the sensor ((x, y, z), plane
    frame) or is unlit by the IR projector ((3,), plane frame; None: not known), next to both
    ends: a lying can behind another, touching it, is seen only above the front one (as can_search's
    upright _rest_hidden)."""
    return _hidden_where_unseen((fit.theta, fit.offset, fit.zc, fit.radius), (a_lo + r_eps, a_hi - r_eps),
                                np.arctan2(side_z - fit.zc, side_lateral - fit.offset),
                                _from_origin(sensor, fit.origin), _others(fit, occluders, a_lo, a_hi, r_eps),
                                _from_origin(projector, fit.origin))


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
