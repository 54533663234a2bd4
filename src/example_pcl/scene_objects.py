"""More objects for the simulated Kinect (example_pcl.scene): cups, mugs, bowls, lying cans, tins,
turned boxes and prisms, anything stacked; and the cases of issue 13 with their ground truth.

Pure NumPy; knows nothing of ROS. An :class:`Obj` is one object in the *table frame* (origin at the
centre of the table top, z up, metres): its base centre (x, y, z: z > 0 when it stands on another
object), a yaw (rad) about the vertical, and its size. scene.generate_scene casts every pixel's ray
against ``SceneSpec.objects`` with :func:`hit_object` and adds each object's truth
(:func:`truth`) to ``Scene.truth["objects"]``.

Kinds: ``can`` (closed upright cylinder: radius, height), ``tin`` (the same, wide and flat: a
biscuit tin, no can), ``lying_can`` (closed cylinder on its
side, its axis along the yaw direction: radius, height = length), ``cup`` (open upright cylinder,
thin wall, a bottom inside), ``mug`` (a cup with a handle on its yaw side), ``bowl`` (an open
spherical cap: radius of the rim, height), ``box`` (size (sx, sy, sz), turned by yaw), ``prism``
(an upright triangular prism: radius of its circumcircle, height).
"""
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from example_pcl.errors import PerceptionError

KINDS = ("can", "tin", "lying_can", "cup", "mug", "bowl", "box", "prism")
CUP_WALL = 0.004  # m, a cup's wall and bottom
HANDLE = (0.022, 0.012, 0.055)  # m: how far a mug's handle sticks out, its thickness, its height


@dataclass
class Obj:
    """One object (module docstring). x, y, z: base centre, table frame (m); radius, height (m);
    size: (sx, sy, sz) of a box (m); yaw (rad); support: what it stands on ("table", "object",
    "can"), for the truth."""

    kind: str
    x: float
    y: float
    z: float = 0.0
    radius: float = 0.033
    height: float = 0.122
    size: Tuple[float, float, float] = (0.1, 0.1, 0.1)
    yaw: float = 0.0
    support: str = "table"

    def validate(self):
        if self.kind not in KINDS:
            raise PerceptionError(f"object kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if not (self.radius > 0 and self.height > 0 and all(s > 0 for s in self.size) and self.z >= 0):
            raise PerceptionError(f"object {self.kind} at ({self.x}, {self.y}): sizes must be > 0 m and z >= 0")

    @property
    def top(self):
        """Height of its top above the table (m)."""
        if self.kind == "box":
            return self.z + self.size[2]
        if self.kind == "lying_can":
            return self.z + 2 * self.radius
        return self.z + self.height


# --- ray casting (table frame) ----------------------------------------------------------------------
# Each takes ray origins o, directions d ((N, 3)) and t_min; returns (t, normal): t (N,) inf for a
# miss, normal (N, 3) unit, outward.


def _rotation_z(yaw):
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _convex(o, d, normals, offsets, t_min):
    """Convex polytope {p: n_i . p <= offset_i}: entering hits only (slab method over planes)."""
    nd = d @ normals.T
    no = o @ normals.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (offsets - no) / nd
    entering = nd < 0
    t_in = np.where(entering, t, -np.inf)
    t_out = np.where(nd > 0, t, np.inf)
    parallel_out = (nd == 0) & (no > offsets)
    face = np.argmax(t_in, axis=1)
    t_near = t_in[np.arange(len(o)), face]
    t_far = t_out.min(axis=1)
    hit = (t_near <= t_far) & (t_near > t_min) & ~parallel_out.any(axis=1)
    return np.where(hit, t_near, np.inf), normals[face]


def _box_planes(center_xy, z0, size, yaw):
    R = _rotation_z(yaw)
    axes = [R[:, 0], R[:, 1], np.array([0.0, 0.0, 1.0])]
    c = np.array([center_xy[0], center_xy[1], z0 + size[2] / 2])
    normals, offsets = [], []
    for a, s in zip(axes, size):
        for sign in (1.0, -1.0):
            n = sign * a
            normals.append(n)
            offsets.append(n @ c + s / 2)
    return np.array(normals), np.array(offsets)


def _prism_planes(obj):
    normals, offsets = [], []
    base = np.array([obj.x, obj.y])
    for k in range(3):
        a = obj.yaw + 2 * np.pi * k / 3 + np.pi / 3  # face normals between the vertices
        n = np.array([np.cos(a), np.sin(a), 0.0])
        normals.append(n)
        offsets.append(n[:2] @ base + obj.radius / 2)  # inradius of an equilateral triangle: R / 2
    normals += [np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])]
    offsets += [obj.z + obj.height, -obj.z]
    return np.array(normals), np.array(offsets)


