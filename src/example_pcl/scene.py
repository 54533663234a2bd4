"""Simulated Kinect scenes: a table seen from above with soda cans (and boxes) standing on it.

Pure NumPy; knows nothing of ROS. A pinhole Kinect (640x480, fx = fy = 525 px) in the camera
optical frame (x right, y down, z forward, metres) looks down at a table top: a horizontal slab
``table_size`` wide, its top ``table_height`` above the floor. Every pixel's ray is cast against
the floor, the table slab, each can (a closed-top upright cylinder) and each box (an axis-aligned
slab in the table frame); the nearest hit wins. Then the Kinect's failures are imitated:

* depth noise along the ray, sigma = 1.425e-3 * z**2 metres (Khoshelham & Elberink 2012), and
  optionally the disparity quantisation (1/8 px steps over the 0.075 m baseline);
* no return (NaN) beyond ``max_range`` depth, where nothing is hit, for a random ``dropout``
  fraction of the pixels, and in the projector's shadow: the IR projector sits 0.075 m to the
  camera's +x side, and a point it cannot light (another surface on the segment between them)
  has no depth. That is the dark band beside each can on the table.

Geometry is built in the *table frame*: origin at the centre of the table top, z up, x to the
camera's right when ``yaw`` is 0 and y away from it. Ground truth (``Scene.truth``) is given in the
camera frame, JSON-able, so a test or a node can compare what it found with what is there.

Command line: ``make_scene OUT.pcd [--distance D] [--tilt T] [--can X Y R H] ...`` writes the
cloud with :func:`example_pcl.pcd.write_cloud` and the ground truth beside it as ``OUT.json``.
"""
import argparse
import dataclasses
import json
import pathlib
import sys
from dataclasses import dataclass, field
from typing import List, Optional, Tuple

import numpy as np

from example_pcl import scene_objects
from example_pcl import transforms
from example_pcl.errors import PerceptionError

# The simulated Kinect's depth camera (pixels); the bundled scenes and the nodes assume these.
WIDTH = 640
HEIGHT = 480
FX = FY = 525.0
CX = 319.5
CY = 239.5

# Per-pixel labels of Scene.labels: the surface the camera ray hit, whether or not it returned depth.
LABEL_NONE = 0  # the ray hit nothing
LABEL_FLOOR = 1
LABEL_TABLE = 2  # the table top
LABEL_TABLE_EDGE = 3  # the table slab's sides
LABEL_CAN_SIDE = 100  # + can index
LABEL_CAN_TOP = 200  # + can index
LABEL_BOX = 300  # + box index
LABEL_OBJECT = 400  # + index into SceneSpec.objects

# Colours (rgb) before shading.
_COLOURS = {
    "floor": (128, 128, 128),
    "table": (122, 80, 44),
    "table_edge": (96, 62, 34),
    "can": (200, 28, 36),
    "can_top": (214, 120, 124),
    "box": (40, 70, 205),
    "object": (60, 170, 80),
}


