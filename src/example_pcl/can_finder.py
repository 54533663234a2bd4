"""The find_can pipeline without ROS: the seed's interactive can registration as one class.

The operator's flow, which :class:`CanFinder` enforces with explicit preconditions:

1. select a patch on the table (``select``, or ``select_near`` for a clicked point);
2. mode 0, IDENTIFY_PLANE: the table plane from the patch, refined from the cloud's points near it;
3. mode 1, FIND_PNTS_ABOVE_PLANE: the points standing on the table;
4. select a patch on the side of the can facing the sensor (any selection made after mode 0 is
   the can patch; the latest selection wins);
5. mode 2, COMPUTE_CYLINDRICAL_FIT_ERR_INIT: the first guess of the can's axis and its radial error;
6. mode 3, COMPUTE_CYLINDRICAL_FIT_ERR_ITERATE: the axis fitted to the can's points, run to
   convergence.

Mode 4, FIND_CAN_AUTO, needs no selection: example_pcl.auto_finder finds the table and every
can on it (upright or lying), radius unknown; the best can becomes the current estimate, so modes 0-3
and mode 4 share their outputs.

Everything is in the sensor frame (the cloud's frame, metres) unless named "plane frame" (z along
the table normal, origin on the table; see example_pcl.geometry). Each mode returns a
:class:`StepResult` carrying the one-line message for the operator and the points to show; a
step that cannot run raises :class:`~example_pcl.errors.PerceptionError` saying what to do next
and leaves the state as it was.
"""
import dataclasses
import enum
from dataclasses import dataclass
from typing import Optional

import numpy as np

from example_pcl import _native
from example_pcl import auto_finder
from example_pcl import geometry
from example_pcl import transforms
from example_pcl.can import Can
from example_pcl.errors import PerceptionError


class Mode(enum.IntEnum):
    """The process_mode service's modes, numbered as in the seed."""

    IDENTIFY_PLANE = 0
    FIND_PNTS_ABOVE_PLANE = 1
    COMPUTE_CYLINDRICAL_FIT_ERR_INIT = 2
    COMPUTE_CYLINDRICAL_FIT_ERR_ITERATE = 3
    FIND_CAN_AUTO = 4


def describe_modes():
    """'0 IDENTIFY_PLANE, 1 FIND_PNTS_ABOVE_PLANE, ...' for messages."""
    return ", ".join(f"{m.value} {m.name}" for m in Mode)


@dataclass(frozen=True)
class FinderConfig:
    """Tolerances and the can's size, in metres.

    z_eps: half-width of the table band (plane inliers, and can-patch points dropped as table);
    z_threshold: height above the table that counts as "above"; can_radius, can_height: the can
    model of modes 2 and 3 (after mode 4, they fit the size of the can it found instead); r_eps: mode 3 leaves out points whose radial residual exceeds it (must be at least about
    half the initial guess's error); max_iterations: of one mode 3 fit; fit_margin: mode 3 uses the
    points above the table within can_radius + fit_margin of the current centre (plane frame x, y)
    and below can_height + fit_margin; refine_iterations: at most, of mode 0's plane refinement;
    refine_points: about how many points of the cloud the refinement fits (a regular subsample;
    the inliers are then taken from the whole cloud); viewpoint: the sensor's position (sensor
    frame), toward which normals are turned.
    """

    z_eps: float = 0.01
    z_threshold: float = 0.01
    can_radius: float = 0.033
    can_height: float = 0.122
    r_eps: float = 0.01
    max_iterations: int = 50
    fit_margin: float = 0.02
    refine_iterations: int = 5
    refine_points: int = 20000
    viewpoint: tuple = (0.0, 0.0, 0.0)
    auto: auto_finder.AutoConfig = auto_finder.AutoConfig()

    def validate(self):
        """Raises PerceptionError naming the first value that cannot work."""
        for name in ("z_eps", "can_radius", "can_height", "r_eps"):
            if not getattr(self, name) > 0:
                raise PerceptionError(f"{name} must be > 0 m, got {getattr(self, name)}")
        for name in ("z_threshold", "fit_margin"):
            if not getattr(self, name) >= 0:
                raise PerceptionError(f"{name} must be >= 0 m, got {getattr(self, name)}")
        for name in ("max_iterations", "refine_iterations", "refine_points"):
            if not int(getattr(self, name)) >= 1:
                raise PerceptionError(f"{name} must be >= 1, got {getattr(self, name)}")
        if len(self.viewpoint) != 3 or not np.isfinite(np.asarray(self.viewpoint, dtype=float)).all():
            raise PerceptionError(f"viewpoint must be 3 finite numbers (m), got {self.viewpoint}")


