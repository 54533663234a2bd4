"""Cans inside objects (issue 13): upright cylinder hypotheses within each cluster on the table.

Pure NumPy; knows nothing of ROS. auto_finder finds the table and clusters the points standing
on it; this module looks inside each cluster for every can, instead of asking the cluster to be
one. Everything here is in the *plane frame* (z up from the table, metres). The method, the rules
and measured figures are in docs/can_search.md; in short, per cluster and round:

1. **Hypotheses.** Circles through triplets of side points seen from above (RANSAC: each triplet
   an anchor and two points within the diameter of a can of a radius drawn per anchor), radius
   within [min_radius, max_radius], from a pool drawn with weights that favour walls (a side piles
   many points into one ``wall_cell`` square seen from above, a lid one layer), but none on a box's
   flat faces (long straight runs seen from above; when they took the pool and its circles failed,
   a second pool off them). The ones with most pool points off those faces
   within r_eps on their half facing the sensor (less those inside the circle at its side's
   heights) are verified, best first, each sharing at most half its points with one taken before
   (circles through one box face count once).
2. **Grow along the axis.** The points are split into height bands (``band_height``); starting
   from the band where the circle holds most points, the run of bands grows down and up while
   each band still has points on the circle (at least ``band_fraction`` of the start band's) and
   no more inside the disc than on it, but not past a surface crowded around the circle (a box's
   top under the can). The can spans that run; its top is the lid above it.
3. **Fit and side criterion.** Levenberg-Marquardt (geometry.fit_cylinder) on the run's points
   on the circle, refitted by Tukey's biweight when that finds another surface's points among them
   (a box or can touching it; _robust_refit), then auto_finder's criterion: radius, inlier
   fraction, rms residual, shape error (flat faces of boxes and prisms), visible arc, the same
   radius along the height (a tapered side is a bowl's, pot's or cup's: _tapered), and at least
   min_can_height explained by the one circle (a bowl's radius changes with height), half of it
   spanned by the side's own points (an upside-down bowl's rim is a stripe under its foot).
4. **What it stands on.** Base within ``table_gap`` of the table: on the table, base seen.
   Else a surface at the base's height around the can, beside or behind its front (a tin's lid,
   a box's top): on that object (``support`` "object", or "can" when it is a can found
   below), base at that height, unless the can's own side goes on down its circle to the table
   (the surface is a neighbour's top). Else an object in front reaching up to the lowest visible
   point, or the image's edge cutting off the side's lowest points: base hidden, inferred on the
   table (``base_seen`` False). Else it floats: rejected.
5. **Not a can.** Open top: points within the circle on its far half (away from the sensor) below
   the rim, inside the disc well below the rim, or seen through where a solid one would stand -
   the inside of a hollow cylinder, so a cup, mug, bowl or pot. Handle: points just outside the
   circle within the can's height, on a narrow arc, reaching further below the top than a lid's
   lip but not down to the support - a mug.
   Inside another: a circle reaching more than r_eps into a cup or mug named before (its handle
   and the wall beside it) - two objects do not share space. Under another: a side on the circle
   of a round object named before that ends where it starts - its lower part.
6. The can's points are taken out of the cluster and the next round looks for another one. When
   none is found, a can seen by its lid alone (or a cup by its rim), and the rounds again. A round
   object named in one cluster takes its points in the others (searched again when before it).

Speed: a verification looks only at the free points near its circle (cropped per round from the
cluster's, height bands computed once per cluster), fits by geometry.fit_circles_algebraic and
fit_circle_geometric (fit_cylinder's objective with less overhead) and takes percentiles by
partial sorts; figures in docs/can_search.md.

7. **Lying cans.** Each cluster is searched for cans on their side first (example_pcl.lying:
   horizontal cylinders one radius above the table, judged like a side), and what the upright
   rounds leave again where they found upright cans; the parts of one lying can that an object
   across it splits into two clusters are joined (_join_lying).

What no hypothesis claims stays a rejected object with the reason of its best hypothesis (and why
it is no lying can either).
"""
import dataclasses
from dataclasses import dataclass, field
from functools import partial
from typing import Callable, NamedTuple, Optional

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from example_pcl import geometry as g
from example_pcl import lying
from example_pcl import transforms
from example_pcl.can import Can
from example_pcl.errors import PerceptionError, require_positive
from example_pcl.geometry import band_run


@dataclass(frozen=True)
class CylinderSearchConfig:
    """Parameters of the search inside clusters (module docstring). Lengths in metres.

    grid_step (px): the search sees every grid_step-th pixel in each direction; hypotheses:
    triplets drawn per round, each from one horizontal slice hypothesis_slice (m) high (one object);
    pool_points: at most this many points score them, drawn with weights that favour walls (points
    per wall_cell x wall_cell square seen from above); face_span, face_points: pool points on a straight
    run (seen from above) at least face_span (m) long, of at least face_points points, are a flat face
    (a box's) and anchor no triplet (geometry.flat_faces); when fewer than min_off_faces of the pool
    lie off them and its hypotheses fail, a pool is drawn off them (_pools); verify: the best so many
    distinct hypotheses are verified per round, each first refined by refine_rounds linear fits in
    its slice;
    fit_points: at most this many side points (evenly subsampled) go into the Levenberg-Marquardt
    fit; max_rounds: per cluster. retries,
    retry_verify: when no circle verified in a round makes progress, up to `retries` more draws from
    the pool points the circles tried did not explain (a big box's faces crowd a small can's
    triplets out of the first draw), verifying the best retry_verify of each; then the best
    retry_verify of the first draw's circles that one tried took out as its duplicates though
    elsewhere (_suppressed_by), scored on the pool points not on a flat face.
    band_height, band_fraction, min_band_points, max_band_gap (bands): the growth along the axis.
    table_gap: a base this close above min_height stands on the table; support_reach: a
    supporting surface is looked for this far around the can; occluder_reach: an object hiding
    the base is looked for this far in front. open_depth: a hollow cylinder shows points this far
    below its rim, a handle (not a lid's lip) this far below the top; max_open_fraction: of the
    circle's near-half points within open_window below the rim (or as deep as the far inner wall can
    show, _open_top), the far-half (or deep inside) ones an open top shows at least. handle_reach: a handle
    sticks out at most this far; max_handle_arc (rad), min_handle_points. min_hidden_arc (rad): a
    side seen over less than the criterion's min_arc but at least this is still a can when an
    object in front hides the rest; min_occluded_arc (rad): or at least this when every part of the
    side's near half not seen lies behind something closer to the sensor (_rest_hidden: a can behind
    another, touching it; a lying one's too, lying._rest_hidden). A side too narrow to fit a circle
    to, under a lid a taller object in front shadows, is fitted with the rim of the rest of that lid
    when it shows over at least min_hidden_arc (_side_and_rim).
    robust_k, robust_min_scale (m), min_outliers: the least-squares circle is refitted by Tukey's
    biweight (geometry.fit_circle_robust, cut-off robust_k x scale, the scale at least
    robust_min_scale) and replaced when at least min_outliers side points lie beyond the cut-off
    (another surface touching the can, not noise).
    max_taper, taper_sigmas: a can's radius is the same along its height, a bowl's, pot's or cup's is
    not. The side is rejected as tapered when its radius changes from the lower to the upper half
    by more than max_taper (m per m of height between them: 0.07, a wall 4 degrees off vertical;
    generated cans show at most 0.006, real ones 0.03) and by more than taper_sigmas standard
    errors of the change (depth noise sigma, so noise alone almost never does it).
    max_facet_ratio: a side seen over at least min_arc whose two halves both lie closer to a line
    than to the circle (rms, below this ratio: geometry.facet_ratio) is two flat faces, a box's
    corner the circle touches, not a can; a lying can's side whose whole arc does
    (geometry.line_ratio) is one flat face. flat_ratio: below this ratio the points are flat for
    sure even where noise may hide a can's curvature (a lid's sparse outline, _hull_rim; the stripe
    of side under a lid's rim, _lid_judged). max_split_ratio: a side either half of which (each of
    at least min_fit_points points) lies this many times closer (rms) to a circle of its own than to
    the side's (geometry.split_ratio) is two round objects, the fronts of two touching cans a wider
    circle is tangent to; inner_split: above this ratio, the half's own circle, when a can's radius
    and more than r_eps smaller, is verified, and its can taken if its rms is lower (a wider circle
    over a can's front and a neighbour's side beside it). min_band_arc: a lying can's side shows its
    arc all along it: the median over its band_height-long bands along the axis (those with 2 points
    or more) of the arc each one's side points span is at least this fraction of the side's arc
    (lying._band_arc; a round object's rim along a fit's axis spans next to none in each band).
    max_radius_error: a side its lid's rim does not pin, and a lid seen alone its side does not pin,
    fixes its circle's radius to this (the standard error, m: geometry.radius_standard_error), or is
    too narrow (or too noisy) to tell a can by.
    lid_arc (rad): a can seen by its lid alone (its side hidden behind an object in front) shows the
    lid's rim over at least this on the half away from the sensor (_lid_only); lid_levels: the
    heights tried for such a lid, fullest first (a box beside it may have more points at its top's
    height; up to as many boxes' tops tried count for none); max_lid_rectangularity: a lid whose
    points' convex hull fills more of its smallest enclosing rectangle (geometry.rectangularity: pi / 4
    for a disc) is a box's top; min_rim_side_arc (rad): its side seen lower, a stripe of it over at
    least this, on the rim's circle, is a can's side when the rest of its near half is hidden
    (verify, rim=True).
    lying_gap (m), lying_directions: lying cans are looked for in each cluster and in what the upright
    search leaves (example_pcl.lying): a lying can's axis, scanned over lying_directions directions,
    lies one radius above the table to within lying_gap (and 3 sigma). lying_join_angle (rad), lying_join_offset (m),
    lying_join_gap (m): two lying cans are the parts of one that an object across it splits
    (_join_lying).
    projector_offset (m): the IR projector's offset from the camera along its +x (a Kinect's 0.075); a
    can's side facing away from it, and what an object shadows from it, show no depth, and are hidden
    (_rest_hidden; a lying can's ends: lying.hidden_ends). 0: not known. The lying_* fields and
    this one are ROS parameters (cfg/can_search_params.py).
    seed: of the RANSAC sampling (the result is the same for the same cloud).
    """

    grid_step: int = 2
    hypotheses: int = 48
    hypothesis_slice: float = 0.05
    refine_rounds: int = 3
    pool_points: int = 200
    wall_cell: float = 0.005
    face_span: float = 0.06
    face_points: int = 12
    min_off_faces: float = 0.25
    verify: int = 2
    fit_points: int = 250
    max_rounds: int = 6
    retries: int = 1
    retry_verify: int = 1
    band_height: float = 0.01
    band_fraction: float = 0.2
    min_band_points: int = 3
    max_band_gap: int = 1
    table_gap: float = 0.012
    support_reach: float = 0.03
    occluder_reach: float = 0.3
    open_depth: float = 0.015
    open_window: float = 0.05
    max_open_fraction: float = 0.08
    handle_reach: float = 0.035
    max_handle_arc: float = 1.3
    min_handle_points: int = 8
    min_hidden_arc: float = 1.0
    min_occluded_arc: float = 0.5
    robust_k: float = 4.685
    robust_min_scale: float = 0.0005
    min_outliers: int = 3
    max_taper: float = 0.07
    taper_sigmas: float = 3.0
    max_facet_ratio: float = 1.0
    flat_ratio: float = 0.5
    max_split_ratio: float = 2.0
    min_band_arc: float = 0.25
    inner_split: float = 1.3
    max_radius_error: float = 0.006
    lid_arc: float = 2.5
    lid_levels: int = 2
    max_lid_rectangularity: float = 0.9
    min_rim_side_arc: float = 0.3
    lying_gap: float = 0.01
    lying_directions: int = 36
    lying_join_angle: float = 0.1
    lying_join_offset: float = 0.015
    lying_join_gap: float = 0.15
    projector_offset: float = 0.075
    seed: int = 0

    def validate(self):
        """Raises PerceptionError naming the first value that makes no sense."""
        require_positive(self, ("grid_step", "hypotheses", "pool_points", "wall_cell", "verify", "max_rounds",
                                "band_height", "min_band_points", "open_depth", "handle_reach", "lying_directions",
                                "lid_levels"))


@dataclass(frozen=True, eq=False)
class Rejection:
    """What in a cluster is not a can: centroid (plane frame, m), n_points, reason, radius of its
    best circle (m, or None)."""

    centroid: np.ndarray
    n_points: int
    reason: str
    radius: Optional[float] = None


# --- hypotheses -----------------------------------------------------------------------------------


def circumcircles(a, b, c):
    """Circles through triplets of 2-D points a, b, c (float64 (K, 2) each): (cx, cy, r) arrays;
    collinear triplets get r = inf."""
    bx, by = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    qx, qy = c[:, 0] - a[:, 0], c[:, 1] - a[:, 1]
    d = 2 * (bx * qy - by * qx)
    b2, q2 = bx * bx + by * by, qx * qx + qy * qy
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = (qy * b2 - by * q2) / d
        uy = (bx * q2 - qx * b2) / d
    r = np.hypot(ux, uy)
    r[~np.isfinite(r)] = np.inf
    return ux + a[:, 0], uy + a[:, 1], r


def circle_hypotheses(xy, z, n, rng, min_radius, max_radius, slice_height, partners=16):
    """Up to n circles (cx, cy, r, z0) through triplets of the points xy (float64 (M, 2), m) at heights
    z (m): each an anchor and two points near it in the same horizontal slice of slice_height (m)
    (z0: the middle of that slice), radius within range.

    Near: within the diameter of a can of a radius drawn per anchor (log-uniform in [min_radius,
    max_radius]), so a small can beside a box gets triplets of its own points as often as a large
    one. One slice keeps the three on one object (a cup on a can, a few millimetres wider, gives no
    circle in between). The two are the first near ones of `partners` points drawn within that
    reach of the anchor in x among its slice's (the points sorted by slice, then x): no (n, M)
    distance matrix."""
    m = len(xy)
    if m < 3:
        return np.empty(0), np.empty(0), np.empty(0), np.empty(0)
    level = np.floor(z / slice_height)
    # One sort key: slices far enough apart in it that no reach in x crosses from one to the next.
    x = xy[:, 0] - xy[:, 0].min()
    key = level * (x.max() + 4 * max_radius + 1.0) + x
    order = np.argsort(key, kind="stable")
    sk = key[order]
    anchors = rng.integers(m, size=n)
    reach = 2 * np.exp(rng.uniform(np.log(min_radius), np.log(max_radius), size=n))
    lo = np.searchsorted(sk, key[anchors] - reach)
    hi = np.searchsorted(sk, key[anchors] + reach, side="right")
    drawn = order[lo[:, None] + (rng.random((n, partners)) * (hi - lo)[:, None]).astype(np.int64)]
    d2 = ((xy[drawn] - xy[anchors, None, :]) ** 2).sum(axis=2)  # (n, partners)
    near = (d2 <= (reach ** 2)[:, None]) & (d2 >= (0.25 * min_radius) ** 2)
    first = np.argsort(~near, axis=1, kind="stable")[:, :2]
    rows = np.arange(n)[:, None]
    ok = near[rows, first].all(axis=1)
    if not ok.any():
        return np.empty(0), np.empty(0), np.empty(0), np.empty(0)
    two = drawn[rows, first][ok]
    cx, cy, r = circumcircles(xy[anchors[ok]], xy[two[:, 0]], xy[two[:, 1]])
    keep = (r >= min_radius) & (r <= max_radius)
    return cx[keep], cy[keep], r[keep], ((level[anchors[ok]] + 0.5) * slice_height)[keep]


def circle_members(xy, cx, cy, r, eps, sensor=None):
    """Which of the points xy (float64 (M, 2), m) lie within eps of each circle (cx, cy, r: (K,) each):
    (members (K, M) bool, residual (K, M): distance from the centre minus the radius, m). With the
    sensor's (x, y) given, only the points on the half of a circle facing it (and a quarter radius
    beyond) are members."""
    dx, dy = xy[None, :, 0] - cx[:, None], xy[None, :, 1] - cy[:, None]
    residual = np.sqrt(dx * dx + dy * dy) - r[:, None]
    members = np.abs(residual) <= eps
    if sensor is not None:
        fx, fy = sensor[0] - cx, sensor[1] - cy
        norm = np.maximum(np.hypot(fx, fy), 1e-9)
        members &= (dx * (fx / norm)[:, None] + dy * (fy / norm)[:, None]) > -0.25 * r[:, None]
    return members, residual


def best_circles(xy, cx, cy, r, eps, count, sensor=None, max_overlap=0.5, z=None, lid=0.01):
    """The `count` best circles, distinct: at most max_overlap of the smaller one's points within eps / 2
    shared with one taken before (so circles through one box face count once, while a can beside it,
    or a cup of another radius on it, is another): their positions in cx, cy, r. Best: the largest
    sum of 1 - (residual / eps)^2 over the points of xy within eps (MSAC's truncated quadratic),
    i.e. many points, close, less the points more than eps inside the circle at the heights of its
    own points (z: the points' heights, m; None: not counted), below the top `lid` (m) of them. With
    the sensor's (x, y) given, only points on the half of a circle facing it count (an upright
    can's side seen; a face seen across a circle's far half is no can)."""
    if len(cx) == 0:
        return []
    members, residual = circle_members(xy, cx, cy, r, eps, sensor)
    score = members.sum(axis=1)
    # Ranked by how close, not only how many: a wide circle tangent to a can's front, or through it
    # and a box's edge, holds as many points in its band as the can's own circle, but loosely.
    quality = np.where(members, 1.0 - (residual / eps) ** 2, 0.0).sum(axis=1)
    if z is not None:
        # Seen from above, a can's disc is empty at the heights of its side (its lid lies at the top):
        # a wide circle tangent to a can holds the rest of the can inside, and outranked the can's own.
        low = np.where(members, z[None, :], np.inf).min(axis=1)
        high = np.where(members, z[None, :], -np.inf).max(axis=1) - lid
        quality -= ((residual < -eps) & (z[None, :] >= low[:, None]) & (z[None, :] <= high[:, None])).sum(axis=1)
    # Shared: within eps / 2 of both. A circle tangent to a can's front, wider than it, shares about half
    # the can's points within eps but fewer within eps / 2; the can's own circles share most of them.
    tight = members & (np.abs(residual) <= 0.5 * eps)
    taken = []
    for k in np.argsort(-quality, kind="stable"):
        if score[k] < 3:
            break
        if taken and _duplicates(tight[k:k + 1], tight[taken], max_overlap).any():
            continue
        taken.append(int(k))
        if len(taken) == count:
            break
    return taken