@dataclass
class SceneSpec:
    """What to put in front of the simulated Kinect. Lengths in metres, angles in radians.

    camera_distance: from the camera to the aim point (the first can's base centre, or the table
        centre without cans) along the optical axis, which passes through it.
    tilt: camera pitch down from horizontal (0 < tilt <= pi/2).
    yaw: heading of the view about the table's up axis (0: looking along the table frame's +y).
    cans: (x, y, radius, height) per can, base centre in the table frame (on the table top).
    boxes: (x, y, size_x, size_y, size_z) per box, base centre in the table frame, sides along
        the table frame's axes.
    table_size: (x, y) extent of the table top; table_height: its top above the floor;
        table_thickness: of the top slab (its edge shows in the image).
    noise: depth noise along the ray (sigma = 1.425e-3 z^2); quantize: disparity quantisation.
    dropout: fraction of pixels (0..1) with no return at random. max_range: depth (z) beyond
        which the Kinect returns nothing. projector_offset: the IR projector's +x offset from the
        camera; 0 disables the shadow.
    seed: of the random generator (noise, dropout) when generate_scene() is given none.
    objects: more objects (example_pcl.scene_objects.Obj: cups, mugs, bowls, lying cans, tins,
        turned boxes, prisms, anything stacked), in the table frame.
    """

    camera_distance: float = 1.0
    tilt: float = 0.9
    yaw: float = 0.0
    cans: List[Tuple[float, float, float, float]] = field(default_factory=lambda: [(0.0, 0.0, 0.033, 0.122)])
    boxes: List[Tuple[float, float, float, float, float]] = field(default_factory=list)
    table_size: Tuple[float, float] = (1.2, 0.8)
    table_height: float = 0.75
    table_thickness: float = 0.03
    noise: bool = True
    quantize: bool = False
    dropout: float = 0.002
    max_range: float = 4.0
    projector_offset: float = 0.075
    seed: Optional[int] = 0
    objects: List[scene_objects.Obj] = field(default_factory=list)

    def validate(self):
        """Raises PerceptionError naming the first value that cannot make a scene."""
        if not self.camera_distance > 0:
            raise PerceptionError(f"camera_distance must be > 0 m, got {self.camera_distance}")
        if not 0 < self.tilt <= np.pi / 2:
            raise PerceptionError(f"tilt must be in (0, pi/2] rad (camera looking down), got {self.tilt}")
        if not (self.table_size[0] > 0 and self.table_size[1] > 0 and self.table_height > 0
                and self.table_thickness > 0 and self.table_thickness < self.table_height):
            raise PerceptionError("table_size, table_height and table_thickness must be > 0 m "
                                  "(thickness below the height)")
        if not 0 <= self.dropout < 1:
            raise PerceptionError(f"dropout must be a fraction in [0, 1), got {self.dropout}")
        if not self.max_range > 0:
            raise PerceptionError(f"max_range must be > 0 m, got {self.max_range}")
        half = np.asarray(self.table_size, dtype=float) / 2
        for i, can in enumerate(self.cans):
            if len(can) != 4:
                raise PerceptionError(f"can {i} must be (x, y, radius, height), got {can}")
            x, y, r, h = can
            if not (r > 0 and h > 0):
                raise PerceptionError(f"can {i}: radius and height must be > 0 m, got {r}, {h}")
            if abs(x) + r > half[0] or abs(y) + r > half[1]:
                raise PerceptionError(f"can {i} at ({x}, {y}) overhangs the table "
                                      f"(half-size {half[0]} x {half[1]} m); move it onto the table")
        for i, box in enumerate(self.boxes):
            if len(box) != 5:
                raise PerceptionError(f"box {i} must be (x, y, size_x, size_y, size_z), got {box}")
            if not all(s > 0 for s in box[2:]):
                raise PerceptionError(f"box {i}: sizes must be > 0 m, got {box[2:]}")
        for obj in self.objects:
            obj.validate()


@dataclass
class Scene:
    """A generated scene. xyz: float32 (480, 640, 3) camera frame, metres, NaN where no return;
    rgb: uint8 (480, 640, 3); labels: int16 (480, 640), the surface each ray hit (LABEL_*), also
    where no depth returned; truth: JSON-able dict (see generate_scene); spec: what was asked."""

    xyz: np.ndarray
    rgb: np.ndarray
    labels: np.ndarray
    truth: dict
    spec: SceneSpec


# --- camera -------------------------------------------------------------------------------------


def intrinsics():
    """The simulated Kinect's depth camera: dict of width, height (px), fx, fy, cx, cy (px)."""
    return {"width": WIDTH, "height": HEIGHT, "fx": FX, "fy": FY, "cx": CX, "cy": CY}


def pixel_rays(width=WIDTH, height=HEIGHT):
    """Ray direction of every pixel in the camera frame, scaled so z = 1: float64 (H, W, 3).

    A hit at parameter t along such a ray has depth z = t, which is how the Kinect reports range.
    """
    u, v = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    return np.stack([(u - CX) / FX, (v - CY) / FY, np.ones_like(u)], axis=-1)


def camera_pose(spec):
    """T_table_from_camera (4x4 float64) for the spec: optical axis through the aim point, pitched
    `tilt` down from horizontal, heading `yaw`, `camera_distance` back from the aim point."""
    aim = np.array([spec.cans[0][0], spec.cans[0][1], 0.0]) if spec.cans else np.zeros(3)
    heading = np.array([-np.sin(spec.yaw), np.cos(spec.yaw), 0.0])  # horizontal, table frame
    z_cam = np.cos(spec.tilt) * heading + np.array([0.0, 0.0, -np.sin(spec.tilt)])
    x_cam = np.array([np.cos(spec.yaw), np.sin(spec.yaw), 0.0])  # horizontal: the camera does not roll
    y_cam = np.cross(z_cam, x_cam)  # points down-ish: optical frame is x right, y down, z forward
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = x_cam, y_cam, z_cam
    T[:3, 3] = aim - spec.camera_distance * z_cam
    return T


