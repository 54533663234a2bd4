"""Generated moving sequences for the tracker: the scene generator frame after frame, with truth.

Pure NumPy; knows nothing of ROS. Each frame is an :func:`example_pcl.scene.generate_scene` scene
whose camera drifts slowly (distance, tilt and yaw change a little per frame) while cans appear,
move along smooth paths (cosine ease between keyframes) and disappear. Per frame the truth gives
every can present with a stable ``id`` (the SequenceCan's truth_id) and its base centre, axis,
radius and height in that frame's camera frame (metres), as generate_scene's truth does.

The camera aims at the first can of the sequence (scene.camera_pose aims at the scene's first
can), which must therefore be present in every frame; it is static in the default sequence.

Rendering a 640x480 frame takes a few tenths of a second: :func:`render_sequence` renders a
sequence once and caches it in an ``.npz`` file keyed by the spec, for tests and benchmarks.
"""
import dataclasses
import hashlib
import json
import os
import pathlib
import tempfile
from dataclasses import dataclass, field
from typing import List, Optional, Tuple

import numpy as np

from example_pcl import scene as sc
from example_pcl import scene_objects
from example_pcl.errors import PerceptionError

# Bumped when the rendering of a given spec changes, so stale cache files are not used.
_CACHE_VERSION = 2


@dataclass(frozen=True)
class SequenceCan:
    """One can of a sequence. truth_id: its id in the truth; radius, height (m); keyframes:
    ((frame, x, y), ...) base centre in the table frame (m) at those frames, sorted by frame; the
    can is at the first keyframe's position before it and at the last one's after it, and moves
    between consecutive keyframes with a cosine ease (at rest at each keyframe). first, last:
    the frames (inclusive) it is on the table; last None = to the end. lying: the can lies on its
    side (scene_objects' lying_can: height is its length, (x, y) the middle of its axis seen from
    above), its axis along yaw (rad, table frame)."""

    truth_id: int
    radius: float
    height: float
    keyframes: Tuple[Tuple[int, float, float], ...]
    first: int = 0
    last: Optional[int] = None
    lying: bool = False
    yaw: float = 0.0

    def present(self, frame):
        """Whether the can is on the table in `frame`."""
        return self.first <= frame and (self.last is None or frame <= self.last)

    def position(self, frame):
        """(x, y) base centre in the table frame (m) at `frame` (a float frame is fine)."""
        keys = self.keyframes
        if frame <= keys[0][0]:
            return float(keys[0][1]), float(keys[0][2])
        for (f0, x0, y0), (f1, x1, y1) in zip(keys, keys[1:]):
            if frame <= f1:
                s = (1 - np.cos(np.pi * (frame - f0) / (f1 - f0))) / 2
                return float(x0 + s * (x1 - x0)), float(y0 + s * (y1 - y0))
        return float(keys[-1][1]), float(keys[-1][2])


def _default_cans():
    return [
        SequenceCan(0, 0.033, 0.122, ((0, 0.0, 0.0),)),
        SequenceCan(1, 0.04, 0.10, ((0, 0.16, 0.04),), last=19),
        SequenceCan(2, 0.028, 0.11, ((12, -0.15, 0.05), (24, -0.13, 0.075)), first=6),
    ]


@dataclass(frozen=True)
class SequenceSpec:
    """A moving sequence. n_frames; rate (Hz): frame i is stamped i / rate (s).

    Camera (see scene.SceneSpec): camera_distance (m), tilt, yaw (rad) at frame 0, changed by
    distance_step (m), tilt_step and yaw_step (rad) per frame. cans: SequenceCan list (the
    first is the camera's aim and must be present in every frame); boxes: static
    (x, y, size_x, size_y, size_z) in the table frame (m). noise, dropout: as in SceneSpec; seed:
    frame i uses seed + i (None: a fresh random draw each time, which the cache cannot reuse).

    The default: 30 frames at 30 Hz, the camera drifting 1 mm, 1 mrad of tilt and 2 mrad of yaw
    per frame; a static soda can (id 0) all along, a wider can (id 1) removed after frame 19, a
    narrow can (id 2) added at frame 6 and moved 3 cm between frames 12 and 24.
    """

    n_frames: int = 30
    rate: float = 30.0
    camera_distance: float = 1.0
    distance_step: float = 0.001
    tilt: float = 0.9
    tilt_step: float = 0.001
    yaw: float = 0.0
    yaw_step: float = 0.002
    cans: List[SequenceCan] = field(default_factory=_default_cans)
    boxes: List[Tuple[float, float, float, float, float]] = field(default_factory=list)
    noise: bool = True
    dropout: float = 0.002
    seed: Optional[int] = 0

    def validate(self):
        """Raises PerceptionError naming the first value that cannot make a sequence."""
        if not (int(self.n_frames) >= 1 and self.rate > 0):
            raise PerceptionError(f"a sequence needs n_frames >= 1 and rate > 0 Hz, got {self.n_frames}, {self.rate}")
        if not self.cans or self.cans[0].lying or not all(self.cans[0].present(i) for i in range(self.n_frames)):
            raise PerceptionError("the first can is the camera's aim: it must stand upright in every frame")
        ids = [c.truth_id for c in self.cans]
        if len(set(ids)) != len(ids):
            raise PerceptionError(f"truth ids must be unique, got {ids}")
        for c in self.cans:
            frames = [k[0] for k in c.keyframes]
            if not frames or frames != sorted(set(frames)):
                raise PerceptionError(f"can {c.truth_id}: keyframes must be non-empty and strictly increasing in frame")

    def scene_spec(self, frame):
        """The scene.SceneSpec of `frame` (0-based)."""
        present = [c for c in self.cans if c.present(frame)]
        lying = [scene_objects.Obj("lying_can", *c.position(frame), radius=c.radius, height=c.height, yaw=c.yaw)
                 for c in present if c.lying]
        return sc.SceneSpec(
            camera_distance=self.camera_distance + frame * self.distance_step,
            tilt=self.tilt + frame * self.tilt_step, yaw=self.yaw + frame * self.yaw_step,
            cans=[(*c.position(frame), c.radius, c.height) for c in present if not c.lying], boxes=list(self.boxes),
            noise=self.noise, dropout=self.dropout, seed=None if self.seed is None else self.seed + frame,
            objects=lying)

    def truth_ids(self, frame):
        """The truth ids of the cans present in `frame`: the upright ones in the order of
        scene_spec(frame).cans, then the lying ones in the order of its objects."""
        present = [c for c in self.cans if c.present(frame)]
        return [c.truth_id for c in present if not c.lying] + [c.truth_id for c in present if c.lying]