def _cylinder(o, d, r, z0, z1, t_min):
    """Side of an upright cylinder about the local z axis (origin on it), z0 <= z <= z1."""
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2 * (o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1])
    c = o[:, 0] ** 2 + o[:, 1] ** 2 - r * r
    disc = b * b - 4 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        roots = np.stack([(-b - sq) / (2 * a), (-b + sq) / (2 * a)], axis=1)
    z = o[:, 2:3] + roots * d[:, 2:3]
    ok = np.isfinite(roots) & (roots > t_min) & (z >= z0) & (z <= z1)
    roots = np.where(ok, roots, np.inf)
    t = roots.min(axis=1)
    with np.errstate(invalid="ignore"):
        p = o + np.where(np.isfinite(t), t, 0)[:, None] * d
    normal = np.zeros_like(o)
    normal[:, :2] = p[:, :2] / r
    return t, normal


def _disc(o, d, r, z, t_min):
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z - o[:, 2]) / d[:, 2]
        p = o + np.where(np.isfinite(t), t, 0)[:, None] * d
    ok = np.isfinite(t) & (t > t_min) & (p[:, 0] ** 2 + p[:, 1] ** 2 <= r * r)
    normal = np.zeros_like(o)
    normal[:, 2] = 1.0
    return np.where(ok, t, np.inf), normal


def _nearest(*hits):
    t = np.stack([h[0] for h in hits])
    k = np.argmin(t, axis=0)
    n = np.stack([h[1] for h in hits])[k, np.arange(t.shape[1])]
    return t[k, np.arange(t.shape[1])], n


def hit_object(obj, o, d, t_min):
    """Nearest hit of rays (o, d: (N, 3), table frame) on obj: (t (N,), normal (N, 3))."""
    if obj.kind in ("box", "prism"):
        normals, offsets = (_box_planes((obj.x, obj.y), obj.z, obj.size, obj.yaw) if obj.kind == "box"
                            else _prism_planes(obj))
        return _convex(o, d, normals, offsets, t_min)
    if obj.kind == "lying_can":
        # Local frame: z along the axis (the yaw direction), origin at the centre of one end.
        axis = np.array([np.cos(obj.yaw), np.sin(obj.yaw), 0.0])
        x = np.array([0.0, 0.0, 1.0])
        y = np.cross(axis, x)
        R = np.stack([x, y, axis], axis=1)  # table_from_local
        origin = np.array([obj.x, obj.y, obj.z + obj.radius]) - axis * obj.height / 2
        lo, ld = (o - origin) @ R, d @ R
        t, n = _nearest(_cylinder(lo, ld, obj.radius, 0.0, obj.height, t_min),
                        _disc(lo, ld, obj.radius, 0.0, t_min), _disc(lo, ld, obj.radius, obj.height, t_min))
        return t, n @ R.T
    lo = o - (obj.x, obj.y, obj.z)
    if obj.kind in ("can", "tin"):
        return _nearest(_cylinder(lo, d, obj.radius, 0.0, obj.height, t_min),
                        _disc(lo, d, obj.radius, obj.height, t_min))
    if obj.kind in ("cup", "mug"):
        hits = [_cylinder(lo, d, obj.radius, 0.0, obj.height, t_min),
                _cylinder(lo, d, obj.radius - CUP_WALL, CUP_WALL, obj.height, t_min),
                _disc(lo, d, obj.radius - CUP_WALL, CUP_WALL, t_min)]
        if obj.kind == "mug":
            reach, thick, tall = HANDLE
            R = _rotation_z(obj.yaw)
            centre = R[:2, 0] * (obj.radius + reach / 2 - 0.002)
            normals, offsets = _box_planes(centre, obj.height / 2 - tall / 2, (reach, thick, tall), obj.yaw)
            hits.append(_convex(lo, d, normals, offsets, t_min))
        return _nearest(*hits)
    if obj.kind == "bowl":
        # A spherical cap through the rim (radius, at height) and the bottom (at 0), open at the top.
        h, a = obj.height, obj.radius
        rs = (a * a + h * h) / (2 * h)
        c = np.array([0.0, 0.0, rs])
        oc = lo - c
        b = np.sum(oc * d, axis=1)
        cc = np.sum(oc * oc, axis=1) - rs * rs
        dd = np.sum(d * d, axis=1)
        disc = b * b - dd * cc
        with np.errstate(invalid="ignore"):
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            roots = np.stack([(-b - sq) / dd, (-b + sq) / dd], axis=1)
        z = lo[:, 2:3] + roots * d[:, 2:3]
        ok = np.isfinite(roots) & (roots > t_min) & (z >= 0) & (z <= h)
        t = np.where(ok, roots, np.inf).min(axis=1)
        with np.errstate(invalid="ignore"):
            p = oc + np.where(np.isfinite(t), t, 0)[:, None] * d
        return t, p / rs
    raise PerceptionError(f"unknown object kind {obj.kind!r}")