# --- ray casting in the table frame ---------------------------------------------------------------
# Each intersector takes ray origins o and directions d ((N, 3), table frame) and the smallest
# accepted parameter t_min, and returns (t, normal, face): t (N,) with inf for a miss, unit outward
# normals (N, 3), and an int face code (N,) for labelling.


def _hit_plane_z(o, d, z, t_min):
    """Horizontal plane at height z, seen from either side (the floor, the table top)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z - o[:, 2]) / d[:, 2]
    t = np.where(np.isfinite(t) & (t > t_min), t, np.inf)
    normal = np.zeros_like(o)
    normal[:, 2] = 1.0
    return t, normal


def _hit_box(o, d, lo, hi, t_min):
    """Axis-aligned box [lo, hi] by the slab method; only rays entering it from outside count, so
    a segment that starts on the box's own surface does not hit it (no self-shadowing of faces)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(d == 0, 1e-300, d)  # keep the sign-less zero from making 0/0 = NaN
        t1 = (lo - o) * inv
        t2 = (hi - o) * inv
    t_lo = np.minimum(t1, t2)
    t_hi = np.maximum(t1, t2)
    face = np.argmax(t_lo, axis=1)
    t_near = t_lo[np.arange(len(o)), face]
    t_far = np.min(t_hi, axis=1)
    hit = (t_near <= t_far) & (t_near > t_min)
    t = np.where(hit, t_near, np.inf)
    normal = np.zeros_like(o)
    normal[np.arange(len(o)), face] = -np.sign(d[np.arange(len(o)), face])
    return t, normal, face


def _hit_can(o, d, cx, cy, r, h, t_min):
    """Upright cylinder of radius r from z = 0 to z = h, axis at (cx, cy), closed by a top disc.

    Returns (t, normal, is_top). Both side roots are tried, so a segment starting on the side and
    passing through the can hits its far side (the can shadows its own back from the projector).
    """
    ox, oy = o[:, 0] - cx, o[:, 1] - cy
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2 * (ox * d[:, 0] + oy * d[:, 1])
    c = ox ** 2 + oy ** 2 - r * r
    disc = b * b - 4 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        roots = np.stack([(-b - sq) / (2 * a), (-b + sq) / (2 * a)], axis=1)
    z = o[:, 2:3] + roots * d[:, 2:3]
    ok = np.isfinite(roots) & (roots > t_min) & (z >= 0) & (z <= h)
    roots = np.where(ok, roots, np.inf)
    t_side = roots.min(axis=1)
    t_top, _ = _hit_plane_z(o, d, h, t_min)
    with np.errstate(invalid="ignore"):
        px = ox + t_top * d[:, 0]
        py = oy + t_top * d[:, 1]
        t_top = np.where(px ** 2 + py ** 2 <= r * r, t_top, np.inf)
    is_top = t_top < t_side
    t = np.minimum(t_side, t_top)
    normal = np.zeros_like(o)
    with np.errstate(invalid="ignore"):
        p = o + np.where(np.isfinite(t), t, 0)[:, None] * d
    normal[:, 0] = (p[:, 0] - cx) / r
    normal[:, 1] = (p[:, 1] - cy) / r
    normal[is_top] = (0.0, 0.0, 1.0)
    return t, normal, is_top