@dataclass(frozen=True, eq=False)
class StepResult:
    """What a mode did. message: one line for the operator, with the numbers; model: float32 (N, 3)
    sensor-frame points to show as plane_model (the plane's inliers, the points above it, or the
    can model at the estimate); can: the estimate after modes 2, 3 and 4 (mode 4: the best can),
    else None; cans: mode 4's every Can, best first (empty for the other modes)."""

    mode: Mode
    message: str
    model: np.ndarray
    can: Optional[Can] = None
    cans: tuple = ()


@dataclass(frozen=True, eq=False)
class _Selection:
    points: Optional[np.ndarray]  # float64 (N, 3), sensor frame; None when rejected
    problem: Optional[str]  # why it cannot be used, for the next mode that needs it
    serial: int


def _fmt(v, digits=3):
    return "(" + ", ".join(f"{x:.{digits}f}" for x in v) + ")"


class CanFinder:
    """The pipeline's state over one scene and one step per mode.

    scene: float32 (N, 3) or (H, W, 3) sensor-frame cloud (m), NaN where no return; kept as
    given (no copy for a float32 array, which must then not change). config: FinderConfig.
    """

    def __init__(self, scene, config=FinderConfig()):
        config.validate()
        self.config = config
        self._selection = None
        self._serial = 0
        self.set_scene(scene)

    def set_scene(self, scene):
        """Takes a new scene (as the constructor's): the table and everything after it are
        forgotten, the latest selection is kept (e.g. a live cloud replacing the last one)."""
        self.scene = geometry.as_points_float32(scene)
        self._take_sample()
        self.reset()

    def set_config(self, config):
        """Takes new tolerances (FinderConfig) for the next step; the state is kept. The size modes 2
        and 3 fit follows the configured one unless mode 4 measured the can. Raises
        PerceptionError (nothing changed) for a config that cannot work."""
        config.validate()
        config.auto.validate()
        old, self.config = self.config, config
        if (self.can_radius, self.can_height) == (old.can_radius, old.can_height):
            self.can_radius, self.can_height = config.can_radius, config.can_height
        self._take_sample()

    def _take_sample(self):
        flat = self.scene.reshape(-1, 3)
        # The refinement's subsample, a strided view: every step^2-th point of the flattened scene
        # (the same points as every 16th for a 640x480 scene), at most refine_points of them.
        self._sample = geometry.subsample(flat, int(np.ceil(np.sqrt(len(flat) / self.config.refine_points))))

    # --- state ------------------------------------------------------------------------------------

    def reset(self):
        """Forgets the plane and everything after it (the latest selection is kept)."""
        self.plane = None  # geometry.Plane, sensor frame
        self.T_sensor_from_plane = None
        self.plane_indices = None  # int64 indices (flattened scene) of the table's inliers
        self._scene_in_plane = None  # float32, the scene in the plane frame, same shape as the scene
        self._table_serial = -1  # the latest selection's serial when mode 0 or 4 set the table
        self.above_indices = None  # int64 indices of the points above the table
        self.can_patch = None  # float64 (K, 3) sensor frame, as used by mode 2
        self.can = None  # Can
        # The size modes 2 and 3 fit: the configured one, or the size of the can mode 4 found.
        self.can_radius, self.can_height = self.config.can_radius, self.config.can_height

    @property
    def has_can_patch(self):
        """A selection made after the table was identified is waiting (or was used) as the can patch."""
        return self._selection is not None and self._selection.serial > self._table_serial

    def select(self, points):
        """Stores the operator's latest selection (sensor frame, m; (N, 3) or (H, W, 3)); returns
        how many finite points it has. Before mode 0 it is the table patch, after it the can patch.
        The selection is checked when a mode uses it, so a bad one fails that mode with a reason."""
        pts = np.asarray(points, dtype=float)
        if pts.size and pts.shape[-1] != 3:
            return self.reject_selection(f"a selection must be points of shape (N, 3), got shape {pts.shape}")
        pts = pts.reshape(-1, 3)
        self._serial += 1
        self._selection = _Selection(points=pts, problem=None, serial=self._serial)
        return int(np.isfinite(pts).all(axis=1).sum())

    def reject_selection(self, problem):
        """Records a selection that cannot be used (e.g. in an unknown frame): the mode that would
        use it fails with `problem`, so an older patch is never used by mistake."""
        self._serial += 1
        self._selection = _Selection(points=None, problem=problem, serial=self._serial)
        return 0

    def points_near(self, center, radius):
        """The scene's points within `radius` (m) of `center` (sensor frame, m): float32 (K, 3).
        What a clicked point selects."""
        center = geometry.as_vector3(center, "the clicked point")
        d2 = _native.squared_distances(self.scene, center)
        return _native.extract(self.scene, np.flatnonzero(d2.reshape(-1) <= radius * radius).astype(np.int64))

    def select_near(self, center, radius):
        """select(points_near(center, radius)); returns how many points were selected."""
        return self.select(self.points_near(center, radius))

    def _selected_points(self, what):
        sel = self._selection
        if sel is None:
            raise PerceptionError(f"no patch selected; select a patch on {what} first")
        if sel.problem is not None:
            raise PerceptionError(f"the last selection cannot be used ({sel.problem}); select a patch on {what} again")
        if len(sel.points) == 0:
            raise PerceptionError(f"the selection is empty; select a patch on {what}")
        if not np.isfinite(sel.points).all(axis=1).any():
            raise PerceptionError(f"the selection has no finite points (all NaN or inf); select a patch on {what}")
        return sel.points

    # --- modes ------------------------------------------------------------------------------------

    def process(self, mode, up=None):
        """Runs one mode (int or Mode); returns its StepResult or raises PerceptionError.

        up: mode 4's prior, the table's up direction in the sensor frame (3 numbers, any length
        but zero), replacing config.auto.up for this call; modes 0-3 have no use for it.
        """
        try:
            mode = Mode(int(mode))
        except (TypeError, ValueError):
            raise PerceptionError(f"unknown mode {mode!r}; use {describe_modes()}") from None
        if mode == Mode.FIND_CAN_AUTO:
            return self.find_cans_auto(up)
        return {
            Mode.IDENTIFY_PLANE: self.identify_plane,
            Mode.FIND_PNTS_ABOVE_PLANE: self.find_points_above_plane,
            Mode.COMPUTE_CYLINDRICAL_FIT_ERR_INIT: self.initial_fit,
            Mode.COMPUTE_CYLINDRICAL_FIT_ERR_ITERATE: self.iterate_fit,
        }[mode]()

    def find_cans_auto(self, up=None):
        """Mode 4: every can on the table (upright or lying), no selection (example_pcl.auto_finder.find_cans).

        up: the table's up direction (sensor frame), replacing config.auto.up when given; only
        planes within config.auto.max_tilt of it are taken for the table. The table becomes the
        current plane, as after mode 0 (mode 1 can follow; only a selection made after mode 4 is the
        can patch), and the best can (the best-measured, first in the list) the current estimate,
        as after mode 3: modes 2 and 3 then fit a can of its radius and height (until mode 0 brings
        back the configured size). No can found is a failure saying why (up to three objects on the table with
        the criterion each failed), and the state is kept.
        """
        cfg = self.config
        auto = cfg.auto if up is None else dataclasses.replace(cfg.auto, up=tuple(geometry.unit_vector(up, "up")))
        found = auto_finder.find_cans(self.scene, cfg.viewpoint, auto)
        if not found.cans:
            reasons = "".join(f"; object {i + 1} ({r.n_points} points at {_fmt(r.centroid)} m): {r.reason}"
                              for i, r in enumerate(found.rejected[:3]))
            raise PerceptionError(f"{found.message}{reasons}; with several objects or a cluttered table, try the "
                                  "operator modes 0-3")
        best = found.cans[0]
        self._set_table(found.table, found.T_sensor_from_plane)
        self.can = best
        self.can_radius, self.can_height = best.radius, best.height
        models = [_native.transform_cloud(geometry.make_can_cloud(c.radius, c.height), c.T_sensor_from_can)
                  for c in found.cans]
        origin, size = ("lying, end centre", "length") if best.lying else ("base centre", "height")
        cut = ", its far end beyond the image's edge" if not best.end_seen else ""
        message = (f"{found.message}; best: {origin} {_fmt(best.base_center)} m, radius {best.radius * 1e3:.1f} mm, "
                   f"{size} {best.height * 1e3:.0f} mm{cut}, RMS radial error {best.rms_error * 1e3:.1f} mm over "
                   f"{best.n_fit_points} points ({found.timings['total'] * 1e3:.0f} ms)")
        return StepResult(Mode.FIND_CAN_AUTO, message, np.concatenate(models), best, tuple(found.cans))

    def identify_plane(self):
        """Mode 0: the table plane from the latest selection.

        The patch is cleaned (geometry.clean_patch: NaN dropped, points beyond one standard
        deviation from the centroid dropped), its plane fitted by PCL's computePointNormal and
        turned toward the sensor; then refined (geometry.refine_plane, at most refine_iterations
        passes, until it stops moving) on a regular subsample of the cloud, so a small or tilted patch still
        gives the table; then the plane frame is put on it and the whole cloud transformed into it
        once, keeping the points within z_eps as the table's inliers.
        """
        cfg = self.config
        patch = geometry.patch_plane(self._selected_points("the table"), cfg.viewpoint)
        plane, T, _, iterations = geometry.refine_plane(self._sample, patch, cfg.z_eps, cfg.viewpoint,
                                                        iterations=cfg.refine_iterations, final_inliers=False)
        indices = self._set_table(plane, T)
        tilt = np.degrees(np.arccos(np.clip(abs(patch.normal @ plane.normal), 0, 1)))
        message = (f"table plane: normal {_fmt(plane.normal)}, d={plane.d:.3f} m, {len(indices)} inliers "
                   f"within {cfg.z_eps * 1e3:.0f} mm (refined in {iterations} iterations from a "
                   f"{patch.n_points}-point patch {tilt:.1f} deg off)")
        return StepResult(Mode.IDENTIFY_PLANE, message, _native.extract(self.scene, indices))

    def _set_table(self, plane, T_sensor_from_plane):
        """Makes `plane` (sensor frame) with its plane frame the current table, as modes 0 and 4
        leave it: everything after it forgotten, the scene in the plane frame, the inliers within
        z_eps; only a selection made from now on is the can patch. Returns the inliers' indices;
        raises PerceptionError (state kept) when fewer than 3 points lie on the plane."""
        z_eps = self.config.z_eps
        indices, in_plane = geometry.plane_inliers(self.scene, T_sensor_from_plane, z_eps)
        if len(indices) < 3:
            raise PerceptionError(f"only {len(indices)} point(s) lie within {z_eps} m of the plane; "
                                  "select a patch on the table")
        self.reset()
        self.plane, self.T_sensor_from_plane = plane, T_sensor_from_plane
        self.plane_indices, self._scene_in_plane = indices, in_plane
        self._table_serial = self._serial
        return indices

    def _require_plane(self):
        if self.plane is None:
            raise PerceptionError("no table plane yet; identify the table first: select a table patch and call mode 0")

    def _require_above(self):
        self._require_plane()
        if self.above_indices is None:
            raise PerceptionError("the points above the table are not found yet; call mode 1 first")

    def find_points_above_plane(self):
        """Mode 1: the points more than z_threshold above the table (not the table, not the floor
        below it), from the scene already in the plane frame."""
        self._require_plane()
        cfg = self.config
        indices = geometry.points_above_plane(self._scene_in_plane, cfg.z_threshold)
        if len(indices) == 0:
            raise PerceptionError(f"no point lies more than {cfg.z_threshold} m above the table; "
                                  "check the table patch (mode 0) or lower z_threshold")
        self.above_indices = indices
        message = (f"{len(indices)} points above the table (more than {cfg.z_threshold * 1e3:.0f} mm above it); "
                   "now select a patch on the can's side and call mode 2")
        return StepResult(Mode.FIND_PNTS_ABOVE_PLANE, message, _native.extract(self.scene, indices))

    def _can_points_plane(self, center):
        """Plane-frame points above the table near a centre (cx, cy): float64 (K, 3)."""
        cfg = self.config
        pts = _native.extract(self._scene_in_plane, self.above_indices).astype(float)
        reach = self.can_radius + cfg.fit_margin
        d2 = (pts[:, 0] - center[0]) ** 2 + (pts[:, 1] - center[1]) ** 2
        return pts[(d2 <= reach * reach) & (pts[:, 2] <= self.can_height - cfg.z_eps)]

    def _estimate(self, center, rms, arc, n_points, n_fit_points, iterations, converged):
        """The Can of the current size with its axis at `center` (cx, cy; m, plane frame)."""
        return Can(T_sensor_from_can=geometry.can_pose(self.T_sensor_from_plane, center[0], center[1]),
                   radius=self.can_radius, height=self.can_height, rms_error=rms, arc_coverage=arc,
                   n_points=n_points, n_fit_points=n_fit_points, center_plane=np.asarray(center, dtype=float),
                   iterations=iterations, converged=converged)

    def can_model(self, can=None):
        """The seed's can model (geometry.make_can_cloud) of a Can's radius and height at its pose
        (default the current can), in the sensor frame: float32 (N, 3)."""
        can = self.can if can is None else can
        model = geometry.make_can_cloud(can.radius, can.height)
        return _native.transform_cloud(model, can.T_sensor_from_can)

    def initial_fit(self):
        """Mode 2: the first guess of the can's axis and its radial error.

        The can patch (the latest selection made after mode 0) loses the points in the table band
        (plane-frame z <= max(z_eps, z_threshold)), is cleaned and fitted as every patch is; the
        can is taken upright on the table with its axis one radius beyond the patch centroid, away
        from the sensor (geometry.initial_can_center).
        """
        self._require_above()
        if not self.has_can_patch:
            raise PerceptionError("no can patch yet; select a patch on the side of the can facing the sensor "
                                  "(after mode 0), then call mode 2")
        cfg = self.config
        raw = self._selected_points("the can")
        finite = raw[np.isfinite(raw).all(axis=1)]
        T_plane_from_sensor = transforms.invert(self.T_sensor_from_plane)
        z = transforms.apply(T_plane_from_sensor, finite)[:, 2]
        band = max(cfg.z_eps, cfg.z_threshold)
        patch_pts = finite[z > band]
        if len(patch_pts) < 3:
            raise PerceptionError(f"the can patch has {len(patch_pts)} point(s) above the table band "
                                  f"({len(finite) - len(patch_pts)} on the table); select a larger patch on the can's side")
        patch = geometry.patch_plane(patch_pts, cfg.viewpoint)
        centroid_plane = transforms.apply(T_plane_from_sensor, patch.centroid)
        center = np.array(geometry.initial_can_center(centroid_plane, self.can_radius, T_plane_from_sensor[:3, 3]))
        pts = self._can_points_plane(center)
        residuals, _, _ = geometry.radial_error(pts, center[0], center[1], self.can_radius)
        near = np.abs(residuals) <= cfg.r_eps
        rms = float(np.sqrt(np.mean(residuals[near] ** 2))) if near.any() else float("nan")
        arc = geometry.arc_coverage(pts[near], center[0], center[1])
        can = self._estimate(center, rms, arc, len(pts), int(near.sum()), 0, True)
        self.can_patch, self.can = patch_pts, can
        message = (f"initial can centre {_fmt(can.base_center)} m: can patch of {patch.n_points} points "
                   f"({len(finite) - len(patch_pts)} table points dropped), moved "
                   f"{self.can_radius * 1e3:.0f} mm away from the sensor; RMS radial error "
                   f"{rms * 1e3:.1f} mm over {int(near.sum())} of {len(pts)} points within "
                   f"{cfg.r_eps * 1e3:.0f} mm; call mode 3 to fit")
        return StepResult(Mode.COMPUTE_CYLINDRICAL_FIT_ERR_INIT, message, self.can_model(can), can)

    def iterate_fit(self, rounds=3):
        """Mode 3: the can's axis (cx, cy) fitted to its points, run to convergence.

        Levenberg-Marquardt on the radial errors |p - c| - radius (the configured can_radius, or
        the radius of the can mode 4 found) with the analytic gradient
        (geometry.fit_cylinder_center), points beyond r_eps left out each iteration; the point set
        (the points above the table near the centre, see FinderConfig.fit_margin) is re-taken
        around the new centre and the fit repeated while the centre still moves by more than
        0.1 mm (at most `rounds` times). Starts from the current estimate (mode 2's, or the last
        fit's), so calling it again is harmless. A fit that does not converge within max_iterations
        raises PerceptionError but keeps its last centre, so calling mode 3 again continues it.
        """
        self._require_above()
        if self.can is None:
            raise PerceptionError("no initial can estimate yet; select a can patch and call mode 2 first")
        cfg = self.config
        center, iterations, fit, pts = self.can.center_plane, 0, None, None
        for _ in range(max(int(rounds), 1)):
            pts = self._can_points_plane(center)
            fit = geometry.fit_cylinder_center(pts, center, self.can_radius, cfg.r_eps,
                                               max_iterations=cfg.max_iterations)
            iterations += fit.iterations
            moved = np.linalg.norm(fit.center - center)
            center = fit.center
            if not fit.converged or moved < 1e-4:
                break
        can = self._estimate(center, fit.rms_error, fit.arc_coverage, len(pts), fit.n_inliers, iterations,
                             fit.converged)
        self.can = can
        if not fit.converged:
            raise PerceptionError(f"the fit did not converge in {iterations} iterations (RMS radial error "
                                  f"{fit.rms_error * 1e3:.1f} mm); call mode 3 again to continue or raise max_iterations")
        message = (f"can centre {_fmt(can.base_center)} m: converged in {iterations} iterations, RMS radial "
                   f"error {fit.rms_error * 1e3:.1f} mm, {fit.n_inliers} points "
                   f"({np.degrees(fit.arc_coverage):.0f} deg of arc); axis {_fmt(can.axis)}")
        return StepResult(Mode.COMPUTE_CYLINDRICAL_FIT_ERR_ITERATE, message, self.can_model(can), can)