# --- truth ------------------------------------------------------------------------------------------


def truth(obj, T_camera_from_table, base_visible, visible_points):
    """JSON-able truth of obj in the camera frame: kind, is_can (an upright can a robot would
    grasp), lying, base_center (upright: centre of its base; lying: of one end), axis (unit, up or
    along a lying can), radius, height (a lying can's length), support, support_height (m above
    the table), base_seen (some of the lowest 2 cm of its side returned depth), visible_points (its
    pixels that returned depth)."""
    R, t = T_camera_from_table[:3, :3], T_camera_from_table[:3, 3]
    if obj.kind == "lying_can":
        axis = np.array([np.cos(obj.yaw), np.sin(obj.yaw), 0.0])
        base = np.array([obj.x, obj.y, obj.z + obj.radius]) - axis * obj.height / 2
    else:
        axis = np.array([0.0, 0.0, 1.0])
        base = np.array([obj.x, obj.y, obj.z])
    return {"kind": obj.kind, "is_can": obj.kind == "can", "lying": obj.kind == "lying_can",
            "base_center": (R @ base + t).tolist(), "axis": (R @ axis).tolist(), "radius": float(obj.radius),
            "height": float(obj.height), "size": [float(s) for s in obj.size], "yaw": float(obj.yaw),
            "support": obj.support, "support_height": float(obj.z), "base_seen": bool(base_visible),
            "visible_points": int(visible_points)}


# --- the cases of issue 13 ----------------------------------------------------------------------------


def _can(rng, x, y, z=0.0, support="table", radius=None, height=None):
    r = float(rng.uniform(0.028, 0.045)) if radius is None else radius
    h = float(rng.uniform(0.09, 0.16)) if height is None else height
    return Obj("can", x, y, z, radius=r, height=h, support=support)


def _tin(rng, x, y):
    return Obj("tin", x, y, radius=float(rng.uniform(0.09, 0.11)), height=float(rng.uniform(0.05, 0.08)))


def _bowl(rng, x, y):
    return Obj("bowl", x, y, radius=float(rng.uniform(0.06, 0.08)), height=float(rng.uniform(0.05, 0.07)))