# --- one cluster ----------------------------------------------------------------------------------


class _Claim(NamedTuple):
    """A round object claimed as no can (plane frame, m): its circle, the heights of the points it
    took, whether it is hollow (a cup, a mug: its inside or handle seen) and whether it keeps its
    space (its far inner wall or handle seen where the circle puts them)."""

    cx: float
    cy: float
    r: float
    z_lo: float
    z_hi: float
    hollow: bool
    keeps_space: bool = False


@dataclass
class _Context:
    """What every verification in a search shares."""

    config: object  # auto_finder.AutoConfig
    search: CylinderSearchConfig
    T_sensor_from_plane: np.ndarray  # 4x4: the table's plane frame in the sensor frame
    sensor: np.ndarray  # the sensor in the plane frame (m)
    standing: np.ndarray  # float64 (N, 3): every point standing on the table (for occluders)
    rng: np.random.Generator
    found: list  # the Cans found so far (supports for stacked cans)
    ray_angle: float = 0.0  # rad: between the rays of neighbouring grid pixels (0: not known)
    claimed: list = field(default_factory=list)  # _Claim: the round objects claimed as no can
    # float64 (E, 3): the standing points on the image's edge (the view ends beyond them; plane frame, m)
    image_edge: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    projector: Optional[np.ndarray] = None  # (3,): the IR projector in the plane frame (m); None: not known
    # Which places (float64 (K, 3), plane frame, m) lie beyond the image's edge: bool (K,); None: no image.
    beyond_image: Optional[Callable] = None


class _Free:
    """The points of a cluster not taken yet, in one round: their indices into the cluster's points,
    their coordinates (float64 (F, 3), plane frame, m), height bands and median height. Computed
    once per round and cropped around each hypothesis, so a verification looks at the points near
    its circle only. seen: the cluster's points no can found took (float64 (S, 3)), those a round
    object's claim took too (for _lid_only; None: not asked for)."""

    def __init__(self, points, bands, idx, seen=None):
        self.idx, self.points, self.bands, self.seen = idx, points[idx], bands[idx], seen
        self.x, self.y, self.z = self.points[:, 0], self.points[:, 1], self.points[:, 2]
        self.median_z = _percentile(self.z, 50)

    def near(self, cx, cy, half):
        """Positions (into this round's arrays) of the points within a square of half side `half` (m)
        about (cx, cy)."""
        return np.flatnonzero((np.abs(self.x - cx) <= half) & (np.abs(self.y - cy) <= half))

    def disc(self, cx, cy, radius, z_lo, z_hi):
        """Positions (into this round's arrays) of the points within `radius` of the axis (cx, cy),
        between heights z_lo and z_hi (m)."""
        return np.flatnonzero(((self.x - cx) ** 2 + (self.y - cy) ** 2 <= radius * radius) & (self.z >= z_lo)
                              & (self.z <= z_hi))


def _percentile(values, q):
    """np.percentile(values, q) (linear interpolation) by a partial sort, at a fraction of its cost."""
    n = len(values)
    pos = q / 100 * (n - 1)
    lo = int(pos)
    hi = min(lo + 1, n - 1)
    part = np.partition(values, (lo, hi))
    return float(part[lo] + (pos - lo) * (part[hi] - part[lo]))


def _sigma(ctx, center):
    return ctx.config.depth_sigma(center, ctx.sensor)


def _facing(x, y, cx, cy, r, ctx):
    """The points on the half of the circle (cx, cy, r) that faces the sensor (and a quarter radius
    beyond): the only half of an upright can's side a sensor sees."""
    front = _toward_sensor(cx, cy, ctx)
    return (x - cx) * front[0] + (y - cy) * front[1] > -0.25 * r


class _TooFew(str):
    """verify's reason when too few side points (`n_points`) lie on the circle to judge it by (a str as
    every reason)."""

    def __new__(cls, n_points, least):
        reason = super().__new__(cls, f"{n_points} points on the circle (min {least})")
        reason.n_points = n_points  # not `count`: str has that method
        return reason


def verify(free, cx, cy, r, ctx, z0=None, again=True, rim=False, split=True):
    """One circle hypothesis against a cluster's free points (_Free, plane frame):
    (Can whose .indices index the cluster's points, None, None), or (None, reason, claim):
    claim the indices of the points of a round object that is no can (a tin, cup, bowl), else None.
    z0: the height (m) of the points the circle came from (None: any). again: when the fit lands
    more than r_eps from the circle the bands were judged on, verify once more from the fitted
    circle. rim: the circle is a lid's rim (_lid_only), judged as it is, not fitted to the side: a
    side seen over a narrow stripe does not fix a circle, and over at least min_rim_side_arc it is a
    can's when the rest of its near half is hidden (_rest_hidden). split: a half of the side with a
    smaller circle of its own is verified on it (inner_split)."""
    c, s = ctx.config, ctx.search
    sigma = _sigma(ctx, (cx, cy, free.median_z))
    r_eps = c.r_eps_at(sigma)
    # Every test before the fit looks within support_reach of the circle, which the refinement
    # below moves by less than 2 r_eps (and widens by less than 2 r_eps).
    near = free.near(cx, cy, r + 4 * r_eps + s.support_reach)
    pts, bands = free.points[near], free.bands[near]
    x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
    # The triplet's circle is only as good as three noisy points: linear (Kasa) fits to the points
    # near it, on its near half and near its height (a cup on the can, a few millimetres wider,
    # would pull it between the two), before the bands judge it. A few rounds: a circle through
    # the ends of a short arc first takes part of it only.
    dist = np.hypot(x - cx, y - cy)
    x0, y0, r0 = cx, cy, r
    level = np.abs(z - z0) <= 0.5 * s.hypothesis_slice if z0 is not None else np.ones(len(z), bool)
    # Not the top band: a lid's points near its rim lie within r_eps inside the circle.
    inner = dist <= r + r_eps
    if np.count_nonzero(inner) >= c.min_fit_points:
        level &= z < _percentile(z[inner], 99) - s.band_height
    for _ in range(0 if rim else s.refine_rounds):
        close = (np.abs(dist - r) <= r_eps) & _facing(x, y, cx, cy, r, ctx) & level
        if np.count_nonzero(close) < c.min_fit_points:
            break
        kx, ky, kr = (float(v[0]) for v in g.fit_circles_algebraic(pts[close]))
        if not (abs(kr - r0) < 2 * r_eps and np.hypot(kx - x0, ky - y0) < 2 * r_eps):
            if again and c.min_radius <= kr < r0 - 2 * r_eps:
                # A wide circle tangent to a can's front: its close points are the can's, whose circle
                # lies inside it. Verified from that circle instead.
                return verify(free, kx, ky, kr, ctx, z0, again=False, split=split)
            break
        cx, cy, r = kx, ky, kr
        dist = np.hypot(x - cx, y - cy)
    # An upright can shows the sensor its near half only: points on the circle's far half are the
    # inside of something hollow (a cup's far wall), never a can's side.
    facing = _facing(x, y, cx, cy, r, ctx)
    residual = dist - r
    on = (np.abs(residual) <= r_eps) & facing
    inside = dist < r - r_eps
    nb = int(c.max_height / s.band_height) + 1
    band_on = np.bincount(bands[on], minlength=nb)
    band_inside = np.bincount(bands[inside], minlength=nb)
    # A band is on the circle when its points near it are centred on it, not offset (a cup a few
    # millimetres wider standing on the can).
    near_circle = (np.abs(residual) <= 2 * r_eps) & facing
    with np.errstate(invalid="ignore", divide="ignore"):
        offset = (np.bincount(bands[near_circle], weights=residual[near_circle], minlength=nb)
                  / np.bincount(bands[near_circle], minlength=nb))
    band_on = np.where(np.abs(offset) <= 0.5 * r_eps, band_on, 0)
    # A band whose disc holds more points than its circle is a lid (or the inside of something): the
    # side does not go on past it (a taller box touching the can showed on the circle above its lid).
    lid_like = band_inside > np.maximum(band_on, s.min_band_points)

    def hidden(first, last):
        # The side goes on up over bands it shows too little of where they are hidden: a can behind a lower
        # object shows its side beside that object's silhouette and above it, with no points between
        # (fresh 7201 of "cluttered table": behind a cup 97 mm high, the can 118 mm; the side below the
        # gap was taken for a can 69 mm high and the part above for another standing on it).
        gap = on & (bands >= first) & (bands <= last)
        return _rest_hidden(pts[gap, :2], cx, cy, r, r_eps, first * s.band_height, (last + 1) * s.band_height, ctx)

    run = band_run(band_on, band_inside, s.band_fraction, s.min_band_points, s.max_band_gap, lid_like, across=hidden)
    if run is None:
        return None, "no band of points on the circle", None
    judged = (cx, cy, r)
    lo, hi = run
    # A surface the can stands on (a tin's lid, a box's top) adds a band crowded with points on
    # the circle and beyond it: the side starts above it.
    ring = (dist > r + r_eps) & (dist <= r + s.support_reach)
    band_out = np.bincount(bands[ring], minlength=nb)
    crowded = 1.3 * _percentile(band_on[lo:hi + 1], 50)
    while lo < hi and band_on[lo] > crowded and band_out[lo] >= 0.3 * band_on[lo]:
        lo += 1
    # So does a band the run bridged with no side on the circle and a surface around it (a box's top
    # around the can standing on it; below, the box's face the can overhangs by 4 mm, near its circle:
    # fresh 13218 of "can on box", a can 131 mm high on a box 58 mm high taken from the table): crowded
    # beyond the circle, over at least half of it (4.7 rad there; a box's top touching a can's side
    # beside it, 1.2 rad: fresh 13141 of "can touching box").
    need = max(s.min_band_points, s.band_fraction * band_on[lo:hi + 1].max())
    crowd = 2 * _percentile(band_on[lo:hi + 1], 50)
    surface = [k for k in range(lo + 1, hi) if band_on[k] < need and band_out[k] >= crowd
               and g.arc_coverage(pts[ring & (bands == k), :2], cx, cy) >= np.pi]
    lo = surface[-1] + 1 if surface else lo
    z_lo, z_hi = lo * s.band_height, (hi + 1) * s.band_height
    # The side ends top_margin (and 3 sigma) below the lid, so the lid's rim is no side point.
    top = _lid(pts[:, :2], dist, z, r, r_eps, z_lo, z_hi, s)
    z_end = min(z_hi, top - c.top_margin - 3 * sigma)
    side = on & (z >= z_lo) & (z < z_end)
    n_side = int(np.count_nonzero(side))
    if n_side < c.min_fit_points:
        return None, _TooFew(n_side, c.min_fit_points), None

    def claim(x0=None, y0=None, radius=None, z_from=None, hollow=False, keeps_space=False, with_lid=False):
        """The points of a round object that is no can: its disc over the run, from z_from (m) when
        its base is known (a cup on a can leaves the can's lid), so no other hypothesis is tried on it.
        A hollow one (its inside or handle seen: a cup or mug for sure) is no can's top; it keeps its
        space (_inside_cup) when its far inner wall or handle showed where its circle puts them.
        with_lid: up to its lid too (3 sigma above `top`): the run ends a band under a flat lid, whose points
        would be left to the lying search (_claim_round)."""
        x0, y0, radius = (cx, cy, r) if x0 is None else (x0, y0, radius)
        taken = free.disc(x0, y0, radius + r_eps, z_lo - s.band_height if z_from is None else z_from,
                          max(z_hi + s.band_height, top + 3 * sigma) if with_lid else z_hi + s.band_height)
        if len(taken):
            ctx.claimed.append(_Claim(x0, y0, radius, float(free.z[taken].min()), float(free.z[taken].max()), hollow,
                                      keeps_space))
        return free.idx[taken]

    if rim:
        return _judge_side(free, cx, cy, r, r_eps, r_eps, sigma, z_lo, z_hi, top, claim, ctx, s.min_rim_side_arc)
    # A run over two objects on a circle between them (a cup 8 mm wider set 5 mm off the can's axis:
    # fresh 8641 of "cup on can", bands 1.3 mm inside the circle and 2.9 mm outside) is fitted on the
    # part _judge_side will judge, or the fit lands between the two and neither is round.
    in_run = near_circle & (z >= z_lo) & (z < z_hi)
    part = _offset_step(bands[in_run], residual[in_run], lo, hi, 0.5 * r_eps)
    if part is not None:
        side &= (bands >= part[0]) & (bands <= part[1])
        if np.count_nonzero(side) < c.min_fit_points:
            return None, _TooFew(int(np.count_nonzero(side)), c.min_fit_points), None
    # A linear (Kasa) circle first: cheap, and it already says when the radius is no can's.
    kx, ky, kr = (float(v[0]) for v in g.fit_circles_algebraic(pts[side]))
    if not np.isfinite(kr):
        return None, "no circle fits the side (the points are collinear)", None
    if not c.min_radius - r_eps <= kr <= c.max_radius + r_eps:
        return _no_cans_radius(free, pts[side], kx, ky, kr, r_eps, claim, ctx, split)
    xy = pts[side, :2]
    if len(xy) > s.fit_points:
        xy = xy[:: int(np.ceil(len(xy) / s.fit_points))]
    try:
        cx, cy, r = g.fit_circle_geometric(xy, (cx, cy), r, r_eps, max_iterations=c.fit_iterations,
                                           tol=c.fit_tolerance, min_inliers=c.min_fit_points, max_shift=r)
    except PerceptionError as e:
        # A stripe of side too narrow to fix a circle, its lid's rim seen across it does (held-out 1207
        # of "cluttered table": a can behind two taller ones, its side seen through the gap between them).
        pinned = _side_and_rim(pts, xy, top, sigma, r_eps, ctx)
        if pinned is None:
            return None, f"no circle fits the side ({str(e).split(';')[0]})", None
        cx, cy, r, cutoff = *pinned, np.inf
    else:
        cx, cy, r, cutoff = _robust_refit(xy, cx, cy, r, r_eps, ctx)
    if not c.min_radius <= r <= c.max_radius:
        return _no_cans_radius(free, xy, cx, cy, r, r_eps, claim, ctx, split)
    # A wide circle through part of a can's side fits onto the can, but its run of bands was grown on
    # the wide circle's points (a part of the can's height): the bands are judged again on the fit. So
    # too a circle refined 7 mm small at the height of a lying can touching the can: its upper bands lay
    # 3 mm off it (fresh 4542 of "lying can touching can").
    if again and (np.hypot(cx - judged[0], cy - judged[1]) > r_eps or abs(r - judged[2]) > r_eps):
        return verify(free, cx, cy, r, ctx, again=False, split=split)
    return _judge_side(free, cx, cy, r, r_eps, cutoff, sigma, z_lo, z_hi, top, claim, ctx, s.min_occluded_arc, split)