@dataclass(frozen=True, eq=False)
class Frame:
    """One rendered frame: index; stamp (s); xyz float32 (480, 640, 3) camera frame (m, NaN
    holes); rgb uint8 (480, 640, 3) or None; truth: dict with ``cans`` (each ``id``,
    ``base_center``, ``axis``, ``radius``, ``height``, ``lying``; camera frame, m), ``table`` and
    ``camera_from_table`` as in generate_scene's truth."""

    index: int
    stamp: float
    xyz: np.ndarray
    rgb: Optional[np.ndarray]
    truth: dict


def render_frame(spec, index, with_rgb=False):
    """Renders frame `index` of the SequenceSpec: a Frame."""
    spec.validate()
    scene = sc.generate_scene(spec.scene_spec(index))
    upright = [{**c, "lying": False} for c in scene.truth["cans"]]
    lying = [{k: c[k] for k in ("base_center", "axis", "radius", "height", "lying")} for c in scene.truth["objects"]]
    cans = [{"id": i, **c} for i, c in zip(spec.truth_ids(index), upright + lying)]
    truth = {"cans": cans, "table": scene.truth["table"], "camera_from_table": scene.truth["camera_from_table"]}
    return Frame(index=index, stamp=index / spec.rate, xyz=scene.xyz, rgb=scene.rgb if with_rgb else None,
                 truth=truth)


def frames(spec, with_rgb=False):
    """Renders the sequence frame by frame: a generator of Frame (nothing cached)."""
    for i in range(int(spec.n_frames)):
        yield render_frame(spec, i, with_rgb)


def _spec_key(spec, with_rgb):
    text = json.dumps({"v": _CACHE_VERSION, "rgb": bool(with_rgb), "spec": dataclasses.asdict(spec)}, sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def default_cache_dir():
    """Where render_sequence caches by default: $EXAMPLE_PCL_CACHE or <tmp>/example_pcl_sequences."""
    return pathlib.Path(os.environ.get("EXAMPLE_PCL_CACHE") or
                        pathlib.Path(tempfile.gettempdir()) / "example_pcl_sequences")


def render_sequence(spec=None, cache_dir=None, with_rgb=False):
    """Every Frame of the sequence (default SequenceSpec()), as a list, rendered once and cached.

    cache_dir: folder of the cache (default default_cache_dir()); False renders without
    caching. The file is named by a hash of the spec (and with_rgb), written atomically; a spec
    with seed None is never cached (each render differs).
    """
    spec = SequenceSpec() if spec is None else spec
    spec.validate()
    if cache_dir is False or spec.seed is None:
        return list(frames(spec, with_rgb))
    path = pathlib.Path(cache_dir or default_cache_dir()) / f"sequence_{_spec_key(spec, with_rgb)}.npz"
    if path.exists():
        try:
            with np.load(path) as data:
                truth = json.loads(str(data["truth"]))
                rgb = data["rgb"] if with_rgb else None
                return [Frame(index=i, stamp=float(data["stamps"][i]), xyz=data["xyz"][i],
                              rgb=None if rgb is None else rgb[i], truth=truth[i]) for i in range(len(truth))]
        except (OSError, ValueError, KeyError):
            pass  # a damaged cache file is rendered again
    out = list(frames(spec, with_rgb))
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {"xyz": np.stack([f.xyz for f in out]), "stamps": np.array([f.stamp for f in out]),
              "truth": np.array(json.dumps([f.truth for f in out]))}
    if with_rgb:
        arrays["rgb"] = np.stack([f.rgb for f in out])
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz.tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    except OSError:
        pathlib.Path(tmp).unlink(missing_ok=True)  # caching is a convenience: the frames are returned anyway
    return out