def case_objects(case, rng):
    """The objects of one case (list of Obj), sizes and places drawn from rng."""
    j = lambda s=0.03: float(rng.uniform(-s, s))  # noqa: E731 - a jitter
    if case == "cup on can":
        can = _can(rng, j(), j())
        return [can, Obj("cup", can.x + j(0.004), can.y + j(0.004), can.top, radius=can.radius + 0.008,
                         height=float(rng.uniform(0.07, 0.1)), support="can", yaw=j(3))]
    if case == "can on can":
        low = _can(rng, j(), j(), radius=float(rng.uniform(0.04, 0.05)), height=float(rng.uniform(0.08, 0.11)))
        return [low, _can(rng, low.x + j(0.005), low.y + j(0.005), low.top, "can",
                          radius=float(rng.uniform(0.026, 0.033)), height=float(rng.uniform(0.08, 0.12)))]
    if case == "cans touching":
        a = _can(rng, j(), j())
        b_r = float(rng.uniform(0.028, 0.045))
        ang = float(rng.uniform(0, np.pi))
        b = _can(rng, a.x + (a.radius + b_r + 0.001) * np.cos(ang), a.y + (a.radius + b_r + 0.001) * np.sin(ang),
                 radius=b_r)
        return [a, b]
    if case == "can touching box":
        can = _can(rng, j(), j())
        sx, sy = float(rng.uniform(0.06, 0.12)), float(rng.uniform(0.05, 0.1))
        side = float(rng.choice([-1.0, 1.0]))
        return [can, Obj("box", can.x + side * (can.radius + sx / 2 + 0.001), can.y + j(0.02),
                         size=(sx, sy, float(rng.uniform(0.06, 0.2))))]
    if case == "box hides base":
        can = _can(rng, j(), j(), height=float(rng.uniform(0.11, 0.16)))
        box_h = float(rng.uniform(0.04, 0.6 * can.height))
        return [can, Obj("box", can.x + j(0.01), can.y - can.radius - 0.03 - 0.015, size=(0.16, 0.03, box_h))]
    if case == "can on tin":
        tin = _tin(rng, j(), j())
        top = _can(rng, tin.x + j(0.03), tin.y + j(0.03), tin.top, "object")
        return [tin, top]
    if case == "can on box":
        box = Obj("box", j(), j(), size=(0.14, 0.12, float(rng.uniform(0.03, 0.08))), yaw=j(0.5))
        return [box, _can(rng, box.x + j(0.02), box.y + j(0.02), box.top, "object")]
    if case == "lying can":
        lying = Obj("lying_can", j(), j(), radius=float(rng.uniform(0.028, 0.04)),
                    height=float(rng.uniform(0.1, 0.2)), yaw=float(rng.uniform(0, np.pi)))
        return [lying, _can(rng, lying.x + 0.2, lying.y + j())]
    if case == "mug and bowl":
        return [Obj("mug", j() - 0.12, j(), radius=float(rng.uniform(0.035, 0.045)),
                    height=float(rng.uniform(0.08, 0.11)), yaw=float(rng.uniform(0, 2 * np.pi))),
                _bowl(rng, j() + 0.12, j()),
                _can(rng, j(), 0.15 + j(0.01))]
    if case == "boxes and prisms":
        return [Obj("box", -0.15 + j(), j(), size=(0.04, 0.04, float(rng.uniform(0.12, 0.2))), yaw=j(1)),
                Obj("prism", j(), j(), radius=float(rng.uniform(0.03, 0.05)), height=float(rng.uniform(0.08, 0.15)),
                    yaw=j(3)),
                Obj("box", 0.15 + j(), j(), size=(0.07, 0.05, 0.12), yaw=float(rng.uniform(0.3, 1.2)))]
    if case.startswith("lying can"):
        return _lying_touching(case, rng, j)
    if case == "cluttered table":
        return _cluttered(rng)
    raise PerceptionError(f"unknown case {case!r}; one of {', '.join(CASES)}")


def _lying_can(rng, x, y, yaw):
    return Obj("lying_can", x, y, radius=float(rng.uniform(0.028, 0.04)), height=float(rng.uniform(0.1, 0.2)), yaw=yaw)


def _lying_touching(case, rng, j):
    """A lying can touching a standing box, an upright can or a second lying can (1 mm apart), on its
    side (across the axis) or, for the box and the upright can, at its end. Whatever touches it stands
    on its side or end away from the sensor (which looks along +y, turned up to 0.6 rad), behind it
    or beside it as the sensor sees it, never in front, where it would hide it."""
    lying = _lying_can(rng, j(), j(), float(rng.uniform(0, np.pi)))
    u = np.array([np.cos(lying.yaw), np.sin(lying.yaw)])
    n = np.array([-u[1], u[0]]) * (1.0 if u[0] >= 0 else -1.0)  # across the axis, away from the sensor
    at_end = case != "lying cans touching" and rng.random() < 0.4
    # From the axis' middle to the contact, and the unit direction on from there: at its far end or
    # its far side (a box at the near end would hide the can's side behind it).
    out = (u if u[1] >= 0 else -u) if at_end else n
    reach = lying.height / 2 if at_end else lying.radius
    along = 0.0 if at_end else float(rng.uniform(-0.3, 0.3)) * lying.height
    contact = np.array([lying.x, lying.y]) + along * u + reach * out
    if case == "lying can touching box":
        deep, wide = float(rng.uniform(0.04, 0.1)), float(rng.uniform(0.06, 0.14))
        c = contact + (deep / 2 + 0.001) * out
        yaw = float(np.arctan2(out[1], out[0]))
        return [lying, Obj("box", float(c[0]), float(c[1]), size=(deep, wide, float(rng.uniform(0.04, 0.16))),
                           yaw=yaw)]
    if case == "lying can touching can":
        can = _can(rng, 0.0, 0.0)
        c = contact + (can.radius + 0.001) * out
        can.x, can.y = float(c[0]), float(c[1])
        return [lying, can]
    other = _lying_can(rng, 0.0, 0.0, lying.yaw)
    # Both on the table, their axes 2 sqrt(r r') apart across (r + r' apart in the plane through both).
    c = (np.array([lying.x, lying.y]) + (2 * np.sqrt(lying.radius * other.radius) + 0.001) * n
         + float(rng.uniform(-0.3, 0.3)) * lying.height * u)
    other.x, other.y = float(c[0]), float(c[1])
    return [lying, other]