def _judge_side(free, cx, cy, r, r_eps, cutoff, sigma, z_lo, z_hi, top, claim, ctx, min_occluded_arc, split=False):
    """verify's judgement of the side on the circle (cx, cy, r) it fitted (or a lid's rim): its run of
    bands z_lo..z_hi, the lid's height top (m), the robust fit's cut-off (m); claim: verify's;
    min_occluded_arc (rad): the least arc seen when the rest of the near half is hidden; split:
    verify's."""
    c, s = ctx.config, ctx.search
    # The fit moved the circle: the rest looks within reach of a handle or a support of the new one.
    near = free.near(cx, cy, r + r_eps + max(2 * s.handle_reach, s.support_reach))
    pts = free.points[near]
    x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
    dist = np.hypot(x - cx, y - cy)
    # The run's bands about the fitted circle: a step in the mean offset of their points near it is two
    # objects on a circle between them (a cup 8 mm wider on the can, seen from 1.3 m: fresh 3801 of
    # "cup on can"); the part on the circle is judged.
    facing = _facing(x, y, cx, cy, r, ctx)
    near_circle = (np.abs(dist - r) <= 2 * r_eps) & facing & (z >= z_lo) & (z < z_hi)
    part = _offset_step(free.bands[near][near_circle], dist[near_circle] - r, int(round(z_lo / s.band_height)),
                        int(round(z_hi / s.band_height)) - 1, 0.5 * r_eps)
    if part is not None:
        z_lo, z_hi = part[0] * s.band_height, (part[1] + 1) * s.band_height
    # The lid again about the fitted circle: a box touching the side lay inside the hypothesis' wider
    # one. The lower of the two: points that do not belong (a box, a can on the lid) only raise it.
    top = min(top, _lid(pts[:, :2], dist, z, r, r_eps, z_lo, z_hi, s, fitted=True))
    z_end = min(z_hi, top - c.top_margin - 3 * sigma)
    in_run = (z >= z_lo) & (z < z_end)
    facing_run = facing & in_run
    # The robust fit's outliers are another surface's points, not the can's side.
    side = (np.abs(dist - r) <= min(r_eps, cutoff)) & facing_run
    n_side = int(np.count_nonzero(side))
    if n_side < c.min_fit_points:
        return None, f"{n_side} points on the fitted circle (min {c.min_fit_points})", None
    residual = dist[side] - r
    rms = float(np.sqrt(residual @ residual / n_side))
    max_rms = max(c.max_rms, c.max_rms_sigmas * sigma)
    sxy = pts[side, :2]
    base = _percentile(z[side], 1)
    # Inlier fraction of the side below the lid: points inside the disc there are no can's.
    fraction = n_side / max(int(np.count_nonzero((dist <= r + r_eps) & in_run)), 1)
    halves = g.split_circles(sxy, cx, cy, r, c.min_fit_points)
    ratio = g.halves_ratio(halves)
    # A wider circle over a can's front and an object beside or in front of it (fresh 5134 of
    # "cluttered table": r 39.9 mm over two touching cans, 11 mm off the one of 29.7, rms 2.6 mm; 5113:
    # r 50.5 mm over a can and the cup in front, "not round"): the can's own circle, if it fits better.
    own = _own_circle_can(free, halves, r, r_eps, ctx, better_than=rms) if split else None
    if own is not None:
        return own, None, None
    if rms > max_rms:
        return None, f"rms residual {1e3 * rms:.2f} mm > {1e3 * max_rms:.2f} mm", None
    shape = g.shape_error(sxy, cx, cy, r, c.shape_bins)
    if shape > c.max_shape_error:
        return None, f"shape error {1e3 * shape:.2f} mm > {1e3 * c.max_shape_error:.2f} mm (not round)", None
    if ratio > s.max_split_ratio:
        return None, (f"two round objects: half of the side lies {ratio:.1f} times closer to a circle of its own "
                      f"(max {s.max_split_ratio:.1f})"), None
    if fraction < c.min_inlier_fraction:
        # A round side with its inside seen (a cup's far wall) is a hollow object: named and claimed,
        # so the can it may stand on is looked for next.
        why, wall_seen = _open_top(pts[dist <= r + r_eps], cx, cy, r, r_eps, base, top, ctx)
        if why:
            # Not below its run: the side of a can under a wider cup may lie within r_eps of its circle.
            return None, why, claim(z_from=max(base, z_lo), hollow=True, keeps_space=wall_seen)
        return None, (f"only {100 * fraction:.0f}% of the side within {1e3 * r_eps:.1f} mm of the circle "
                      f"(min {100 * c.min_inlier_fraction:.0f}%)"), None
    # Over the side's points with another within reach: a stray point or two far round the circle (the
    # edge of a box's side face) would stretch it (fresh 5004 of "cluttered table": 0.4 rad of a box's
    # front and two points of its side 0.5 rad beyond made 2.06).
    arc = g.arc_coverage(sxy[_not_stray(pts[side], r_eps, ctx)], cx, cy)
    pinned = False
    if arc < c.min_arc and not (arc >= s.min_hidden_arc and _in_front(cx, cy, r, base, top, ctx)) \
            and not (arc >= min_occluded_arc and _rest_hidden(sxy, cx, cy, r, r_eps, base, z_end, ctx)):
        # A narrow stripe fixes its circle poorly (held-out 2605 of "cluttered table": r 36 mm for 30,
        # and part of that circle's near half did not lie behind the can in front): judged on the
        # circle its lid's rim pins.
        joint = _pinned_by_lid(pts, sxy, cx, cy, r, top, sigma, r_eps, max_rms, ctx) \
            if arc >= min_occluded_arc else None
        if joint is None or not _rest_hidden(sxy, *joint[:3], r_eps, base, z_end, ctx):
            return None, f"side seen over {arc:.2f} rad < {c.min_arc:.2f} rad", None
        cx, cy, r, rms = joint
        dist, pinned = np.hypot(x - cx, y - cy), True
    # Checked where both halves span enough of the circle for its curvature to show: at least 1.25
    # on the 2324 cans found so on the development seeds 0-99 and 400-499, 1.38 on the real ones;
    # 0.40-0.94 on the five 4 x 4 cm boxes found as cans there before.
    facets = g.facet_ratio(sxy, cx, cy, r) if arc >= c.min_arc else np.nan
    if facets < s.max_facet_ratio:
        return None, (f"two flat faces: each half of the side lies closer to a line than to the circle "
                      f"(rms ratio {facets:.2f} < {s.max_facet_ratio:.2f}; a box's corner)"), None
    # What it stands on.
    support, base_seen, base_z, why = _support(pts, cx, cy, r, base, r_eps, sigma, ctx)
    if support is None:
        return None, why, None
    # On an object, the points within 3 sigma of its surface are the support's.
    lowest = base_z - 0.5 * s.band_height if support == "table" else base_z + 3 * sigma
    # The side's own points within 2 r_eps (not the robust fit's outliers), to see its radius change.
    wall = (np.abs(dist - r) <= min(2 * r_eps, cutoff)) & facing_run
    why = _tapered(dist[wall], z[wall], sigma, ctx)
    if why:
        return None, why, claim(z_from=lowest)
    height = top - base_z
    # Its base hidden behind an object in front, the side below what is seen is hidden too: half
    # min_can_height seen will do (a taller can behind another shows its side above the front one's lid).
    seen = min(c.min_can_height if base_seen else 0.5 * c.min_can_height, 0.6 * height)
    if height < c.min_can_height or top - base < seen:
        return None, (f"one circle explains only {100 * (top - base):.1f} cm of it (min "
                      f"{100 * seen:.1f} cm; a bowl's radius changes with height)"), claim(z_from=lowest)
    # Nor a side seen as a stripe far under the lid: a wall spans half of that itself (the cans found on the
    # development seeds 0-19 and the real scenes: at least 25 mm); an upside-down bowl's rim, 5 mm of it,
    # under its foot 24 mm higher, is none (the real learn37 at two of its views and search seeds: 23 mm
    # from the stripe's top to the foot). A stripe up to where a side ends under its lid, its base hidden, is
    # the top of a side hidden below (fresh 8019 of "cluttered table": 12 mm under the lid, a can behind a cup
    # 13 mm lower, whose far wall 10 mm off the circle spoilt the bands below).
    stripe_top = _percentile(z[side], 99)
    span = stripe_top - base
    under_lid = top - stripe_top <= c.top_margin + 3 * sigma + 0.5 * s.band_height
    if span < 0.5 * seen and (base_seen or not under_lid):
        return None, (f"its side spans {1e3 * span:.0f} mm of height only (min {500 * seen:.0f} mm; a rim under "
                      f"a lid, no wall)"), claim(z_from=lowest)
    why, wall_seen = _open_top(pts[dist <= r + r_eps], cx, cy, r, r_eps, base, top, ctx)
    if not why:
        why, wall_seen = _handle(pts, cx, cy, dist, r, r_eps, base_z, top, ctx), True
    if why:
        return None, why, claim(z_from=lowest, hollow=True, keeps_space=wall_seen)
    why = _inside_cup(cx, cy, r, base_z, top, r_eps, ctx)
    if why:
        return None, why, None
    why = _under_claimed(cx, cy, r, top, r_eps, ctx)
    if why:
        return None, why, claim(z_from=lowest)
    # The arc and shape error stay the side's own: the tracker refits a can seen this narrowly by its lid.
    if arc < s.min_hidden_arc and not pinned:
        joint = _pinned_by_lid(pts, sxy, cx, cy, r, top, sigma, r_eps, max_rms, ctx)
        if joint is not None:
            cx, cy, r, rms = joint
            dist, pinned = np.hypot(x - cx, y - cy), True
    # A narrow side no lid pins may not fix its radius (fresh 5028 of "cluttered table": a can of r 32
    # mm seen over 0.64 rad, fitted r 53 +- 12 mm, 21 mm off; the cans found on the development seeds:
    # at most 3.2 mm).
    radius_error = 0.0 if pinned else g.radius_standard_error(sxy, cx, cy, r)
    if radius_error > s.max_radius_error:
        return None, (f"the side, seen over {arc:.2f} rad, fixes its radius to {1e3 * radius_error:.1f} mm only "
                      f"(max {1e3 * s.max_radius_error:.1f} mm)"), None
    mine = free.idx[near[(dist <= r + r_eps) & (z >= lowest) & (z <= top + s.band_height)]]
    height = _covered_top(cx, cy, r, r_eps, top, sigma, ctx) - base_z
    can = Can(T_sensor_from_can=g.can_pose(ctx.T_sensor_from_plane, cx, cy, base_z), radius=r,
              height=height, rms_error=rms, arc_coverage=arc, n_points=len(mine), n_fit_points=n_side,
              center_plane=np.array([cx, cy]), shape_error=shape, indices=mine, support=support,
              base_seen=base_seen, support_height=float(base_z))
    return can, None, None


def _not_stray(points, r_eps, ctx):
    """Which of a side's points (float (N, 3), plane frame, m) have two others within max(2 r_eps, 3 grid
    spacings) (m): a side is a surface, each point has neighbours in its column at least; a pair of
    points apart from the rest is none (fresh 12545 of "cluttered table": two of a mug's wall 1.2 rad
    round a circle through the face of its handle, seen over 0.35 rad, gave it 1.79)."""
    spacing = 3 * ctx.ray_angle * float(np.linalg.norm(points.mean(axis=0) - ctx.sensor))
    # The two nearest other points only (k=3: itself first): counting all within reach costs a dense side more.
    nearest, _ = cKDTree(points).query(points, k=3, distance_upper_bound=max(2 * r_eps, spacing))
    return np.isfinite(nearest[:, 2])


def _no_cans_radius(free, side, cx, cy, r, r_eps, claim, ctx, split):
    """verify's answer to a side (float (N, 2+), m) whose circle (cx, cy, r) has no can's radius: the
    can of its own circle of the half of the side on a can (_own_circle_can, when split), else
    (None, why, the claim of a round object: _claim_round). A wide circle over a can and a box
    beside it (fresh 5342 of "can touching box": r 95 mm at the can's base) claimed the can."""
    c = ctx.config
    own = _own_circle_can(free, g.split_circles(side, cx, cy, r, c.min_fit_points), r, r_eps, ctx) if split else None
    if own is not None:
        return own, None, None
    return None, (f"radius {1e3 * r:.1f} mm outside [{1e3 * c.min_radius:.0f}, {1e3 * c.max_radius:.0f}] mm"
                  ), _claim_round(side, cx, cy, r, claim, c)


def _own_circle_can(free, halves, r, r_eps, ctx, better_than=np.inf):
    """The Can verified (once: not again from there) on the circle of its own of the half of a side
    (halves: geometry.split_circles' about the side's circle of radius r, m) that lies the most
    times closer to it, when at least inner_split times, and that circle is of a can's radius and
    more than r_eps smaller than the side's: the half on a can of a wider circle over it and an
    object beside or in front of it. None when not, or its rms is not below better_than (m)."""
    c = ctx.config
    if not halves:
        return None
    ratio, kx, ky, kr = max(halves)
    if ratio < ctx.search.inner_split or not c.min_radius <= kr < r - r_eps:
        return None
    can, _, _ = verify(free, kx, ky, kr, ctx, again=False, split=False)
    return can if can is not None and can.rms_error < better_than else None


def _offset_step(bands, residual, lo, hi, min_step, min_bands=2):
    """The part (first, last band) of the run lo..hi on one side of the largest step in the mean
    residual per band of the points near a circle (bands: theirs; residual: their distance from it
    less its radius, m), the side whose mean residual is nearer zero (the object the circle lies on),
    when that step exceeds min_step (m) with at least min_bands bands of points on each side; None:
    no such step."""
    keep = (bands >= lo) & (bands <= hi)
    count = np.bincount(bands[keep] - lo, minlength=hi - lo + 1)
    total = np.bincount(bands[keep] - lo, residual[keep], minlength=hi - lo + 1)
    n_below, sum_below, bands_below = np.cumsum(count), np.cumsum(total), np.cumsum(count > 0)
    best, split = min_step, None
    for k in range(1, len(count)):
        if bands_below[k - 1] < min_bands or bands_below[-1] - bands_below[k - 1] < min_bands:
            continue
        step = abs((sum_below[-1] - sum_below[k - 1]) / (n_below[-1] - n_below[k - 1])
                   - sum_below[k - 1] / n_below[k - 1])
        if step > best:
            best, split = step, k
    if split is None:
        return None
    mean_below = sum_below[split - 1] / n_below[split - 1]
    mean_above = (sum_below[-1] - sum_below[split - 1]) / (n_below[-1] - n_below[split - 1])
    return (lo, lo + split - 1) if abs(mean_below) <= abs(mean_above) else (lo + split, hi)


def _pinned_by_lid(pts, side_xy, cx, cy, r, top, sigma, r_eps, max_rms, ctx):
    """(cx, cy, r, rms) of a can whose side shows over a narrow arc only, its circle refitted to that
    side (side_xy: float (M, 2), m) and its lid's rim (RimCircle.with_side; the lid among pts, float
    (N, 3), at height top, as _lid_only takes it), or None to keep it: an arc under min_hidden_arc
    fixes the radius poorly (cans behind others 3-5 mm off their axis, "cans touching" 0 and 75). Only
    when the lid's rim passes _lid_only's tests on the new circle (seen over min_hidden_arc will do
    when rim and side together span min_arc) and the side lies on it within max_rms (m), and not by a
    box's top (_box_top, as _lid_at tells it); rms: the side's on it."""
    lid = _bare_lid(pts, top, sigma, ctx.search.band_height)
    # Far away a box's square top fits a circle within the noise (fresh 6140 of "boxes and prisms": a 4 x 4
    # cm top 1.26 m away, rms 2.8 mm, pinned a circle in its corner through its front face).
    if len(lid) < ctx.config.min_fit_points or _box_top(lid, r_eps, ctx):
        return None
    rim = g.rim_circle(lid, ctx.sensor[:2], r_eps)
    joint = None if rim is None else _rim_with_side(rim, side_xy, lid, sigma, r_eps, ctx, side_counts=True)
    if joint is None:
        return None
    residual = np.hypot(side_xy[:, 0] - joint.cx, side_xy[:, 1] - joint.cy) - joint.radius
    rms = float(np.sqrt(np.mean(residual ** 2)))
    return None if rms > max_rms else (joint.cx, joint.cy, joint.radius, rms)


def _side_and_rim(pts, side_xy, top, sigma, r_eps, ctx):
    """(cx, cy, r) (m) of the circle through a stripe of side (side_xy, float (M, 2)) and the rim of
    its lid that a taller object in front shadows (the lid among pts, float (N, 3), at height top, as
    _lid_only takes it; its outline less the samples beside the shadow: geometry.shadowed), or None.
    Only when the rim lies on it within r_eps (m) over at least min_hidden_arc, its radius is a can's
    and 95 % of the lid's points lie inside it; verify judges the side on it as on a fitted one."""
    c, s = ctx.config, ctx.search
    lid = _bare_lid(pts, top, sigma, s.band_height)
    if len(lid) < c.min_fit_points:
        return None
    outline = g.rim_outline(lid, ctx.sensor)
    if len(outline) < 3:
        return None
    taller = ctx.standing[ctx.standing[:, 2] > top + s.band_height]
    # Where a taller object in front shadows the lid, the outline is the shadow's edge, not the rim.
    edge = g.shadowed(outline, float(np.median(lid[:, 2])), taller, ctx.sensor, 0.006)
    # A lid no taller object shadows fixes its circle alone (_lid_only, _pinned_by_lid).
    rim = g.rim_circle(lid, ctx.sensor, r_eps, outline=outline[~edge]) if edge.any() else None
    if rim is None:
        return None
    # The side evenly subsampled to at most 4 points per outline point: the rim weighs in the fit.
    joint = rim.with_side(side_xy[::int(np.ceil(len(side_xy) / (4 * len(rim.outline))))], from_both=True)
    if (joint is None or not c.min_radius <= joint.radius <= c.max_radius or joint.arc() < s.min_hidden_arc
            or not _holds_lid(lid, joint.cx, joint.cy, joint.radius, r_eps, joint.spacing,
                              (c.min_radius, c.max_radius))):
        return None
    return joint.cx, joint.cy, joint.radius


def _inside_cup(cx, cy, r, z_lo, z_hi, r_eps, ctx):
    """Why the circle (cx, cy, r) over heights z_lo..z_hi (m, plane frame) is no can: it reaches more
    than r_eps into a hollow object claimed before that keeps its space (a cup or mug: its far inner
    wall or handle seen) over more than two bands of its height, where no can could stand (the mug's
    handle beside it, held-out seed 808 of "mug and bowl"); else "". Not into the other round
    objects claimed: a circle of no can's radius through a can's front and a box (held-out seed 909
    of "box hides base") is no object."""
    band = ctx.search.band_height
    for cup in (claim for claim in ctx.claimed if claim.keeps_space):
        apart = np.hypot(cx - cup.cx, cy - cup.cy)
        depth = r + cup.r - apart
        if depth <= r_eps:
            continue
        shared = min(z_hi, cup.z_hi) - max(z_lo, cup.z_lo) > 2 * band
        if not shared and apart >= r:
            # A cup whose centre is off the circle stands on no can there: its wall goes on down, unseen,
            # from the lowest point seen, which a can reaching a band higher meets.
            shared = min(z_hi - cup.z_lo, min(z_hi, cup.z_hi) - z_lo) > band
        if shared:
            return (f"reaches {1e3 * depth:.0f} mm into a cup or mug (r {1e3 * cup.r:.0f} mm): two objects do not "
                    "share space (its handle)")
    return ""


def _under_claimed(cx, cy, r, top, r_eps, ctx):
    """Why the circle (cx, cy, r) whose side ends at `top` (m, plane frame) is no can: a round object
    claimed before on the same circle (centre and radius within r_eps / 4, m) starts there (its
    lowest point within a band of top), and the wall goes on down under it: that object's lower part
    (fresh 6128 of "cluttered table": a mug claimed from 61 mm up where its inside showed, its wall
    below, beside a cup in front, 60 mm high: 0.3 mm and 0.4 mm off its circle); else "". A can under
    a cup is narrower than it (8 mm on "cup on can")."""
    for other in ctx.claimed:
        if (abs(r - other.r) <= 0.25 * r_eps and np.hypot(cx - other.cx, cy - other.cy) <= 0.25 * r_eps
                and abs(other.z_lo - top) <= ctx.search.band_height):
            return (f"the lower part of a round object claimed above it (r {1e3 * other.r:.0f} mm, from "
                    f"{1e3 * other.z_lo:.0f} mm up): its wall goes on down on the same circle")
    return ""