def _cast(spec, o, d, t_min):
    """Nearest hit of each ray over every surface of the scene: (t, label, normal)."""
    n = len(o)
    t_best = np.full(n, np.inf)
    label = np.full(n, LABEL_NONE, dtype=np.int16)
    normal = np.zeros((n, 3))

    def take(t, lab, nrm):
        closer = t < t_best
        t_best[closer] = t[closer]
        label[closer] = lab[closer] if np.ndim(lab) else lab
        normal[closer] = nrm[closer]

    t, nrm = _hit_plane_z(o, d, -spec.table_height, t_min)
    take(t, LABEL_FLOOR, nrm)

    half = np.array([spec.table_size[0] / 2, spec.table_size[1] / 2, 0.0])
    lo = np.array([-half[0], -half[1], -spec.table_thickness])
    t, nrm, face = _hit_box(o, d, lo, half, t_min)
    take(t, np.where(face == 2, LABEL_TABLE, LABEL_TABLE_EDGE).astype(np.int16), nrm)

    for i, (cx, cy, r, h) in enumerate(spec.cans):
        t, nrm, is_top = _hit_can(o, d, cx, cy, r, h, t_min)
        take(t, np.where(is_top, LABEL_CAN_TOP + i, LABEL_CAN_SIDE + i).astype(np.int16), nrm)

    for i, (bx, by, sx, sy, sz) in enumerate(spec.boxes):
        lo = np.array([bx - sx / 2, by - sy / 2, 0.0])
        hi = np.array([bx + sx / 2, by + sy / 2, sz])
        t, nrm, _ = _hit_box(o, d, lo, hi, t_min)
        take(t, LABEL_BOX + i, nrm)

    for i, obj in enumerate(spec.objects):
        t, nrm = scene_objects.hit_object(obj, o, d, t_min)
        take(t, LABEL_OBJECT + i, nrm)
    return t_best, label, normal


def _base_colours(labels):
    rgb = np.zeros(labels.shape + (3,))
    for lab, name in ((LABEL_FLOOR, "floor"), (LABEL_TABLE, "table"), (LABEL_TABLE_EDGE, "table_edge")):
        rgb[labels == lab] = _COLOURS[name]
    rgb[(labels >= LABEL_CAN_SIDE) & (labels < LABEL_CAN_TOP)] = _COLOURS["can"]
    rgb[(labels >= LABEL_CAN_TOP) & (labels < LABEL_BOX)] = _COLOURS["can_top"]
    rgb[(labels >= LABEL_BOX) & (labels < LABEL_OBJECT)] = _COLOURS["box"]
    rgb[labels >= LABEL_OBJECT] = _COLOURS["object"]
    return rgb


# --- the scene ------------------------------------------------------------------------------------


def generate_scene(spec=None, rng=None):
    """Renders `spec` (default: the bundled scene, one soda can ~1 m away) as a Kinect would.

    rng: numpy.random.Generator for noise and dropout; default np.random.default_rng(spec.seed),
    so the same spec gives the same scene.

    Returns a Scene whose ``truth`` dict (camera frame, metres; all plain lists and floats) holds:
    ``camera`` (intrinsics, px), ``camera_from_table`` (4x4, maps table-frame points into the
    camera frame), ``projector`` (its position, camera frame), ``table`` (``normal``: unit, toward
    the camera; ``d``: normal . p + d = 0 on the top; ``center`` of the top; ``size``; ``height``
    above the floor), ``floor`` (``normal``, ``d``), ``cans`` (``base_center``: centre of the base
    on the table; ``axis``: unit, up away from the table; ``radius``; ``height``) and ``boxes``
    (``base_center``, ``axis``, ``x_axis``: the box's size_x direction, ``size``: [x, y, z]).
    """
    spec = SceneSpec() if spec is None else spec
    spec.validate()
    rng = np.random.default_rng(spec.seed) if rng is None else rng

    T_table_cam = camera_pose(spec)
    R, cam = T_table_cam[:3, :3], T_table_cam[:3, 3]
    rays_cam = pixel_rays().reshape(-1, 3)
    rays = rays_cam @ R.T  # same rays in the table frame; t along them is still the camera depth
    origins = np.broadcast_to(cam, rays.shape)
    depth, labels, normals = _cast(spec, origins, rays, t_min=1e-9)

    hit = np.isfinite(depth)
    returned = hit & (depth <= spec.max_range)

    # The projector's shadow: a point the projector cannot see gets no depth. The segment from the
    # point to the projector is cast with t in (t_min, 1); the point's own surface does not count.
    if spec.projector_offset > 0:
        projector = cam + spec.projector_offset * R[:, 0]
        idx = np.flatnonzero(returned)
        points = cam + depth[idx, None] * rays[idx]
        t_block, _, _ = _cast(spec, points, projector - points, t_min=1e-7)
        returned[idx[t_block < 1.0 - 1e-7]] = False

    # Shading by the angle between surface and ray, so the colour image shows shape.
    unit_rays = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    cos = np.abs(np.sum(normals * unit_rays, axis=1))
    rgb = _base_colours(labels) * (0.45 + 0.55 * cos)[:, None]

    # Random draws are made whatever the options, in a fixed order, so a seed means one scene.
    gauss = rng.standard_normal(depth.shape)
    drop = rng.random(depth.shape) < spec.dropout
    z = np.where(hit, depth, np.nan)
    if spec.noise:
        z = z + 1.425e-3 * z ** 2 * gauss
    if spec.quantize:
        # Disparity in 1/8 px over the projector-camera baseline, as the Kinect measures it.
        disparity = np.round(8 * FX * 0.075 / z) / 8
        z = FX * 0.075 / disparity
    returned &= ~drop
    z = np.where(returned, z, np.nan)
    xyz = (rays_cam * z[:, None]).astype(np.float32).reshape(HEIGHT, WIDTH, 3)

    # An object's base is seen when some of the lowest 2 cm of it returned depth.
    seen = np.flatnonzero(returned & (labels >= LABEL_OBJECT))
    heights = cam[2] + depth[seen] * rays[seen, 2]
    base_seen = [bool(np.any(heights[labels[seen] == LABEL_OBJECT + i] < obj.z + 0.02))
                 for i, obj in enumerate(spec.objects)]
    visible = np.bincount(labels[seen] - LABEL_OBJECT, minlength=len(spec.objects))

    return Scene(
        xyz=xyz,
        rgb=np.clip(np.round(rgb), 0, 255).astype(np.uint8).reshape(HEIGHT, WIDTH, 3),
        labels=labels.reshape(HEIGHT, WIDTH),
        truth=_truth(spec, T_table_cam, base_seen, visible),
        spec=spec,
    )