def _cluttered(rng):
    """6-9 objects of every kind on one table (half of them cans), each placed where its footprint
    (a circle round it seen from above) overlaps none placed before: at random, or half the time
    1-15 mm from one placed before, so objects touch, stand close and hide each other."""
    def draw(kind):
        if kind == "can":
            return _can(rng, 0.0, 0.0)
        if kind == "lying_can":
            return _lying_can(rng, 0.0, 0.0, float(rng.uniform(0, np.pi)))
        if kind in ("cup", "mug"):
            return Obj(kind, 0.0, 0.0, radius=float(rng.uniform(0.03, 0.045)), height=float(rng.uniform(0.07, 0.11)),
                       yaw=float(rng.uniform(0, 2 * np.pi)))
        if kind == "bowl":
            return _bowl(rng, 0.0, 0.0)
        if kind == "tin":
            return _tin(rng, 0.0, 0.0)
        if kind == "prism":
            return Obj("prism", 0.0, 0.0, radius=float(rng.uniform(0.03, 0.05)),
                       height=float(rng.uniform(0.08, 0.15)), yaw=float(rng.uniform(0, 2 * np.pi)))
        return Obj("box", 0.0, 0.0, size=(float(rng.uniform(0.04, 0.14)), float(rng.uniform(0.04, 0.12)),
                                          float(rng.uniform(0.04, 0.2))), yaw=float(rng.uniform(0, np.pi)))

    def footprint(obj):
        if obj.kind == "box":
            return 0.5 * float(np.hypot(obj.size[0], obj.size[1]))
        if obj.kind == "lying_can":
            return float(np.hypot(0.5 * obj.height, obj.radius))
        return obj.radius + (HANDLE[0] if obj.kind == "mug" else 0.0)

    kinds = ["can"] * 5 + ["lying_can", "cup", "mug", "bowl", "tin", "prism", "box", "box"]
    placed = []
    for _ in range(int(rng.integers(6, 10))):
        obj = draw(kinds[int(rng.integers(len(kinds)))])
        for _ in range(50):
            if placed and rng.random() < 0.5:
                near = placed[int(rng.integers(len(placed)))]
                d = footprint(near) + footprint(obj) + float(rng.uniform(0.001, 0.015))
                a = float(rng.uniform(0, 2 * np.pi))
                obj.x, obj.y = near.x + d * np.cos(a), near.y + d * np.sin(a)
            else:
                obj.x, obj.y = float(rng.uniform(-0.25, 0.25)), float(rng.uniform(-0.15, 0.2))
            if abs(obj.x) <= 0.3 and abs(obj.y) <= 0.25 and all(
                    np.hypot(obj.x - o.x, obj.y - o.y) >= footprint(obj) + footprint(o) + 0.001 for o in placed):
                obj.x, obj.y = float(obj.x), float(obj.y)
                placed.append(obj)
                break
    return placed


CASES = ("cup on can", "can on can", "cans touching", "can touching box", "box hides base", "can on tin",
         "can on box", "lying can", "mug and bowl", "boxes and prisms", "lying can touching box",
         "lying can touching can", "lying cans touching", "cluttered table")


def case_spec(case, seed):
    """A scene.SceneSpec of one case of issue 13 for a seed: the objects drawn from
    default_rng(seed) and the camera 0.7-1.3 m away, pitched 0.6-1.1 rad down, turned up to 0.6 rad."""
    from example_pcl import scene  # scene imports this module

    rng = np.random.default_rng([seed, CASES.index(case)])
    objects = case_objects(case, rng)
    return scene.SceneSpec(camera_distance=float(rng.uniform(0.7, 1.3)), tilt=float(rng.uniform(0.6, 1.1)),
                           yaw=float(rng.uniform(-0.6, 0.6)), cans=[], objects=objects, seed=int(seed))