def _lid(xy, dist, z, r, r_eps, z_lo, z_hi, s, fitted=False):
    """The height of the lid (m) over the run of bands z_lo..z_hi (m) of a circle of radius r: the 99th
    percentile of the heights z of the points within the disc (xy: plane frame, dist: from the axis, m)
    up to 2 bands above the run. Taken on the disc's outer ring when it holds points: a narrower can
    standing on the lid rises inside it. Above the run, only points within the circle by r_eps / 2: a
    taller box or can touching the side lies just outside it, within r_eps, and made the lid its height
    (the lid was then "deep inside" the rim: a cup; "can touching box", development seeds 57 and 97);
    nor a surface reaching in over the circle from beyond it (_top_from_beside). fitted: the circle is
    the side's own fit (a hypothesis' circle may take in a box touching the can)."""
    lid = ((dist <= r + r_eps) & (z >= z_lo) & (z < z_hi + 2 * s.band_height)
           & ((z < z_hi) | (dist <= r - 0.5 * r_eps)))
    ring = lid & (dist >= 0.7 * r)
    # Something standing on the lid, higher than it can be (2 bands above the run) and inside the fitted
    # side, rises from the lid's inner part: the ring begins beyond it (fresh 4825 of "can on can": a can
    # of r 29 mm 4 mm off the axis of one of 44 mm reached 0.75 r out, and the lid came out 18 mm high).
    # Not inside a hypothesis' circle: a taller box touching the can may lie there (held-out 1500 of "can
    # touching box": 10 mm low). Standing: spanning 2 bands, not an open mug's far rim above a run cut
    # short (the real learn33 with a fifth of its pixels dropped: a can).
    if fitted:
        on_lid = (dist < r - r_eps) & (z >= z_hi + 2 * s.band_height)
        if (np.count_nonzero(on_lid) >= s.min_band_points
                and _percentile(z[on_lid], 95) - _percentile(z[on_lid], 5) >= 2 * s.band_height):
            ring &= dist >= _percentile(dist[on_lid], 95) + 0.5 * r_eps
    used = ring if np.count_nonzero(ring) >= s.min_band_points else lid
    top = _percentile(z[used], 99)
    inner = lid & (dist < 0.7 * r)

    def at(height):  # the points within half a band of a height (m)
        return np.abs(z - height) <= 0.5 * s.band_height

    at_top = at(top)
    if top >= z_hi and np.count_nonzero(inner & at_top) < s.min_band_points:
        # A top on the ring alone, joined to a surface beyond the circle, over a lid of its own across the
        # disc's inside, is a taller neighbour's reaching in over a circle fitted wide (fresh 14228 of
        # "cans touching": r 35 mm over a can of 29 took the top of the can behind it, 16 mm higher, and
        # its own lid lay "inside, below the rim": a cup). A cup's rim joins nothing beyond it.
        theirs = _top_from_beside(xy, dist, at_top, r, r_eps)
        own = used & ~theirs
        if theirs.any() and np.count_nonzero(own) >= s.min_band_points:
            lower = _percentile(z[own], 99)
            if lower < top - 0.5 * s.band_height and np.count_nonzero(inner & at(lower)) >= s.min_band_points:
                return lower
    return top


def _top_from_beside(xy, dist, at_top, r, r_eps):
    """bool over the points (xy, m, plane frame; dist from the axis, m): those of at_top (bool: at a
    top's height) on a surface joined to points beyond the circle (radius r, r_eps, m) at that height:
    another object's top reaching in over the circle, no lid of its own."""
    layer = at_top & (dist <= r + 3 * r_eps)
    beyond = layer & (dist > r + r_eps)
    theirs = np.zeros(len(dist), bool)
    if not beyond.any() or np.count_nonzero(layer) < 2:
        return theirs
    where = np.flatnonzero(layer)
    piece = _spaced_pieces(xy[where])
    theirs[where] = np.isin(piece, piece[beyond[where]])
    return theirs


def _claim_round(xy, cx, cy, r, claim, config):
    """claim(cx, cy, r) (the disc's points: verify's claim) when the side points xy (m, plane frame)
    are round about the circle (shape error within max_shape_error: a tin, a pot), else None. A
    circle of no can's radius through a box's corner, or through a box's face and a can beside it,
    would take the can's points with its disc. Its lid is taken too: a tin's lid left beside a lying
    can pulled the lying search's circles off it (fresh seed 2003 of "cluttered table")."""
    if g.shape_error(xy, cx, cy, r, config.shape_bins) > config.max_shape_error:
        return None
    return claim(cx, cy, r, with_lid=True)


def radius_taper(dist, z):
    """How the radius changes along the side: (change, height apart, n_low, n_up), or None with
    fewer than 3 points in a half.

    dist, z: distance from the axis and height of the side points (m). The side is split at its
    median height; change: the median distance of the upper half minus that of the lower half (m;
    > 0 wider at the top, a bowl or cup; < 0 narrower, an upside-down one); height apart: between
    the halves' median heights (m); n_low, n_up: points per half."""
    if len(z) < 6:
        return None
    mid = _percentile(z, 50)
    up, low = z > mid, z <= mid
    n_up, n_low = int(np.count_nonzero(up)), int(np.count_nonzero(low))
    if n_up < 3 or n_low < 3:
        return None
    return (_percentile(dist[up], 50) - _percentile(dist[low], 50), _percentile(z[up], 50) - _percentile(z[low], 50),
            n_low, n_up)


def _tapered(dist, z, sigma, ctx):
    """Why the side is no can's straight wall (a bowl, pot or cup), or "": its radius changes from the
    lower to the upper half by more than max_taper x their height apart (steeper than any can's wall)
    and by more than taper_sigmas standard errors of that change (not noise: the median of n points
    with depth noise sigma is off by about 1.25 sigma / sqrt(n))."""
    s = ctx.search
    taper = radius_taper(dist, z)
    if taper is None:
        return ""
    change, apart, n_low, n_up = taper
    noise = s.taper_sigmas * 1.25 * sigma * np.sqrt(1.0 / n_low + 1.0 / n_up)
    if abs(change) <= max(s.max_taper * apart, noise):
        return ""
    return (f"tapered: the radius changes by {1e3 * change:+.1f} mm over {1e3 * apart:.0f} mm of height (max "
            f"{s.max_taper:.2f} per metre of height and {1e3 * noise:.1f} mm noise; a bowl, pot or cup, not a can)")