def _truth(spec, T_table_cam, base_seen=(), visible=()):
    T = transforms.invert(T_table_cam)  # camera_from_table
    R = T[:3, :3]
    up = R[:, 2]

    def to_cam(p):
        return transforms.apply(T, p)

    def plane(point):
        return {"normal": up.tolist(), "d": float(-up @ to_cam(point))}

    table = {**plane((0, 0, 0)), "center": to_cam((0, 0, 0)).tolist(),
             "size": [float(s) for s in spec.table_size], "height": float(spec.table_height)}
    cans = [{"base_center": to_cam((x, y, 0)).tolist(), "axis": up.tolist(), "radius": float(r),
             "height": float(h)} for x, y, r, h in spec.cans]
    boxes = [{"base_center": to_cam((x, y, 0)).tolist(), "axis": up.tolist(), "x_axis": R[:, 0].tolist(),
              "size": [float(sx), float(sy), float(sz)]} for x, y, sx, sy, sz in spec.boxes]
    return {
        "frame": "camera optical frame (x right, y down, z forward), metres",
        "camera": {k: (int(v) if k in ("width", "height") else float(v)) for k, v in intrinsics().items()},
        "camera_from_table": T.tolist(),
        "projector": [float(spec.projector_offset), 0.0, 0.0],
        "table": table,
        "floor": plane((0, 0, -spec.table_height)),
        "cans": cans,
        "boxes": boxes,
        "objects": [scene_objects.truth(obj, T, seen, int(n))
                    for obj, seen, n in zip(spec.objects, base_seen, visible)],
        "spec": json.loads(json.dumps(dataclasses.asdict(spec))),  # tuples become lists
    }


def truth_path(pcd_path):
    """Where the ground truth of a scene file lives: OUT.pcd -> OUT.json beside it."""
    return pathlib.Path(pcd_path).with_suffix(".json")


def can_pose_error(T_sensor_from_can, truth_can):
    """(centre error in m, axis error in degrees) of a can's pose (4x4: origin at the centre of its
    base, z along its axis) against a ground-truth can (the truth's ``cans[i]``: base_center, axis;
    same frame)."""
    T = np.asarray(T_sensor_from_can, dtype=float)
    centre_error = float(np.linalg.norm(T[:3, 3] - np.asarray(truth_can["base_center"])))
    cos = np.clip(T[:3, 2] @ np.asarray(truth_can["axis"]), -1.0, 1.0)
    return centre_error, float(np.degrees(np.arccos(cos)))


# --- command line ---------------------------------------------------------------------------------


def _parser():
    d = SceneSpec()
    p = argparse.ArgumentParser(
        prog="make_scene",
        description="Write a simulated Kinect scene (a table with soda cans, or one of the cases of "
                    "--case) as OUT.pcd, with its ground truth (camera frame) as OUT.json beside it.")
    p.add_argument("out", metavar="OUT.pcd", help="the PCD file to write")
    p.add_argument("--case", choices=scene_objects.CASES, metavar="CASE",
                   help="one of the issue 13 cases, its objects and camera drawn from --seed: "
                        + ", ".join(f"'{c}'" for c in scene_objects.CASES) + " (not with --can or --box)")
    p.add_argument("--distance", type=float,
                   help=f"camera to the first can's base along the view, m (default {d.camera_distance}; "
                        "with --case, the case's)")
    p.add_argument("--tilt", type=float,
                   help=f"camera pitch down from horizontal, rad (default {d.tilt}; with --case, the case's)")
    p.add_argument("--yaw", type=float, help=f"view heading about the table normal, rad (default {d.yaw}; "
                                             "with --case, the case's)")
    p.add_argument("--can", type=float, nargs=4, action="append", metavar=("X", "Y", "R", "H"),
                   help="a can: base centre x, y in the table frame, radius, height, m; repeat for "
                        "more cans (default: one soda can, 0 0 0.033 0.122)")
    p.add_argument("--box", type=float, nargs=5, action="append", metavar=("X", "Y", "SX", "SY", "SZ"),
                   help="a box: base centre x, y in the table frame and its sizes, m; repeatable")
    p.add_argument("--no-noise", dest="noise", action="store_false", help="exact depths")
    p.add_argument("--quantize", action="store_true", help="quantise depth as the Kinect's disparity")
    p.add_argument("--dropout", type=float, default=d.dropout,
                   help="fraction of pixels with no return at random (default %(default)s)")
    p.add_argument("--seed", type=int, default=d.seed,
                   help="random seed of the noise and dropout (and of --case's objects) (default %(default)s)")
    p.add_argument("--format", choices=("ascii", "binary", "binary_compressed"), default="binary_compressed",
                   help="PCD data format (default %(default)s)")
    return p


def main(argv=None):
    """make_scene OUT.pcd [options]: writes OUT.pcd and OUT.json; returns the exit status."""
    parser = _parser()
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    if out.suffix != ".pcd":
        parser.error(f"OUT must end in .pcd, got {out}")
    if args.case is not None:
        if args.can or args.box:
            parser.error("--case draws its own objects: give no --can or --box with it")
        spec = scene_objects.case_spec(args.case, args.seed)
    else:
        spec = SceneSpec(cans=[tuple(c) for c in args.can] if args.can else SceneSpec().cans,
                         boxes=[tuple(b) for b in args.box or []], seed=args.seed)
    camera = {name: value for name, value in (("camera_distance", args.distance), ("tilt", args.tilt),
                                              ("yaw", args.yaw)) if value is not None}
    spec = dataclasses.replace(spec, **camera, noise=args.noise, quantize=args.quantize, dropout=args.dropout)
    try:
        scene = generate_scene(spec)
    except PerceptionError as e:
        parser.error(str(e))

    from example_pcl.pcd import write_cloud  # needs the compiled extension; scene.py itself does not

    json_path = truth_path(out)
    tmp = json_path.with_name(json_path.name + ".tmp")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_cloud(str(out), scene.xyz, rgb=scene.rgb, fmt=args.format)
        tmp.write_text(json.dumps(scene.truth, indent=2) + "\n")
        tmp.replace(json_path)  # atomic, like write_cloud: a reader never sees half a file
    except OSError as e:
        print(f"make_scene: cannot write {out} / {json_path}: {e}", file=sys.stderr)
        return 1
    valid = int(np.isfinite(scene.xyz[..., 2]).sum())
    what = (f"'{args.case}' seed {args.seed}: " + ", ".join(o["kind"] for o in scene.truth["objects"])
            if args.case is not None else f"{len(spec.cans)} can(s), {len(spec.boxes)} box(es)")
    print(f"wrote {out} ({valid} of {WIDTH * HEIGHT} points with depth, {what}) and {json_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