def _robust_refit(xy, cx, cy, r, r_eps, ctx):
    """The least-squares circle (cx, cy, r) of the side points xy (plane frame, m) checked for
    another surface: (cx, cy, r, cutoff).

    A box face or a neighbour can touching the can lies within r_eps of its circle near the contact
    and pulls a least-squares fit by millimetres. Tukey's biweight from the least-squares circle
    finds such points as outliers (beyond robust_k x scale, which noise at that scale almost never
    reaches); with at least min_outliers of them the biweight fit replaces the least-squares one,
    started also from the middle half of the visible arc (away from the contacts at its ends, which
    a start biased toward the neighbour may never leave), keeping the start of least biweight
    loss. cutoff: the residual (m) beyond which a point is no side point (inf when the
    least-squares circle stands).

    A neighbour's points all within a few millimetres of the circle may leave no outliers: the
    least-squares circle bends through them instead (fresh 7929 of "cluttered table": a can of r 38 mm
    and a cup's wall curving away from its circle at one end, 5 to 16 mm off it, fitted r 52 mm, not
    round). A bent circle is no side's either: the biweight from the middle half of the arc replaces
    it when that one is round, however far it moved."""
    c, s = ctx.config, ctx.search
    fit = partial(g.fit_circle_robust, xy, r_eps=r_eps, k=s.robust_k, min_scale=s.robust_min_scale,
                  max_iterations=c.fit_iterations, tol=c.fit_tolerance)
    try:
        fits = [fit((cx, cy), r)]
    except PerceptionError:
        return cx, cy, r, np.inf

    def off(circle):  # each point's distance (m) from a circle (cx, cy, r, ...)
        return np.abs(np.hypot(xy[:, 0] - circle[0], xy[:, 1] - circle[1]) - circle[2])

    bent = False
    if np.count_nonzero(off(fits[0]) > s.robust_k * fits[0][3]) < s.min_outliers:
        bent = g.shape_error(xy, cx, cy, r, c.shape_bins) > c.max_shape_error
        if not bent:
            return cx, cy, r, np.inf  # nothing but noise: least squares is the better estimate
    on = np.flatnonzero(off((cx, cy, r)) <= r_eps)
    order = g.angular_order(np.arctan2(xy[on, 1] - cy, xy[on, 0] - cx))[0]
    middle = on[order[len(order) // 4: len(order) - len(order) // 4]]
    try:
        mx, my, mr = g.fit_circle_geometric(xy[middle], (cx, cy), r, r_eps, max_iterations=c.fit_iterations,
                                            tol=c.fit_tolerance, min_inliers=3, max_shift=r)
        fits.append(fit((mx, my), mr))
    except PerceptionError:
        pass
    if bent:
        # The middle half's circle alone, when round on its points within its cut-off.
        fits = [f for f in fits[1:]
                if g.shape_error(xy[off(f) <= s.robust_k * f[3]], *f[:3], c.shape_bins) <= c.max_shape_error]
    else:
        # A circle more than 2 r_eps from the least-squares one is no correction for a neighbour's points.
        fits = [f for f in fits if np.hypot(f[0] - cx, f[1] - cy) <= 2 * r_eps]
    if not fits:
        return cx, cy, r, np.inf
    cutoff = s.robust_k * min(f[3] for f in fits)
    fx, fy, fr, scale = min(fits, key=lambda f: g.biweight_loss(xy, f[0], f[1], f[2], cutoff))
    return fx, fy, fr, s.robust_k * scale


def _toward_sensor(cx, cy, ctx):
    """Unit horizontal vector from the axis toward the sensor (plane frame)."""
    v = ctx.sensor[:2] - (cx, cy)
    n = np.linalg.norm(v)
    return v / n if n > 1e-9 else np.array([0.0, -1.0])


def _support(points, cx, cy, r, base, r_eps, sigma, ctx):
    """(support, base_seen, base height, "") or (None, False, base, why not) when it floats (module
    docstring)."""
    c, s = ctx.config, ctx.search
    if base <= c.min_height + s.table_gap + 3 * sigma:
        return "table", True, 0.0, ""
    front = _toward_sensor(cx, cy, ctx)
    rel = points[:, :2] - (cx, cy)
    dist = np.hypot(rel[:, 0], rel[:, 1])
    ahead = rel @ front  # > 0 toward the sensor
    z = points[:, 2]
    # A surface at the base's height around the can, not only in front of it: it reaches under it.
    level = _at_base(z, base, sigma) & (dist > r + r_eps) & (dist <= r + s.support_reach)
    beside = level & (ahead < 0.5 * r)
    # Or something right under it, narrower than it (the can a wider cup stands on); not the can's own
    # side going on below the run, where an object in front hides most of it. Only r_eps / 2 inside the
    # circle too when most of the points under the base are (fresh 8712 of "cup on can": a can 8 mm narrower
    # set 4 mm toward the sensor, its near side 4 mm inside the cup's circle, 34-37 mm from its axis for 39.8).
    under_base = (dist <= r + r_eps) & (z >= base - 0.03) & (z <= base - 0.005)
    inside = np.count_nonzero(under_base & (dist < r - 0.5 * r_eps))
    narrower = np.count_nonzero(under_base & (dist < r - r_eps)) >= s.min_band_points \
        or (inside >= s.min_band_points and inside > 0.5 * np.count_nonzero(under_base))
    # The surface's top, when its points there form a layer that can hold the base (_top_layer). Beside
    # the can too, not only in front of it: a bowl's rim in front of a can whose base it hides, a
    # neighbour's side beside it (fresh 14438 of the cluttered table: put on the rim, 62 mm up, the can
    # was 35 mm high).
    held = _holds_layer(z[beside], base, sigma, s.min_band_points)
    layer = _top_layer(z[level], base, sigma) if held else None
    if layer is not None and _one_sided(rel[beside], front, s.min_band_points) \
            and _hidden_front(cx, cy, r, r_eps, layer + 3 * sigma, ctx):
        # Beside the can on one side only, where an object in front stands higher: a neighbour's top
        # touching it, whose base that object hides; a support reaches under the can from both sides, or
        # shows its front (fresh 14679 of the cluttered table: a tin's top 55 mm up on its right, a bowl's
        # rim 64 mm up in front; put on the tin, 104 mm high for 158).
        layer = None
    if layer is not None or narrower:
        base_z = base if layer is None else layer
        if not narrower and _side_goes_on_down(points, dist, cx, cy, r, base_z - 3 * sigma, r_eps, ctx):
            return "table", True, 0.0, ""
        below = "object"
        for other in ctx.found:
            top = other.support_height + other.height
            if (not other.lying and np.hypot(cx - other.center_plane[0], cy - other.center_plane[1]) < other.radius
                    and abs(top - base_z) < 0.02):
                below = "can"
        return below, True, base_z, ""
    # A can found before, right under it (its lid's points left with it): it stands on that can.
    for other in ctx.found:
        top = other.support_height + other.height
        if (not other.lying and np.hypot(cx - other.center_plane[0], cy - other.center_plane[1]) < other.radius
                and _at_base(top, base, sigma)):
            return "can", True, top, ""
    # A round object claimed before as no can right under it, its circle within that object's (a tin too
    # wide for a can, claimed with its lid: fresh 12448 of "can on tin", whose front stood as high as the
    # base), its lid's points around the can at the base's height: it stands on that lid.
    st = ctx.standing
    srel = st[:, :2] - (cx, cy)
    for other in ctx.claimed:
        if other.hollow or np.hypot(cx - other.cx, cy - other.cy) + r > other.r + r_eps:
            continue
        lid = ((np.hypot(st[:, 0] - other.cx, st[:, 1] - other.cy) <= other.r + r_eps)
               & (np.hypot(srel[:, 0], srel[:, 1]) > r + r_eps) & _at_base(st[:, 2], base, sigma))
        # Beside the can too, as a surface's layer must be (above): a bowl claimed on a circle too wide
        # holds a can behind its rim, whose points are all in front of it (fresh 14657 of the cluttered
        # table: put on the rim, 64 mm up, 50 mm high for 113).
        lid_beside = lid & (srel @ front < 0.5 * r)
        held_beside = _holds_layer(st[lid_beside, 2], base, sigma, s.min_band_points)
        lid_top = _top_layer(st[lid, 2], base, sigma) if held_beside else None
        if lid_top is not None:
            return "object", True, lid_top, ""
    # Something in front, as high as the lowest point seen: the base is hidden behind it.
    if _hidden_front(cx, cy, r, r_eps, base - 0.02, ctx):
        return "table", False, 0.0, ""
    # Its lowest side points on the image's edge: the view ends there, the side goes on below unseen.
    edge = ctx.image_edge
    cut = ((np.abs(np.hypot(edge[:, 0] - cx, edge[:, 1] - cy) - r) <= 2 * r_eps)
           & (edge[:, 2] <= base + s.band_height))
    if np.count_nonzero(cut) >= s.min_band_points:
        return "table", False, 0.0, ""
    if base <= c.min_height + c.max_base_gap:
        return "table", True, 0.0, ""
    return None, False, base, (f"its lowest side point is {100 * base:.1f} cm above the table with nothing "
                               "under it (floats)")


def _hidden_front(cx, cy, r, r_eps, height, ctx):
    """Whether an object stands in front of the can (cx, cy, r) up to `height` or higher (m, plane
    frame): min_band_points of the points standing on the table within occluder_reach of it toward the
    sensor, across its width. Beyond r_eps: its own front's noise is nothing in front of it (fresh 4630
    of "cup on can": a cup on a can stood on the table behind itself, and its claim took the can)."""
    s = ctx.search
    front = _toward_sensor(cx, cy, ctx)
    st = ctx.standing
    srel = st[:, :2] - (cx, cy)
    ahead = srel @ front
    lateral = np.abs(srel[:, 0] * front[1] - srel[:, 1] * front[0])
    return np.count_nonzero((ahead > r + r_eps) & (ahead < r + s.occluder_reach) & (lateral < r)
                            & (st[:, 2] >= height)) >= s.min_band_points


def _holds_layer(z, base, sigma, min_points):
    """Whether heights z (m) at a base's level (m) are at least min_points and hold a support's top
    layer (_top_layer; sigma: the depth noise there, m)."""
    return len(z) >= min_points and _top_layer(z, base, sigma) is not None


def _one_sided(rel, front, min_points):
    """Whether points (x, y relative to a can's axis, float (N, 2), m) lie on one side of it only, seen
    from the sensor (`front`: unit (x, y) toward it): fewer than min_points on the left or the right."""
    across = rel[:, 0] * front[1] - rel[:, 1] * front[0]
    return min(np.count_nonzero(across > 0), np.count_nonzero(across < 0)) < min_points


def _at_base(z, base, sigma):
    """Whether heights z (m; array or scalar) lie at a base's height (m): within _base_window."""
    lo, hi = _base_window(base, sigma)
    return (z >= lo) & (z <= hi)


def _base_window(base, sigma):
    """The heights (m) at a base's height (m): from 25 mm (and 3 sigma) under it, where a support's
    top may lie below the lowest side point seen, to 5 mm over it."""
    return base - 0.025 - 3 * sigma, base + 0.005


def _side_goes_on_down(points, dist, cx, cy, r, below, r_eps, ctx):
    """Whether the side of the circle (cx, cy, r) goes on down from under a level surface beside it
    (below: m, under its top and noise) to the table, curved, over a can's arc (points: float (N,
    3), plane frame, m; dist: their distances from its axis, m): then the surface is a neighbour's
    top, no support (a tin's rim beside a can: fresh 11848 of "cluttered table"). A box's face under a
    can crosses its circle straight; a low support's top, on the circle all round, lies above
    `below`."""
    c, s = ctx.config, ctx.search
    z = points[:, 2]
    under = (z < below) & (z >= c.min_height)
    on = under & (np.abs(dist - r) <= r_eps) & _facing(points[:, 0], points[:, 1], cx, cy, r, ctx)
    if np.count_nonzero(under & (dist < r - r_eps)) >= s.min_band_points or np.count_nonzero(on) < c.min_fit_points:
        return False
    # Every whole band under the surface, two at least, down to one within table_gap of the table.
    first, last = int((c.min_height + s.table_gap) / s.band_height), int(below / s.band_height) - 1
    counts = np.bincount((z[on] / s.band_height).astype(int), minlength=last + 1)
    if last - first < 1 or np.any(counts[first:last + 1] < s.min_band_points):
        return False
    xy = points[on, :2]
    return (g.arc_coverage(xy, cx, cy) >= 0.5 * c.min_arc
            and g.facet_ratio(xy, cx, cy, r) >= s.max_facet_ratio)


def _top_layer(z, base, sigma):
    """The height (m) of a support's top from the heights z (m) of the points at the level of a
    base (m, the lowest side point; _at_base): the median of those within 3 sigma (2 mm at least)
    under their 90th percentile, not of all (the support's side lower down would pull it down:
    "can on can" 6723). None when they hold no such layer: fewer than twice the points an even
    spread over the window puts there (a neighbour's side: fresh 13906, 13920 of "cluttered table"),
    or more than sigma above the base, another object's (fresh 6129); within sigma the lowest side
    point is as noisy (fresh 13909 of "can on can"). Docs: can_search.md, step 4."""
    high = _percentile(z, 90)
    width = max(3 * sigma, 0.002)
    layer = z >= high - width
    lo, hi = _base_window(base, sigma)
    even = len(z) * width / (hi - lo)  # the count an even spread over the window puts in the layer's width
    top = _percentile(z[layer], 50)
    return top if top <= base + sigma and np.count_nonzero(layer) >= 2 * even else None


def _covered_top(cx, cy, r, r_eps, top, sigma, ctx):
    """The height (m) of the top of a can whose lid is covered by a wider object standing on it (a cup):
    that object's base, as far above the highest point seen as its overhang can hide the side from the
    sensor; else `top`, the highest point seen. The object's base must be seen around the axis, and
    nothing may stand beside the can below its top (a taller can or box it touches)."""
    s = ctx.search
    st = ctx.standing
    rel = st[:, :2] - (cx, cy)
    dist = np.hypot(rel[:, 0], rel[:, 1])
    z = st[:, 2]
    ring = (dist > r + r_eps) & (dist <= r + s.support_reach) & (rel @ _toward_sensor(cx, cy, ctx) > 0)
    beside = ring & (z >= top - 2 * s.band_height) & (z < top - 3 * sigma)
    over = ring & (z >= top - 3 * sigma)
    if np.count_nonzero(over) < s.min_band_points or np.count_nonzero(beside) >= s.min_band_points:
        return top
    # Its lowest band's lowest points: a percentile of all of it would lie above its base.
    base = _percentile(z[over], 2)
    base = _percentile(z[over & (z <= base + s.band_height)], 5)
    # A ray from the sensor past an overhang reaching support_reach beyond the side hides the side
    # support_reach x tan(elevation) below the object's base, no more.
    tan_elevation = (ctx.sensor[2] - top) / max(np.hypot(*(ctx.sensor[:2] - (cx, cy))) - r, 1e-3)
    lowest = over & (z <= base + s.band_height)
    if (base > top + s.support_reach * tan_elevation + 3 * sigma or np.count_nonzero(lowest) < s.min_band_points
            or g.arc_coverage(st[lowest, :2], cx, cy) < ctx.config.min_arc):
        return top
    return max(top, base)


def _in_front(cx, cy, r, z_low, z_high, ctx):
    """Whether some object stands in front of the can (toward the sensor, within occluder_reach,
    less than 2 r to the side) as high as z_low..z_high: it may hide part of the can's side."""
    s = ctx.search
    front = _toward_sensor(cx, cy, ctx)
    rel = ctx.standing[:, :2] - (cx, cy)
    ahead = rel @ front
    lateral = np.abs(rel[:, 0] * front[1] - rel[:, 1] * front[0])
    z = ctx.standing[:, 2]
    return bool(((ahead > r) & (ahead < r + s.occluder_reach) & (lateral < 2 * r) & (z >= z_low)
                 & (z <= z_high)).sum() >= s.min_band_points)


def _rest_hidden(side_xy, cx, cy, r, r_eps, z_lo, z_hi, ctx, samples=13, limb=1.3, cone=0.01):
    """Whether every part of the near half of the side (cx, cy, r; heights z_lo..z_hi, m) that shows
    none of the side points side_xy has no depth, at the top and the bottom of the side: behind
    something closer to the sensor, unlit by the IR projector (geometry.without_depth) or beyond the
    image's edge; a can behind another, touching it, is seen only beside the front one's
    silhouette, over less than min_hidden_arc (0.55-0.93 rad on "cans touching", development seeds 0,
    5, 15, 23). Sampled at `samples` angles within `limb` (rad) of the direction to the sensor (the
    side near its limbs is seen at a grazing angle, often not at all); behind: a standing point
    outside the disc within `cone` (rad) of the sensor's (or projector's) ray to it and 1 cm nearer.
    Toward the limbs, where one column of the grid spans a wider arc than the samples' spacing, a
    sample is seen when a side point lies within that arc (geometry.sampled_arc)."""
    front = _toward_sensor(cx, cy, ctx)
    toward = np.arctan2(front[1], front[0])
    # Held-out 1800 of "cluttered table": a can seen between two objects in front over 0.82 rad, its
    # limb's last 10 degrees in one pixel column that the grid leaves out.
    grid_arc = g.sampled_arc(g.near_half_angles(toward, limb, samples), cx, cy, r, 0.5 * (z_lo + z_hi), ctx.sensor,
                             ctx.ray_angle)
    unseen = g.unseen_angles(np.arctan2(side_xy[:, 1] - cy, side_xy[:, 0] - cx), toward, limb, samples, grid_arc)
    if len(unseen) == 0:
        return True
    st = ctx.standing
    st = st[(st[:, 0] - cx) ** 2 + (st[:, 1] - cy) ** 2 > (r + r_eps) ** 2]
    outward = np.column_stack([np.cos(unseen), np.sin(unseen), np.zeros(len(unseen))])
    q = np.vstack([outward * (r, r, 0) + (cx, cy, z) for z in (z_lo, z_hi)])
    hidden = g.without_depth(q, np.vstack([outward, outward]), st, ctx.sensor, ctx.projector, cone)
    # Or out of view (fresh 6845 of "cluttered table": a can the image's bottom edge cuts, seen by its
    # lid and 0.51 rad of side).
    if ctx.beyond_image is not None and not hidden.all():
        hidden |= ctx.beyond_image(q)
    return bool(hidden.all())


def _open_top(points, cx, cy, r, r_eps, base, top, ctx):
    """Why it is a hollow cylinder open at the top (a cup, mug, bowl or pot), or "", and whether its
    far inner wall told it (bool): only points inside, deep or seen through, may be another object's
    inside a circle fitted too wide (fresh 7549 of "cluttered table": r 73 mm over a cup's side and a
    can behind it).

    Looked for among every point standing on the table near the axis, not only the cluster's: the
    inside of a cup is a depth step away from its rim, often a cluster of its own."""
    s = ctx.search
    st = ctx.standing
    near_axis = (np.abs(st[:, 0] - cx) < r + r_eps) & (np.abs(st[:, 1] - cy) < r + r_eps)
    points = np.concatenate([points, st[near_axis]])
    rel = points[:, :2] - (cx, cy)
    dist = np.hypot(rel[:, 0], rel[:, 1])
    z = points[:, 2]
    ahead = rel @ _toward_sensor(cx, cy, ctx)
    low = (z < top - s.open_depth) & (z > base)
    on = np.abs(dist - r) <= r_eps
    # Compared where both would show: the upper part. A cup's far inner wall shows down to where the
    # sight line over its near rim meets it, 2 r tan(elevation) below the rim: seen from low, a few cm
    # of inner wall against the near side's open_window made it look like noise (fresh seed 2200 of
    # "cup on can": 73 points against 990).
    rise, span = ctx.sensor[2] - top, float(np.hypot(*(ctx.sensor[:2] - (cx, cy))))
    window = min(s.open_window, 2 * r * rise / span) if rise > 0 and span > 0 else s.open_window
    upper = low & (z > top - window)
    near = int((on & upper & (ahead > 0.3 * r)).sum())
    # Anywhere within the disc, not only on the circle: a mug's inner wall lies its wall's thickness
    # inside, 8-12 mm on learn39's open mugs: beyond r_eps and short of "deep" (0.3 r inside). Not
    # beyond the circle: there a can touching it shows its side past a circle it pulled wide (fresh
    # held-out 3206 of "cluttered table").
    far = int(((dist <= r) & upper & (ahead < -0.3 * r)).sum())
    deep = int(((dist < 0.7 * r) & low).sum())
    limit = max(s.min_band_points, s.max_open_fraction * near)
    if far >= limit:
        return (f"open top: {far} points on the far inner wall below the rim (a hollow cylinder: cup, mug, "
                "bowl or pot)"), True
    if deep >= limit:
        return f"open top: {deep} points inside, below the rim (a cup, mug, bowl or pot)", False
    # Points a solid can would hide, seen through where it would stand: a cup's inner wall beyond a
    # circle its near wall's stripe pulled small (fresh 6735 of "cluttered table": r 29.9 mm for 35.9,
    # 48 points). Within r_eps of its side and open_depth of its top they may be its own.
    around = (np.abs(st[:, 0] - cx) < 2 * r) & (np.abs(st[:, 1] - cy) < 2 * r)
    through = int(g.seen_through(st[around], ctx.sensor, cx, cy, r - r_eps, base + r_eps, top - s.open_depth).sum())
    if through >= limit:
        return (f"open top: {through} points seen through where it would stand (a hollow cylinder: cup, mug, bowl "
                "or pot)"), False
    return "", False


def _handle(points, cx, cy, dist, r, r_eps, base, top, ctx):
    """Why it has a handle (a mug), or "": points just outside the circle within its height, some
    more than open_depth below the top, spanning 2 r_eps of height or more, on an arc narrower than
    max_handle_arc, none of them reaching down to the support or above the top (a box or can
    touching it stands on the table or is taller), nor ending, further out or lower, where
    something nearer the sensor hides where it would go on."""
    s = ctx.search
    # Whether it reaches further is judged on every point standing on the table around it too, not
    # only the cluster's free ones: a cup touching the can, rejected before it, took its points with
    # it ("cluttered table", development seed 14: its lower part hidden, it was the can's "handle").
    st = ctx.standing
    st = st[(np.abs(st[:, 0] - cx) <= r + 2 * s.handle_reach) & (np.abs(st[:, 1] - cy) <= r + 2 * s.handle_reach)]
    around = np.concatenate([points, st])
    own = np.arange(len(around)) < len(points)
    z, dist = around[:, 2], np.concatenate([dist, np.hypot(st[:, 0] - cx, st[:, 1] - cy)])
    out = (dist > r + 2 * r_eps) & (dist <= r + s.handle_reach)
    mid = own & out & (z > base + 0.01) & (z < top - 0.005)
    # A handle reaches further down than a lid's lip or a rim wider than the side (learn43's coffee
    # canister: its lid's lip 10-14 mm out, 8-14 mm below the top, was a "handle" at one grid offset).
    if mid.sum() < s.min_handle_points or np.count_nonzero(mid & (z < top - s.open_depth)) < s.min_handle_points:
        return ""
    # A handle is a loop up the side: seen from where its inside would be hidden, its points span its
    # height. Points at one height (within 2 r_eps) are a face: the top of a box or prism touching the
    # can, the rest of it hidden (fresh held-out "cluttered table" 3009: a prism's top, 12 points).
    if np.ptp(z[mid]) < 2 * r_eps:
        return ""
    angle = np.arctan2(around[:, 1] - cy, around[:, 0] - cx)
    order, arc = g.angular_order(angle[mid])
    if arc > s.max_handle_arc:
        return ""
    start = angle[mid][order[0]]
    span = _in_arc(angle, start, arc)
    beyond = (dist > r + s.handle_reach) & (dist <= r + 2 * s.handle_reach)
    if (out & span & ((z <= base + 0.01) | (z >= top + 0.005))).any() or (beyond & span).sum() >= s.min_handle_points:
        return ""  # it reaches the support, the top or further out: another object touching it
    # A box's face touching the can runs on beyond handle_reach, seen from above, at any angle to the
    # radius (outside the arc when it is nearly tangent); a handle ends there. So does a prism's top
    # beyond its edge seen beside the can, which may lie well within the reach, the rest of the edge
    # hidden (fresh 4605 of "cluttered table"): followed from point to point within 2 r_eps outside the
    # side.
    if beyond.any() and np.count_nonzero(_reached(around, mid, out | beyond, 2 * r_eps) & beyond) \
            >= s.min_handle_points:
        return ""
    outer = mid & (dist > r + s.handle_reach - 2 * r_eps)
    # Where its outer end lies behind something nearer the sensor (not the can, not itself), it may
    # go on: a cup touching the can, seen in the gap between it and a can in front ("cluttered
    # table", development seed 14), is no handle.
    if outer.any():
        tip = around[outer]
        radial = (tip[:, :2] - (cx, cy)) / dist[outer, None]
        tip[:, :2] += 0.01 * radial
        others = _neither_can_nor_handle(dist, angle, r, r_eps, start, arc, s.handle_reach)
        if np.mean(g.behind(tip, around[others], ctx.sensor)) > 0.5:
            return ""
    # So too where its lower end lies behind something nearer, which may stand well beyond the handle's
    # reach (any standing point but the can's and the handle's own): it may go on down to the support (a
    # cup 4 mm from the can, its front wall seen between the can and a taller one in front that hides the
    # rest of it: fresh 5445 of "cluttered table").
    foot = around[mid & (z <= z[mid].min() + 2 * r_eps)] - (0.0, 0.0, 0.01)
    standing = ctx.standing
    sx, sy = standing[:, 0] - cx, standing[:, 1] - cy
    others = _neither_can_nor_handle(np.hypot(sx, sy), np.arctan2(sy, sx), r, r_eps, start, arc, s.handle_reach)
    if np.mean(g.behind(foot, standing[others], ctx.sensor)) > 0.5:
        return ""
    return (f"handle: {int(mid.sum())} points stick out of the side over {arc:.2f} rad without reaching the "
            "support (a mug)")


def _neither_can_nor_handle(dist, angle, r, r_eps, start, arc, reach):
    """Which points, by their distance (m) from a can's axis and angle (rad) about it, may hide where a
    handle goes on: not the can's (within r + r_eps), nor the handle's own (within its arc of `arc`
    rad from `start`, out to r + reach + 2 r_eps, m)."""
    return (dist > r + r_eps) & ~(_in_arc(angle, start, arc) & (dist <= r + reach + 2 * r_eps))


def _in_arc(angle, start, arc):
    """Which angles (rad) lie on the arc of `arc` rad going counter-clockwise from `start` (rad)."""
    return (angle - start) % (2 * np.pi) <= arc + 1e-9


def _reached(points, start, allowed, step):
    """Which points (float (N, 2+), m) are reached from those of `start` (bool (N,)) going from point
    to point among the `allowed` ones (bool (N,)) no more than `step` (m) apart seen from above."""
    reached = start & allowed
    tree = cKDTree(points[allowed, :2])
    index = np.flatnonzero(allowed)
    frontier = points[reached, :2]
    while len(frontier):
        # Each frontier point finds itself at least: no empty list.
        hits = np.unique(np.concatenate(list(tree.query_ball_point(frontier, step))).astype(np.int64))
        new = index[hits[~reached[index[hits]]]]
        reached[new] = True
        frontier = points[new, :2]
    return reached


def _wall_sample(points, n, cell, rng):
    """Positions of up to n of the points (float64 (M, 3), plane frame, m), drawn with weights that
    favour walls: seen from above, a vertical side piles many points into one `cell` x `cell`
    square (m), a lid or a box's top only a layer. The hypotheses come from side points."""
    if len(points) <= n:
        return np.arange(len(points))
    cells = np.floor(points[:, :2] / cell).astype(np.int64)
    cells -= cells.min(axis=0)
    key = cells[:, 0] * (int(cells[:, 1].max()) + 1) + cells[:, 1]
    weight = np.bincount(key)[key].astype(float)
    return np.sort(rng.choice(len(points), size=n, replace=False, p=weight / weight.sum()))


def _duplicates(tight_a, tight_b, max_overlap):
    """(A, B) bool: circle a of tight_a and b of tight_b (bool (A, M), (B, M): which points lie within
    eps / 2 of each) share more than max_overlap of the smaller one's points: one seen twice."""
    a, b = tight_a.astype(np.int64), tight_b.astype(np.int64)
    shared = a @ b.T
    return shared > max_overlap * np.minimum(a.sum(axis=1)[:, None], b.sum(axis=1)[None, :])


def _suppressed_by(circles, others, xy, eps, sensor, max_overlap=0.5):
    """Which of the circles (cx, cy, r: (K,) each, m) best_circles takes out as duplicates of one of
    the others ((cx, cy, r) each) though centre or radius lies more than eps (m) from it."""
    if not others:
        return np.zeros(len(circles[0]), bool)
    ox, oy, o_r = (np.array(v) for v in zip(*others))
    tight = []
    for cx, cy, r in (circles, (ox, oy, o_r)):
        members, residual = circle_members(xy, cx, cy, r, eps, sensor)
        tight.append(members & (np.abs(residual) <= 0.5 * eps))
    cx, cy, r = (v[:, None] for v in circles)
    like = (np.hypot(cx - ox, cy - oy) <= eps) & (np.abs(r - o_r) <= eps)
    # Not one like a circle tried already, though it shares another tried one's points (held-out 1301).
    return _duplicates(tight[0], tight[1], max_overlap).any(axis=1) & ~like.any(axis=1)


def _draws(xy, z_pool, face, tried, tried_circles, r_eps, ctx):
    """A round's circle hypotheses, drawn in turn as the search asks for them: (cx, cy, r, z0, and
    the pool points (x, y) and heights they are scored on). Drawn from and scored on the pool points
    xy, z_pool (m, plane frame) not on a flat face: a box's face beside a thin can outscored its
    circles with a wider one through both (held-out 1708 "can touching box"), or carried a circle
    tangent to it through the box's corner past those of the can touching its end (fresh 6019).
    First from all of them; then up to `retries` draws from those the circles tried (`tried`, a
    bool mask updated in place by the caller) did not explain, a big box's faces crowding out a small
    can's triplets, skipped when fewer than 3 are left; last, the first draw's circles that one tried
    (`tried_circles`, (cx, cy, r) each) took out of the first choice as sharing its points though
    elsewhere (_suppressed_by: a circle through a can's front and a tall box's edge verified first and
    failed, its points the can's own circles'; held-out 606 "can touching box")."""
    c, s = ctx.config, ctx.search
    first = None
    for attempt in range(1 + s.retries):
        scored = ~tried & ~face
        if attempt and np.count_nonzero(scored) < 3:
            continue
        axy, az = xy[scored], z_pool[scored]
        circles = circle_hypotheses(axy, az, s.hypotheses, ctx.rng, c.min_radius, c.max_radius + r_eps,
                                    s.hypothesis_slice)
        first = circles if first is None else first
        yield (*circles, axy, az)
    keep = _suppressed_by(first[:3], tried_circles, xy, r_eps, ctx.sensor)
    yield (*(a[keep] for a in first), xy[~face], z_pool[~face])


def search_cluster(points, ctx, claimed_elsewhere=()):
    """Every can in one cluster: (list of Can with indices into `points`, list of Rejection).

    points: float64 (M, 3), plane frame (m); claimed_elsewhere: the round objects (_Claim) claimed as
    no can in other clusters."""
    c, s = ctx.config, ctx.search
    # Height bands, once per cluster (points above max_height share the last band).
    bands = np.minimum((points[:, 2] / s.band_height).astype(np.int64), int(c.max_height / s.band_height))
    free = np.ones(len(points), bool)
    cans, rejections, last = [], [], None
    # A round object claimed in another cluster may go on in this one (a cup touching a can, split
    # between the can's cluster and its own: fresh 13116 of "cluttered table"); its points there
    # crowd the can's side beside it and bend its circle ("not round").
    elsewhere = _on_claimed(points, ctx, claimed_elsewhere)
    if np.count_nonzero(elsewhere) >= c.min_fit_points:
        free &= ~elsewhere
        rejections.append(Rejection(centroid=points[elsewhere].mean(axis=0), n_points=int(np.count_nonzero(elsewhere)),
                                    reason="part of a round object that is no can, claimed in another cluster"))
    # Lying cans first: an upright hypothesis through a lying can and what touches it could take its
    # points as a round object that is no can, or make a box's corner beside it look round.
    lying_cans, lying_why = _lying(points, np.arange(len(points)), ctx) if len(points) >= c.min_fit_points else ([], "")
    for can in lying_cans:
        cans.append(can)
        ctx.found.append(can)
        free[can.indices] = False
    last = _rounds(points, bands, free, cans, rejections, ctx)
    if len(cans) > len(lying_cans) or (rejections and not lying_cans):
        # Upright cans found: the lying cans are looked for again without them. A lying can beside one
        # may stand out only now, and one found before may have taken a neighbour's side at its end for
        # its end's disc (too long). So too when no lying can was found and the rounds claimed round
        # objects that are no can (the rejections so far): beside a big one (a tin of r 99 mm) a lying can
        # has too few of the lying search's subsampled points for its circles to outrank the tin's (fresh
        # seed 2003 of "cluttered table").
        for can in lying_cans:
            free[can.indices] = True
        # Nor the points just around an upright can that its own points leave (its side's noise, the
        # points a sensor interpolates between it and a lying can's end).
        near_upright = np.zeros(len(points), bool)
        for can in (c for c in cans if not c.lying):
            cx, cy = can.center_plane
            reach = can.radius + 2 * c.r_eps_at(_sigma(ctx, (cx, cy, 0.5 * can.height)))
            near_upright |= ((points[:, 0] - cx) ** 2 + (points[:, 1] - cy) ** 2 <= reach * reach) \
                & (points[:, 2] <= can.support_height + can.height + s.band_height)
        lying_points = np.flatnonzero(free & ~near_upright)
        again, why = _lying(points, lying_points, ctx) if len(lying_points) >= c.min_fit_points else ([], lying_why)
        if len(again) >= len(lying_cans):
            for can in lying_cans:
                cans.remove(can)
                ctx.found.remove(can)
            lying_cans, lying_why = again, why
            cans.extend(again)
            ctx.found.extend(again)
        for can in lying_cans:
            free[can.indices] = False
    rest = np.flatnonzero(free)
    # What is left may be a can seen by its lid alone, its side hidden behind what stands in front; or a
    # cup whose rim tells it (hollow), standing on a can that the rounds took together with it ("cup
    # on can", fresh 5047: a cup 8 mm wider at 1.2 m, noise 2 mm): claimed, and the rounds search again.
    for _ in range(int(s.max_rounds)):
        if len(rest) < c.min_fit_points:
            break
        not_cans = np.ones(len(points), bool)
        for found in cans:
            not_cans[found.indices] = False
        can, reason, claim = _lid_only(_Free(points, bands, rest, seen=points[not_cans]), ctx)
        if can is not None:
            cans.append(can)
            ctx.found.append(can)
            free[can.indices] = False
        elif claim is None:
            break
        else:
            _take_claim(points, claim, reason, None, free, cans, rejections, ctx)
        last = _rounds(points, bands, free, cans, rejections, ctx) or last
        rest = np.flatnonzero(free)
    if len(rest) >= c.min_fit_points or not (cans or rejections):
        reason, radius = last or ("nothing round left", None)
        reason = f"{reason}; {lying_why}" if lying_why else reason
        rejections.append(Rejection(centroid=points[rest].mean(axis=0) if len(rest) else points.mean(axis=0),
                                    n_points=len(rest), reason=reason, radius=radius))
    return cans, rejections


def _on_claimed(points, ctx, claimed):
    """Which of a cluster's points (float64 (M, 3), plane frame, m) lie in the disc of one of the round
    objects claimed as no can (_Claim; r_eps about its circle), from a band under its lowest point
    claimed to its highest. Only those of a can's radius: a circle of r 234 mm claimed over a box's
    faces ("radius outside") took a can 83 mm from its centre (development 6 of the cluttered table)."""
    c, s = ctx.config, ctx.search
    on = np.zeros(len(points), bool)
    for other in (o for o in claimed if c.min_radius <= o.r <= c.max_radius):
        r_eps = c.r_eps_at(_sigma(ctx, (other.cx, other.cy, other.z_hi)))
        on |= ((np.hypot(points[:, 0] - other.cx, points[:, 1] - other.cy) <= other.r + r_eps)
               & (points[:, 2] >= other.z_lo - s.band_height) & (points[:, 2] <= other.z_hi))
    return on


def _rounds(points, bands, free, cans, rejections, ctx):
    """The rounds of search_cluster: circle hypotheses drawn from the free points (bool over the
    cluster's points, updated in place), verified in turn; each can found or round object claimed
    takes its points and starts a new round. Appends to cans and rejections; returns (reason, radius)
    of the first hypothesis that failed, or None."""
    c, s = ctx.config, ctx.search
    last = None
    for _ in range(int(s.max_rounds)):
        idx = np.flatnonzero(free)
        if len(idx) < c.min_fit_points:
            break
        this_round = _Free(points, bands, idx)
        progress = False
        for xy, z_pool, face, r_eps in _pools(this_round, ctx):
            progress, failed = _verify_draws(points, this_round, xy, z_pool, face, r_eps, free, cans, rejections, ctx)
            last = last or failed
            if progress:
                break
        if not progress:
            break
    return last


def _pools(this_round, ctx):
    """The pools a round draws its circle hypotheses from, in turn while none yields a can or a claim:
    (x, y and heights of the pool points, m, plane frame; which lie on a flat face; r_eps, m). First
    one drawn with weights that favour walls; then, when a big box's faces took most of it (fewer
    than min_off_faces off them), one drawn off those faces: a can touching the box may have kept too
    few points in the first for a triplet (fresh 12718 of "can touching box": 5 of 200). Only when the
    first failed: drawn instead of it, the redraw lost a can whose front lies in line with the box's
    face (fresh 13043)."""
    c, s = ctx.config, ctx.search
    pool = _wall_sample(this_round.points, s.pool_points, s.wall_cell, ctx.rng)
    r_eps = c.r_eps_at(_sigma(ctx, this_round.points[pool].mean(axis=0)))
    radii = (c.min_radius, c.max_radius)
    # No triplet from a box's or prism's flat faces: circles through their corners outscored a small
    # can beside a big box and took the round's verifications.
    xy = this_round.points[pool, :2]
    face, runs = g.flat_faces(xy, 0.5 * r_eps, s.face_span, s.face_points, ctx.rng, radii=radii, lines=True)
    yield xy, this_round.z[pool], face, r_eps
    if np.count_nonzero(~face) >= s.min_off_faces * len(pool):
        return
    off = np.flatnonzero(~g.on_faces(this_round.points[:, :2], runs, 0.5 * r_eps))
    if len(off) < c.min_fit_points:
        return
    pool = off[_wall_sample(this_round.points[off], s.pool_points, s.wall_cell, ctx.rng)]
    xy = this_round.points[pool, :2]
    yield xy, this_round.z[pool], g.flat_faces(xy, 0.5 * r_eps, s.face_span, s.face_points, ctx.rng, radii=radii), r_eps


def _verify_draws(points, this_round, xy, z_pool, face, r_eps, free, cans, rejections, ctx):
    """One pool's circle hypotheses (_draws) verified in turn until one yields a can or a claimed
    round object (appended to cans or rejections, its points taken from free). Returns (whether one
    did, (reason, radius) of the first that failed or None)."""
    c, s = ctx.config, ctx.search
    tried, tried_circles, failed = np.zeros(len(xy), bool), [], None
    for attempt, (cx, cy, r, z0, axy, az) in enumerate(_draws(xy, z_pool, face, tried, tried_circles, r_eps, ctx)):
        best = best_circles(axy, cx, cy, r, r_eps, s.verify if attempt == 0 else s.retry_verify,
                            sensor=ctx.sensor, z=az, lid=s.band_height)
        if not best:
            if attempt == 0:
                return False, ("no circle of a can's radius through its points", None)
            continue
        # A circle through a lid or a box's top has its points at one height: no side, not verified.
        candidates = [(cx[k], cy[k], r[k], z0[k]) for k in best
                      if np.ptp(az[np.abs(np.hypot(axy[:, 0] - cx[k], axy[:, 1] - cy[k]) - r[k]) <= r_eps])
                      >= 0.5 * c.min_can_height]
        for cx0, cy0, r0, h0 in candidates:
            can, reason, claim = verify(this_round, cx0, cy0, r0, ctx, h0)
            if can is not None:
                cans.append(can)
                ctx.found.append(can)
                free[can.indices] = False
                return True, failed
            if claim is not None and len(claim):
                # A round object that is no can (a tin, a cup): named, and not tried again.
                _take_claim(points, claim, reason, r0, free, cans, rejections, ctx)
                return True, failed
            failed = failed or (reason, r0)
            tried |= np.abs(np.hypot(xy[:, 0] - cx0, xy[:, 1] - cy0) - r0) <= r_eps
            tried_circles.append((cx0, cy0, r0))
    return False, failed


def _take_claim(points, claim, reason, radius, free, cans, rejections, ctx):
    """A round object claimed as no can (claim: indices into the cluster's points): named in the
    rejections with its reason and hypothesis radius (m, or None), its points taken from free, and
    the cans found before it that reach into it withdrawn (_withdraw_inside_cup)."""
    rejections.append(Rejection(centroid=points[claim].mean(axis=0), n_points=len(claim), reason=reason,
                                radius=radius))
    free[claim] = False
    _withdraw_inside_cup(cans, free, ctx)


def _withdraw_inside_cup(cans, free, ctx):
    """After a claim: the upright cans found in this cluster (cans, updated in place) whose circle
    reaches into a cup or mug claimed since (_inside_cup) are withdrawn, their points made free
    again (bool over the cluster's points) for the rounds after. Verified before the cup, whose
    handle bent its side ("not round" first), such a circle was its handle (fresh 13518 of
    "cluttered table": r 19 mm about a mug's handle and part of its wall, 8 mm into the mug), or a
    can's circle bent wide by what touches it (fresh 13822: r 54 mm for 40, 15 mm off)."""
    for can in [can for can in cans if not can.lying]:
        cx, cy = can.center_plane
        r_eps = ctx.config.r_eps_at(_sigma(ctx, (cx, cy, can.support_height + 0.5 * can.height)))
        if _inside_cup(cx, cy, can.radius, can.support_height, can.support_height + can.height, r_eps, ctx):
            cans.remove(can)
            ctx.found.remove(can)
            free[can.indices] = True


def _lid_only(free, ctx):
    """A can seen by its lid alone: its side hidden behind an object in front, only its lid and a
    little of its side under it show ("cans touching", "cluttered table": a can behind a taller one).
    (Can with indices into the cluster's points, "", None); (None, why, claim) when a rim's side told a
    cup (_rim_verdict: claim, the indices of its points into the cluster's); else (None, "", None).
    free: the cluster's points no can took (_Free).

    The lid: the points within max(5 mm, 3 sigma) of the height of the fullest band at least
    min_can_height up, without those under a point more than a band higher (a wall's), or each of
    its pieces apart from the others (_lid_pieces) when it is no can's whole; the next fullest bands
    (up to lid_levels, not next to one tried) when that is no can's. The circle of its rim
    (geometry.rim_circle, from its outline on the half away from the sensor): a can's radius, round
    (facet_ratio), rms within max(2 mm, 2 sigma), over at least lid_arc (or less, pinned by the
    stripe of side under it, _side_stripe, unless that lies flat: a box's face, flat_ratio; else
    over min_arc with something higher in front: _lid_rim's shaded), holding 95 % of the lid's
    points; no can found there (overlapping one by more than r_eps). Then its side: seen mostly (or
    over min_fit_points) lower than min_can_height under the lid, over at least min_fit_points,
    judged on the rim's circle as the rounds judge one (verify, rim=True; fewer than min_fit_points
    that low are too few to judge); else hidden: the points near the circle on its near half within
    min_can_height under the lid, and every part of that half that shows none of them behind
    something nearer the sensor below that (_rest_hidden), and no open top."""
    c, s = ctx.config, ctx.search
    pts, z = free.points, free.z
    high = z >= c.min_can_height
    if np.count_nonzero(high) < c.min_fit_points:
        return None, "", None
    band = np.floor(z / s.band_height).astype(np.int64)
    sigma = _sigma(ctx, pts[high].mean(axis=0))
    r_eps = c.r_eps_at(sigma)
    counts = np.bincount(band[high])
    tried, tops, boxes = [], 0, np.zeros(len(z), bool)
    # A can beside a box lower than it (held-out 1909 of "can touching box", seen steeply from above)
    # has fewer points at its lid's height than the box at its top's. A box's top tried (up to
    # lid_levels of them) is no lid tried: its points leave the lids looked for next, and the band next
    # to it is tried too (fresh 5329 of "cluttered table": a can's lid at 93 mm beside a box's top at
    # 100 and another at 197, fuller).
    for level in np.argsort(-counts, kind="stable"):
        if (len(tried) == s.lid_levels or tops == s.lid_levels
                or ((tried or tops) and counts[level] < c.min_fit_points)):
            break
        if any(abs(int(level) - t) <= 1 for t in tried):
            continue
        can, reason, claim, top = _lid_at(free, band, int(level), sigma, r_eps, ctx, boxes)
        if can is not None or claim is not None:
            return can, reason, claim
        if top is None:
            tried.append(int(level))
        else:
            boxes |= top
            tops += 1
    return None, "", None


def _lid_at(free, band, level, sigma, r_eps, ctx, boxes):
    """_lid_only at the band `level` (band: each free point's, bands of band_height up from the
    table): (Can, "", None, None), (None, why, claim: the indices of a cup's points its rim's side
    told, _rim_verdict, None), (None, "", None, top: bool over the free points, a box's top's: a lid
    wider than a can or filling its rectangle) or (None, "", None, None). sigma, r_eps (m): the depth
    noise and the circle's tolerance there. boxes: bool over the free points, those of the boxes'
    tops seen before (left out of the lid)."""
    c, s = ctx.config, ctx.search
    pts, z = free.points, free.z
    rest = ~boxes
    at_level = (np.abs(band - level) <= 1) & rest
    if not at_level.any():
        return None, "", None, None
    z_lid = float(np.median(z[at_level]))
    lid = _bare_lid(pts[rest], z_lid, sigma, s.band_height)
    above = boxes & (z > z_lid)
    if above.any() and len(lid):
        # Under the edge of a box's top lie its faces, not a lid.
        lid = lid[cKDTree(pts[above, :2]).query_ball_point(lid[:, :2], 0.005, return_length=True) == 0]
    if len(lid) < c.min_fit_points:
        return None, "", None, None
    if _box_top(lid, r_eps, ctx):
        # A can's lid apart from a box's top as high is no part of it (fresh 11019 of "cluttered table":
        # a lid at 146 mm, its side hidden by a taller can in front, and a box's top at 148 21 cm away).
        # Only a lid wider than a can that does not fill its rectangle holds both (a box's top alone fills
        # it: no pieces looked for).
        if (_wider_than_a_can(lid, r_eps, ctx)
                and g.rectangularity(lid[:, :2]) <= ctx.search.max_lid_rectangularity):
            can, reason, claim = _pieces_judged(free, z_lid, lid, sigma, r_eps, ctx)
            if can is not None or claim is not None:
                return can, reason, claim, None
        # The top's own height, within 3 sigma: a can's lid a few millimetres off it, touching the box,
        # is no part of it (fresh 5035 of "can touching box": a lid at 128 mm beside a top at 132).
        z_top = float(np.median(lid[:, 2]))
        return None, "", None, rest & (np.abs(z - z_top) <= max(3 * sigma, 0.002))
    can, reason, claim = _lid_judged(free, z_lid, lid, sigma, r_eps, ctx)
    if can is None and claim is None:
        # Tops at one height apart from each other are no one rim's (fresh 9210 of "cluttered table": a
        # can's lid at 126 mm, its side hidden by a box in front, and a prism's top as high 1 cm from it,
        # one outline).
        can, reason, claim = _pieces_judged(free, z_lid, lid, sigma, r_eps, ctx)
    return can, reason, claim, None


def _pieces_judged(free, z_lid, lid, sigma, r_eps, ctx):
    """_lid_judged on each piece of a lid's points apart from the others (_lid_pieces) that is no
    box's top, largest first, until one is a can or a cup: (Can, "", None), (None, why, claim) or
    (None, "", None). Arguments as _lid_judged's."""
    for piece in _lid_pieces(lid, ctx.config.min_fit_points):
        if not _box_top(piece, r_eps, ctx):
            can, reason, claim = _lid_judged(free, z_lid, piece, sigma, r_eps, ctx)
            if can is not None or claim is not None:
                return can, reason, claim
    return None, "", None


def _lid_pieces(lid, min_points):
    """The pieces of a lid's points (float (N, 3), plane frame, m) apart from each other (_pieces), of at
    least min_points each, largest first; none unless two are: a lid less a few stray points is the
    same lid (fresh 6013 of "cluttered table": 109 of a lying can's top's 113 points, its rim judged
    again, passed as a lid of r 15 mm)."""
    if len(lid) < 2 * min_points:
        return []
    label = _spaced_pieces(lid[:, :2])
    counts = np.bincount(label)
    pieces = [lid[label == k] for k in np.argsort(-counts, kind="stable") if counts[k] >= min_points]
    return pieces if len(pieces) >= 2 else []


def _spaced_pieces(xy):
    """Each point's piece (int (N,), 0 up) of points xy (float (N, 2), m, N >= 2) joined by chains of
    points each within twice their median nearest-neighbour spacing of the next."""
    tree = cKDTree(xy)
    nearest, _ = tree.query(xy, k=2)
    return _pieces(tree, 2 * float(np.median(nearest[:, 1])))


def _pieces(tree, link):
    """Each point's piece (int (N,), 0 up): the points of a cKDTree (plane frame, m) joined by chains of
    points each within `link` (m) of the next."""
    pairs = tree.query_pairs(link, output_type="ndarray")
    n = tree.n
    return connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
                                directed=False)[1]


def _box_top(lid, r_eps, ctx):
    """Whether a lid's points (float (N, 3), plane frame, m) are no can's: wider than a can seen from
    above (a tin's, a box's top), or filling their smallest rectangle as a box's top does (a lid, even
    cut short by a straight shadow, fills less: fresh 5048 of "cluttered table", a 46 x 42 mm box's top
    behind a taller mug, its rim rms 2.9 mm at 1.2 m, 0.94; the 10 lids alone on "cans touching" and
    "cluttered table" 0-99: 0.79-0.84). r_eps (m): the circle's tolerance there."""
    return _wider_than_a_can(lid, r_eps, ctx) or g.rectangularity(lid[:, :2]) > ctx.search.max_lid_rectangularity


def _wider_than_a_can(points, r_eps, ctx):
    """Whether points (float (N, 3), plane frame, m) spread wider than a can seen from above (max_radius
    and r_eps, m, either side) along x or y."""
    return bool(np.any(np.ptp(points[:, :2], axis=0) > 2 * (ctx.config.max_radius + r_eps)))


def _lid_judged(free, z_lid, lid, sigma, r_eps, ctx):
    """_lid_at's judgement of a lid (lid: its points, float (N, 3), plane frame, at the height z_lid,
    m): (Can, "", None), (None, why, claim: a cup's points, _rim_verdict) or (None, "", None)."""
    c, s = ctx.config, ctx.search
    pts, z = free.points, free.z
    rim = g.rim_circle(lid, ctx.sensor[:2], r_eps)
    if rim is None or len(rim.outline) < c.shape_bins:
        return None, "", None
    judged = _rim_judged(rim, pts, z_lid, lid, sigma, r_eps, ctx)
    if judged is None:
        # A lid the can in front cuts short to a noisy crescent may fit a circle too wide that overlaps
        # that can (fresh 14009 of "cans touching": r 40 mm for 35, 60 points at 1.2 m, rms 2.9 mm,
        # 7 mm into it): judged again on the circle touching it, as _clear_of_found refits one that passed.
        moved = _clear_of_found(rim, lid, r_eps, ctx)
        judged = None if moved is rim else _rim_judged(moved, pts, z_lid, lid, sigma, r_eps, ctx)
        if judged is None:
            return None, "", None
    rim, whole, by_side = judged
    rim = _clear_of_found(rim, lid, r_eps, ctx)
    cx, cy, r, far = rim.cx, rim.cy, rim.radius, rim.outline
    if _top_of_claimed(cx, cy, r, z_lid, r_eps, ctx):
        return None, "", None
    dist = np.hypot(pts[:, 0] - cx, pts[:, 1] - cy)
    facing = _facing(pts[:, 0], pts[:, 1], cx, cy, r, ctx)
    side = (np.abs(dist - r) <= r_eps) & (z < z_lid - s.band_height) & facing
    # Its side seen mostly within min_can_height under the lid, hidden below. A can seen steeply from
    # above behind a lower object shows a little of its side below that (4 of 18 points, held-out seed
    # 1002 of "cluttered table"). Seen lower, the side is judged as the rounds judge one, on the rim's
    # circle: a can between others shows a narrow stripe of it, too narrow to fit a circle to (held-out
    # 1400 of "cluttered table"); a 4 x 4 cm box's top shows its faces, no can's side ("boxes and
    # prisms", development seeds 413, 417: 70 % of the points near the circle lower).
    hidden_below = z_lid - c.min_can_height
    n_side, n_low = np.count_nonzero(side), np.count_nonzero(z[side] < hidden_below)
    # Fewer than min_fit_points are too few for verify to judge as a side: hidden (fresh held-out 3202
    # and 3208 of "cans touching", a can behind another, touching it). As many lower are a side seen,
    # however many more are near the lid (fresh 4111 of "cluttered table": a 4.5 cm box's faces, 43 of
    # 94 lower, seen down to 16 mm over the table, were taken for a hidden can's).
    if ((n_low > max(s.min_band_points, 0.5 * n_side) or n_low >= c.min_fit_points)
            and n_side >= c.min_fit_points):
        can, reason, claim = _rim_verdict(free, cx, cy, r, ctx)
        if can is not None or claim is not None:
            return can, reason, claim
        # A lid cut short by the can in front fixes its circle to a few millimetres only, and the
        # stripe of side seen beside that can lies off it (held-out 1507 of "cluttered table": 5 mm
        # outside): the circle refitted to both, if its lid's rim still fits it.
        under = (np.abs(dist - r) <= 2 * r_eps) & (z < hidden_below) & facing
        n_under = np.count_nonzero(under)
        refit = n_under >= c.min_fit_points
        joint = _rim_with_side(rim, pts[under], lid, sigma, r_eps, ctx) if refit else None
        # Too few on the circle to judge a side by, and most of the points near it under the lid: hidden
        # (fresh 6713 of "cans touching": a can behind a wider one, touching it, its lid whole, 27 of its
        # 44). Too few of those: another surface is seen where the side would be (fresh 7506 of "boxes
        # and prisms": a tall box's face tangent to the circle of its top's "rim", none of its 262).
        own_on = reason.n_points if isinstance(reason, _TooFew) else None  # on the rim's own circle
        too_few = own_on is not None and own_on >= 0.5 * n_under
        if refit and joint is None and not too_few:
            # No such circle: no can, unless too few to judge, hidden then, as below.
            return None, "", None
        if joint is not None:
            can, reason, claim = _rim_verdict(free, joint.cx, joint.cy, joint.radius, ctx)
            # Fewer than min_fit_points of them on its circle over the run of bands the side shows: too
            # few to judge a side by, hidden as below (fresh 5731 of "cans touching": a can behind a wider
            # one 8 mm lower, 25 of its points on the circle).
            if can is not None or claim is not None:
                return can, reason, claim
            # A rim seen whole (over lid_arc) fixes its circle: with a stripe of side on it too narrow to
            # judge by (min_band_points or more), a refit pulled off it by another object's points under it
            # fails and it is judged hidden as below (fresh 9402 of "cluttered table": a can 4.5 mm behind a
            # cup whose rim stands 3 mm above its lid; 11 points on the rim's circle, the refit 6 mm toward
            # the cup, rms 3.17 mm). None on it is another surface where the side would be (fresh 9705 of
            # "boxes and prisms": a 4 x 4 cm box's face tangent to the circle inscribed in its top).
            own_stripe = own_on is not None and own_on >= s.min_band_points
            if not isinstance(reason, _TooFew) and not (whole and own_stripe):
                return can, reason, claim
        # Too few of them to judge as a side or to refit the rim with: hidden, as when fewer are seen
        # (fresh 4048 of "cans touching": 22 points low on a can behind a wider one).
    # A can seen by its lid alone has a flat lid: its heights spread as the noise spreads them. A mug's
    # rim with the top of its inner wall under it, seen over a taller box in front, spreads down from the
    # rim (fresh 5119 of "cluttered table": 8.5 mm from the 5th to the 95th percentile, 6.7 sigma; the 16
    # lids alone on "cans touching", "cluttered table" and "box hides base" 0-99 and 400-459: 1.9-3.5
    # sigma, at most 5.6 mm). Only here: a cup's rim whose side tells it (_rim_verdict) is claimed, and
    # the can under it found (cup on can 5047).
    # Nor does a rim alone over a short arc of noisy samples fix its radius, as a side its lid does not pin
    # does not (verify's max_radius_error: fresh 6203 of "cluttered table", a prism's top between two cans, its
    # rim over 1.8 rad, 11 samples, r 25.5 mm +- 6.4; the 24 cans seen by their lids alone on "cans touching",
    # "cluttered table" and "box hides base" 0-99, 400-499 and held-out 600-609 to 1900-1909: 0.6-2.1 mm).
    if (_open_top(pts[dist <= r + r_eps], cx, cy, r, r_eps, 0.0, z_lid, ctx)[0]
            or _not_flat(lid[np.hypot(lid[:, 0] - cx, lid[:, 1] - cy) <= r + r_eps, 2], sigma)
            or not _rest_hidden(_side_seen(free.seen, cx, cy, r, r_eps, z_lid - s.band_height, ctx), cx, cy, r,
                                r_eps, c.min_height + 0.01, hidden_below, ctx)
            or (by_side is None and g.radius_standard_error(far[rim.kept], cx, cy, rim.outline_radius)
                > s.max_radius_error)):
        return None, "", None
    mine = free.idx[(dist <= r + r_eps) & (z <= z_lid + s.band_height)]
    return Can(T_sensor_from_can=g.can_pose(ctx.T_sensor_from_plane, cx, cy, 0.0), radius=r, height=z_lid,
               rms_error=rim.rms, arc_coverage=g.arc_coverage(pts[side, :2], cx, cy) if side.any() else 0.0,
               n_points=len(mine), n_fit_points=int(np.count_nonzero(np.abs(rim.residual) <= r_eps)),
               center_plane=np.array([cx, cy]),
               shape_error=g.shape_error(far, cx, cy, rim.outline_radius, c.shape_bins),
               indices=mine, support="table", base_seen=False, support_height=0.0), "", None


def _rim_judged(rim, pts, z_lid, lid, sigma, r_eps, ctx):
    """_lid_judged's tests of a lid's rim (geometry.RimCircle; lid: its points at the height z_lid, pts
    the cluster's free points, float (N, 3), plane frame, m): (the rim, refitted if pinned by a
    stripe of side or fitted on its hull, whether it was seen whole, the pinned rim or None), or None
    when it is no lid's rim."""
    s = ctx.search
    by_side = None
    whole = _lid_rim(rim, lid, sigma, r_eps, ctx)
    if not whole:
        # A lid the can in front cuts short shows its rim over less than lid_arc: pinned by the stripe
        # of side under it ("cans touching" 2408, development 73 of "cluttered table"), or, with no
        # such stripe, judged as it is if something in front stands higher (_lid_rim's shaded).
        stripe = _side_stripe(rim, pts, z_lid, r_eps, ctx)
        pinned = by_side = (None if stripe is None
                            else _rim_with_side(rim, stripe, lid, sigma, r_eps, ctx, side_counts=True))
        if pinned is not None and g.line_ratio(stripe, pinned.cx, pinned.cy, pinned.radius) < s.flat_ratio:
            # A stripe lying nearer a line than its circle by more than 1 / flat_ratio (rms) is a box's
            # face under its top: no lid at this height (fresh 10528 of "cluttered table", a 69 x 44 mm
            # box's top cut short by a taller can's shadow, 0.42, and development 312, a prism's, 0.38:
            # each a can of r 23 mm; the cans pinned on "cans touching" and "cluttered table" 60-399:
            # 0.62-1.97).
            return None
        if pinned is None and not _lid_rim(rim, lid, sigma, r_eps, ctx, shaded=True):
            # A lid seen sparsely (far, a few points per sector of the outline) has outline samples
            # well inside its rim; judged on the rest too, those on the hull of its points (fresh 5134
            # of "cluttered table": a can behind a taller box at 1.1 m, 82 points on its lid, the
            # box's shadow cutting its near part; its rim 7 mm small, 7 mm off).
            pinned = _hull_rim(rim, lid, sigma, r_eps, ctx)
            if pinned is None:
                return None
            # The hull fixes the circle to a few millimetres only; a stripe of side under it, seen wide
            # but too short for the rounds to judge, pins it (fresh 14728 of "lying can touching can": a
            # can behind a lying one, 20 mm of its side over it, 21 points on the rounds' circle; the
            # hull's circle 3.9 mm off, its own side then seen through it).
            stripe = _side_stripe(pinned, pts, z_lid, r_eps, ctx, wide=True)
            joint = None if stripe is None else _rim_with_side(pinned, stripe, lid, sigma, r_eps, ctx,
                                                               side_counts=True)
            if joint is not None and g.line_ratio(stripe, joint.cx, joint.cy, joint.radius) >= s.flat_ratio:
                pinned = by_side = joint
        rim = rim if pinned is None else pinned
    return rim, whole, by_side


def _side_seen(points, cx, cy, r, r_eps, z_below, ctx):
    """The (x, y) (m, plane frame) of the points (float64 (N, 3), plane frame) within r_eps of the
    circle (cx, cy, r) on its near half below z_below (m): where its side is seen, whatever claimed
    the points. A cup's claim reaches r_eps beyond its wall, over the side of a can behind it,
    touching it (fresh 8749 of "cluttered table": 12 of the 87 points on the circle of a can seen by
    its lid left free)."""
    near = points[(np.abs(points[:, 0] - cx) <= r + r_eps) & (np.abs(points[:, 1] - cy) <= r + r_eps)
                  & (points[:, 2] < z_below)]
    on = (np.abs(np.hypot(near[:, 0] - cx, near[:, 1] - cy) - r) <= r_eps) & _facing(near[:, 0], near[:, 1], cx, cy,
                                                                                        r, ctx)
    return near[on, :2]


def _rim_verdict(free, cx, cy, r, ctx):
    """verify (rim=True) of a lid's rim's circle: (Can, "", None), or (None, why, claim) when its side
    told a cup or mug (hollow: its inside or handle seen; claim: the indices of its points), else
    (None, why, None): only a hollow object is surely no can's top."""
    claimed_before = len(ctx.claimed)
    can, reason, claim = verify(free, cx, cy, r, ctx, rim=True)
    # verify records what it claims in ctx.claimed, hollow or not.
    hollow = len(ctx.claimed) > claimed_before and ctx.claimed[-1].hollow
    return can, reason, claim if hollow else None


def _hull_rim(rim, lid, sigma, r_eps, ctx):
    """A lid's rim (geometry.RimCircle) fitted to its outline samples within half a sample spacing
    of the convex hull of its points (lid: float (N, 3), plane frame, m; geometry.on_hull), when
    that leaves out some, keeps at least shape_bins and passes _lid_rim (shaded); else None. An
    outline a half of which lies flat_ratio times as far (rms) from a line as from its circle or less
    (geometry.half_line_ratios) is a box's edge or corner, refitted on no subset of it (fresh 10039
    of "cluttered table": a 68 x 53 mm box's top behind a taller can, both halves 0.36-0.42, the 10
    samples on the hull 1.22: a can of r 37 mm; fresh 10849: a 100 x 46 mm box's top behind a can,
    its edge along its side face 0.30, a can of r 27 mm). A round lid's sparse, noisy outline comes
    near 1 (0.92-0.97 on fresh 9530 and 9640 of "cans touching" and 5134 of "cluttered table", cans
    found by the samples on their hull)."""
    kept = rim.outline[rim.kept]
    halves = g.half_line_ratios(kept, rim.cx, rim.cy, rim.outline_radius)
    if any(ratio < ctx.search.flat_ratio for ratio in halves):
        return None
    keep = g.on_hull(lid, rim.outline, 0.5 * rim.spacing)
    if keep.all() or np.count_nonzero(keep) < ctx.config.shape_bins:
        return None
    hull = g.rim_circle(lid, ctx.sensor, r_eps, outline=rim.outline[keep])
    return hull if hull is not None and _lid_rim(hull, lid, sigma, r_eps, ctx, shaded=True) else None


def _clear_of_found(rim, lid, r_eps, ctx):
    """A lid's rim (geometry.RimCircle), refitted touching the upright can found that its circle
    overlaps most (RimCircle.touching), if it does, when that still holds the lid (its points, float
    (N, 3), plane frame, m; _holds_lid, r_eps in m) with a can's radius; else as it is."""
    c = ctx.config
    overlaps = [(rim.radius + o.radius - np.hypot(*(o.center_plane - (rim.cx, rim.cy))), o)
                for o in ctx.found if not o.lying]
    depth, other = max(overlaps, key=lambda overlap: overlap[0], default=(0.0, None))
    if depth <= 0.0:
        return rim
    moved = rim.touching((*other.center_plane, other.radius))
    if (moved is None or not c.min_radius <= moved.radius <= c.max_radius
            or not _holds_lid(lid, moved.cx, moved.cy, moved.radius, r_eps, moved.spacing,
                              (c.min_radius, c.max_radius))):
        return rim
    return moved


def _side_stripe(rim, pts, z_lid, r_eps, ctx, wide=False):
    """The stripe of side under a lid's rim (geometry.RimCircle) that may pin its circle
    (_rim_with_side, the side counting toward its arc): pts' points (float (N, 3), plane frame, m)
    within 2 r_eps of the rim's circle on its half facing the sensor, more than a band under the lid
    at z_lid (m), their (x, y), float (M, 2); None when fewer than shape_bins, or over min_arc unless
    wide (a side seen wider is the rounds' to fit and judge: a low box's faces pinned its top's rim,
    development 83 of "cluttered table")."""
    c, s = ctx.config, ctx.search
    dist = np.hypot(pts[:, 0] - rim.cx, pts[:, 1] - rim.cy)
    under = ((np.abs(dist - rim.radius) <= 2 * r_eps) & (pts[:, 2] < z_lid - s.band_height)
             & _facing(pts[:, 0], pts[:, 1], rim.cx, rim.cy, rim.radius, ctx))
    stripe = pts[under, :2]
    if len(stripe) < c.shape_bins or (not wide and g.arc_coverage(stripe, rim.cx, rim.cy) >= c.min_arc):
        return None
    return stripe


def _lid_rim(rim, lid, sigma, r_eps, ctx, beside=None, shaded=False):
    """Whether a RimCircle is a can's lid's (_lid_only): a can's radius, round (facet_ratio), rms
    within max(2 mm, 2 sigma) over at least lid_arc, holding 95 % of the lid's points (float (N, 3),
    plane frame, m), and no can found there (its outline's circle, the rim less half the sample
    spacing, overlapping one by more than r_eps, m: two touching cans' circles overlap by their fits'
    errors, and a rim cut short comes out too wide: fresh 4536 of "cans touching"). beside: the
    stripe of side (float (M, 2), m) the rim was refitted with: a rim seen over min_hidden_arc will do
    when both span min_arc, as a side must (the lid of a can behind a taller one, cut short by its
    shadow: "cans touching" 5, its rim over 1.2 rad, 2.25 with the side), and its rms may reach a
    sample spacing (RimCircle.fits, pinned).
    shaded: over min_arc will do when an object in front stands higher than the lid, whose shadow may
    cut it short (fresh 4121 of "cans touching": a rim over 2.43 rad, no side seen)."""
    c, s = ctx.config, ctx.search
    cx, cy, r = rim.cx, rim.cy, rim.radius
    pinned = beside is not None
    if pinned and rim.arc(beside) < c.min_arc:
        return False
    if pinned:
        min_rim_arc = s.min_hidden_arc
    elif shaded and _in_front(cx, cy, r, float(np.median(lid[:, 2])) + s.band_height, np.inf, ctx):
        min_rim_arc = c.min_arc
    else:
        min_rim_arc = s.lid_arc
    return (c.min_radius <= r <= c.max_radius and rim.fits(sigma, min_rim_arc, pinned)
            and g.facet_ratio(rim.outline[rim.kept], cx, cy, rim.outline_radius) >= s.max_facet_ratio
            and _holds_lid(lid, cx, cy, r, r_eps, rim.spacing, (c.min_radius, c.max_radius))
            and not any(not other.lying
                        and np.hypot(*(other.center_plane - (cx, cy))) < rim.outline_radius + other.radius - r_eps
                        for other in ctx.found))


def _top_of_claimed(cx, cy, r, z_lid, r_eps, ctx):
    """Whether a lid (its rim's circle (cx, cy, r) at height z_lid, m) is the top of a round object
    claimed before as no can: within its disc (and r_eps), less than min_can_height above what the
    claim took, lower than a can standing on it would reach (the real learn37 at one grid offset
    and seed: an upside-down bowl's foot over its tapered side)."""
    return any(np.hypot(cx - o.cx, cy - o.cy) + r <= o.r + r_eps and z_lid - o.z_hi < ctx.config.min_can_height
               for o in ctx.claimed)


def _holds_lid(lid, cx, cy, r, r_eps, spacing, radii):
    """Whether 95 % of a lid's points (float (N, 3), m) lie within r + r_eps of (cx, cy) (m): a lid
    wider than the circle is no can's. Of those beyond, only the ones joined to the lid count (a
    chain of points each within 2 sample spacings, `spacing` m, of the next): another object's top
    at about its height, seen apart from it, is not its lid (fresh 8136 of "cluttered table": the rim
    of a cup in front, 5 mm lower, 10 mm clear of the lid's circle; 11 of the lid's 167 points); nor
    are they when they are another round object's rim beside it (_rim_beside; radii: the range of
    its radius, m)."""
    inside = np.hypot(lid[:, 0] - cx, lid[:, 1] - cy) <= r + r_eps
    if np.mean(inside) >= 0.95:
        return True
    label = _pieces(cKDTree(lid[:, :2]), 2 * spacing)
    joined = np.isin(label, label[inside])
    if np.count_nonzero(inside) >= 0.95 * np.count_nonzero(joined):
        return True
    return _rim_beside(lid[joined & ~inside], cx, cy, r, r_eps, spacing, radii)


def _rim_beside(beyond, cx, cy, r, r_eps, spacing, radii, min_points=5):
    """Whether the points beyond a lid's circle (cx, cy, r) (float (M, 3), m) are another round
    object's rim beside it: a circle of a radius within `radii` (m) fits them within a sample spacing
    (rms, m: a rim one sample thick, not a wider top's area) and overlaps the lid's by at most r_eps.
    Fresh 9109 of "cluttered table": a cup as high as the can behind it, 9 mm apart, its far rim one
    sample spacing from the lid's outermost points (36 of its 246; circle r 36 mm, rms 2.5 mm)."""
    if len(beyond) < min_points:
        return False
    try:
        ox, oy, other = g.fit_circle_algebraic(beyond)
    except PerceptionError:
        return False
    return (radii[0] <= other <= radii[1] and g.circle_rms(beyond, ox, oy, other) <= spacing
            and np.hypot(ox - cx, oy - cy) >= r + other - r_eps)


def _rim_with_side(rim, side_xy, lid, sigma, r_eps, ctx, side_counts=False):
    """The lid's rim (geometry.RimCircle) refitted to its outline and a stripe of side under it
    (side_xy, m; RimCircle.with_side), or None when that fits no circle or the lid (its points, float
    (N, 3), m) fails the rim's tests on it (_lid_rim; side_counts: the side counts toward its arc,
    _lid_rim's beside)."""
    joint = rim.with_side(side_xy)
    beside = side_xy if side_counts else None
    return joint if joint is not None and _lid_rim(joint, lid, sigma, r_eps, ctx, beside=beside) else None


def _bare_lid(points, z_lid, sigma, band):
    """lid_points less those under a point more than `band` (m) higher at the same place (seen from
    above, within 5 mm): nothing stands over a lid, such a point is a wall's, an object's beside or
    behind the can."""
    lid = lid_points(points, z_lid, sigma)
    over = points[points[:, 2] > z_lid + band, :2]
    if len(over) and len(lid):
        lid = lid[cKDTree(over).query_ball_point(lid[:, :2], 0.005, return_length=True) == 0]
    return lid


def _not_flat(z, sigma):
    """Whether heights z (m) of a lid's points spread more than a flat lid's: from their 5th to their 95th
    percentile more than max(5 sigma, 5 mm) (sigma: the depth noise there, m)."""
    lo, hi = _percentile(z, 5), _percentile(z, 95)
    return hi - lo > max(5 * sigma, 0.005)


def lid_points(points, z_lid, sigma):
    """The points (float (N, 3), plane frame, m) on a lid at height z_lid (m): within max(5 mm,
    3 sigma) of it (sigma: the depth noise there, m)."""
    return points[on_lid(points[:, 2], z_lid, sigma)]


def on_lid(z, z_lid, sigma):
    """Which heights z (m) lie on a lid at z_lid (m): within max(5 mm, 3 sigma) of it (sigma: the
    depth noise there, m). bool, z's shape."""
    return np.abs(z - z_lid) <= max(0.005, 3 * sigma)


def _lying(points, rest, ctx):
    """The lying cans among the points `rest` (indices into the cluster's points, plane frame) that no
    upright can claimed: (list of Can with lying=True and indices into the cluster's points, why
    the rest is no lying can)."""
    c = ctx.config
    pts = points[rest]
    sigma = _sigma(ctx, pts.mean(axis=0))
    found, why = lying.lying_cans(pts, c.r_eps_at(sigma), sigma, c, ctx.search, ctx.sensor,
                                  ctx.standing, ctx.projector, ctx.ray_angle)
    return [_lying_result(can, rest, ctx) for can in found], why


def _lying_result(found, rest, ctx):
    """The Can of a lying can found (lying.LyingCan, masks over the points `rest` index). Its points are
    its side and ends and the rims of its ends on the far half: left to the upright search, the rim of an
    end touching an upright can stuck out of it like a mug's handle ("lying can touching can",
    development seeds 29, 40)."""
    fit = found.fit
    mine = found.mine | found.rims
    middle = found.start + 0.5 * found.length * found.direction
    return Can(T_sensor_from_can=g.lying_can_pose(ctx.T_sensor_from_plane, found.start, found.direction),
               radius=fit.radius, height=found.length, rms_error=found.rms, arc_coverage=found.arc,
               n_points=int(mine.sum()), n_fit_points=int(found.inliers.sum()), center_plane=middle[:2].copy(),
               shape_error=found.shape_error, indices=rest[mine], support="table", base_seen=True,
               support_height=0.0, lying=True)


def projector_in_plane(T_plane_from_sensor, search):
    """The IR projector (3,), projector_offset (CylinderSearchConfig `search`) along the camera's +x,
    in the plane frame (m; T_plane_from_sensor 4x4), or None when the offset is not known (0)."""
    if not search.projector_offset:
        return None
    return transforms.apply(T_plane_from_sensor, (search.projector_offset, 0.0, 0.0))


def search(clusters, standing, T_sensor_from_plane, sensor_plane, config, ray_angle=0.0, image_edge=None,
           beyond_image=None):
    """Every can in the clusters: (list of (cluster number, Can)), list of (cluster number,
    Rejection)), each Can's indices into that cluster's points.

    clusters: list of float64 (M, 3) plane-frame points (m), one array per cluster; standing:
    float64 (N, 3), every point standing on the table (occluders are looked for among them);
    T_sensor_from_plane: 4x4, the plane frame in the sensor frame (the Cans' poses are in the sensor
    frame); sensor_plane: the sensor in the plane frame (m); config: auto_finder.AutoConfig (the
    band, fit and criterion; its .cylinders the CylinderSearchConfig); ray_angle (rad): between
    the rays of neighbouring points of the grid searched (geometry.ray_angle; 0: not known);
    image_edge: float64 (E, 3), the standing points on the image's edge (a can's base below them is
    out of view; None: no image); beyond_image: which places (float64 (K, 3), plane frame, m) lie
    beyond the image's edge, bool (K,) (None: no image)."""
    s = config.cylinders
    s.validate()
    projector = projector_in_plane(transforms.invert(T_sensor_from_plane), s)
    ctx = _Context(config=config, search=s, T_sensor_from_plane=np.asarray(T_sensor_from_plane, dtype=float),
                   sensor=np.asarray(sensor_plane, dtype=float),
                   standing=np.asarray(standing, dtype=float), rng=np.random.default_rng(s.seed), found=[],
                   ray_angle=float(ray_angle),
                   image_edge=np.zeros((0, 3)) if image_edge is None else np.asarray(image_edge, dtype=float),
                   projector=projector, beyond_image=beyond_image)
    cans, rejections, own = [], {}, []
    # Lowest clusters first is not needed: a stacked can's support is in its own cluster.
    for k, points in enumerate(clusters):
        before = len(ctx.claimed)
        h, rejections[k] = search_cluster(points, ctx, list(ctx.claimed))
        cans += [(k, can) for can in h]
        own.append((ctx.claimed[before:], len(ctx.claimed)))  # its claims, and where the later ones start
    # A round object claimed in a later cluster may go on in one searched before it where no can was
    # found (the cup of fresh 13116 split between its cluster and a can's): that one is searched again
    # without it (and without its own claims, made again).
    with_cans = {k for k, _ in cans}
    again = [k for k, (_, after) in enumerate(own) if k not in with_cans and np.count_nonzero(
        _on_claimed(clusters[k], ctx, ctx.claimed[after:])) >= config.min_fit_points]
    for k in again:
        ctx.claimed[:] = [o for o in ctx.claimed if not any(o is m for m in own[k][0])]
        h, rejections[k] = search_cluster(clusters[k], ctx, list(ctx.claimed))
        cans += [(k, can) for can in h]
    return _join_lying(cans, ctx), [(k, rj) for k in sorted(rejections) for rj in rejections[k]]


def _join_lying(cans, ctx):
    """The (cluster number, Can) list with the parts of one lying can joined: an object standing
    across a lying can (a box in front of its middle) splits it into two clusters, each a shorter
    lying can. Two lying cans are one when their axes are within lying_join_angle (rad) of each other,
    each one's axis passes within lying_join_offset (m) of the other's middle, their radii differ
    by less than that, the gap between them is at most lying_join_gap (m) and some standing object
    reaches up to their axis' height in that gap (it hides the middle). The joined can keeps the
    larger part's cluster number and indices."""
    T_plane_from_sensor = transforms.invert(ctx.T_sensor_from_plane)
    joined = True
    while joined:
        joined = False
        lying_at = [i for i, (_, can) in enumerate(cans) if can.lying]
        for i in lying_at:
            for j in lying_at:
                if i < j and _same_lying(cans[i][1], cans[j][1], T_plane_from_sensor, ctx):
                    a, b = cans[i][1], cans[j][1]
                    keep = cans[i][0] if a.n_points >= b.n_points else cans[j][0]
                    bigger = a if a.n_points >= b.n_points else b
                    cans = [kc for n, kc in enumerate(cans) if n not in (i, j)]
                    cans.append((keep, _joined(a, b, bigger, T_plane_from_sensor)))
                    joined = True
                    break
            if joined:
                break
    return cans


def _lying_ends(can, T_plane_from_sensor):
    """(start, end, unit direction) of a lying can's axis in the plane frame (m)."""
    start = transforms.apply(T_plane_from_sensor, can.base_center)
    end = transforms.apply(T_plane_from_sensor, can.base_center + can.height * can.axis)
    return start, end, (end - start) / max(can.height, 1e-9)


def _same_lying(a, b, T_plane_from_sensor, ctx):
    """Whether the lying cans a and b are two visible parts of one (see _join_lying)."""
    s = ctx.search
    sa, ea, ua = _lying_ends(a, T_plane_from_sensor)
    sb, eb, ub = _lying_ends(b, T_plane_from_sensor)
    if abs(float(ua @ ub)) < np.cos(s.lying_join_angle) or abs(a.radius - b.radius) > s.lying_join_offset:
        return False
    for (p, u), m in (((sa, ua), 0.5 * (sb + eb)), ((sb, ub), 0.5 * (sa + ea))):
        rel = m - p
        if np.linalg.norm(rel - (rel @ u) * u) > s.lying_join_offset:
            return False
    # Along a's axis: b's span, and the gap between the two spans.
    ta = sorted((0.0, a.height))
    tb = sorted(((sb - sa) @ ua, (eb - sa) @ ua))
    lo, hi = (ta[1], tb[0]) if tb[0] >= ta[1] else (tb[1], ta[0])
    if hi - lo > s.lying_join_gap:
        return False
    st = ctx.standing
    rel = st - sa
    along = rel @ ua
    lateral = np.linalg.norm(rel[:, :2] - along[:, None] * ua[:2], axis=1)
    hiding = ((along >= lo - 0.01) & (along <= hi + 0.01) & (lateral <= a.radius + s.occluder_reach)
              & (st[:, 2] >= sa[2]))
    return int(np.count_nonzero(hiding)) >= s.min_band_points


def _joined(a, b, bigger, T_plane_from_sensor):
    """One lying Can from its two parts a and b: the horizontal axis through the middles of both
    parts' axes, from the farthest end to the farthest end."""
    (sa, ea, _), (sb, eb, _) = _lying_ends(a, T_plane_from_sensor), _lying_ends(b, T_plane_from_sensor)
    # A part's middle is surer than its direction: the parts' middles, far apart, pin the axis
    # (a part of a real Pringles behind a box came out 3 degrees off the labelled can's axis).
    ma, mb = 0.5 * (sa + ea), 0.5 * (sb + eb)
    u = np.array([mb[0] - ma[0], mb[1] - ma[1], 0.0])
    u /= max(np.linalg.norm(u), 1e-9)
    ends = np.array([sa, ea, sb, eb])
    along = (ends - ma) @ u
    lo, hi = float(along.min()), float(along.max())
    start = ma + lo * u
    start[2] = 0.5 * (ma[2] + mb[2])
    T = g.lying_can_pose(transforms.invert(T_plane_from_sensor), start, u)
    n = a.n_fit_points + b.n_fit_points
    rms = float(np.sqrt((a.n_fit_points * a.rms_error ** 2 + b.n_fit_points * b.rms_error ** 2) / max(n, 1)))
    middle = start + 0.5 * (hi - lo) * u
    return dataclasses.replace(bigger, T_sensor_from_can=T, height=hi - lo, rms_error=rms,
                               arc_coverage=max(a.arc_coverage, b.arc_coverage), n_points=a.n_points + b.n_points,
                               n_fit_points=n, center_plane=middle[:2].copy(),
                               radius=(a.n_fit_points * a.radius + b.n_fit_points * b.radius) / max(n, 1))
