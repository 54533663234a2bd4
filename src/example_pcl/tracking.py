"""Tracking cans over frames: stable ids, smoothed poses, velocities. Pure NumPy (and SciPy's
assignment), knows nothing of ROS.

:class:`CanTracker` takes each frame's detections - any objects with ``base_center`` (float (3,),
m), ``axis`` (unit (3,)), ``radius``, ``height`` (m), ``rms_error`` (m), ``arc_coverage`` (rad),
``n_fit_points`` and ``lying`` (false when absent), as example_pcl.can.Can has - all in one frame
(the sensor's or a fixed target frame), with the frame's stamp (s), and keeps one :class:`Track` per can:

* **Association.** Each track's centre is predicted to the new stamp; detections are
  assigned to tracks by minimum total distance (``scipy.optimize.linear_sum_assignment``) among
  the pairs within ``gate_distance`` of the prediction whose radii differ by at most
  ``radius_gate`` and that both lie or both stand. An unassigned detection starts a new track
  with a new id (ids count up from 1 and are never reused, not even after a reset). The centre
  is an upright can's base centre, and the middle of a lying can's axis (a detection with
  ``lying`` true: base_center one end, axis along it, height its length), which does not
  depend on the end its pose starts from (but with ``end_seen`` false, the image's edge cutting
  the other end, the track's pose starts from the detection's end, the end seen); a lying
  detection never continues an upright track nor the reverse (a can that falls over, or is
  stood up, is a new track: it is grasped differently, and a lying can beside an upright one
  cannot take its id).
* **Smoothing.** The centre runs two constant-velocity Kalman filters (each with one 2x2
  covariance shared by x, y and z; measurement noise ``position_noise``): a *steady* one
  (white acceleration ``accel_noise``: heavy smoothing, a static can's jitter well below the
  detections') and an *agile* one (``max_accel``: follows a pushed can closely). The track
  reports the steady filter while its innovations average out; when their exponential mean
  (gain ``lag_gain``) is more than ``lag_sigmas`` of its standard deviations from zero - the
  steady filter lags, the can is moving - the steady filter takes the agile one's state and
  covariance, and so follows at once. Axis, radius and height are running means for the first
  frames, then exponential with gains ``axis_gain`` and ``size_gain``; the axis, like the
  centre, follows at once (takes the detection's) when the exponential mean of its innovations
  (gain ``lag_gain``) is more than ``lag_sigmas`` of its standard deviations (from ``axis_noise``)
  from zero: a camera turning, or a lying can turned, is followed instead of lagged behind.
* **Ending.** A track not seen for ``max_missed`` consecutive frames is dropped (reported in
  TrackerUpdate.ended on that frame). Unseen tracks coast on their prediction meanwhile.
* **Confidence** (0..1) = min(1, hits / confirm_hits) * hits / (hits + misses) *
  (0.5 + 0.5 * quality), where misses counts every frame unseen since the track started, and
  quality = min(1, arc / pi) * max(0, 1 - rms / rms_limit) of the last fit (arc: visible arc,
  rms: radial rms residual).
* **Time.** A stamp earlier than the last one (a bag played in a loop) ends every track and
  starts afresh (TrackerUpdate.reset says why); a gap longer than ``max_gap`` keeps the tracks
  but forgets their velocities; a repeated stamp updates without prediction.
"""
import dataclasses
from dataclasses import dataclass, field
from typing import List

import numpy as np
from scipy.optimize import linear_sum_assignment

from example_pcl import geometry as g
from example_pcl.errors import PerceptionError, require_positive


@dataclass(frozen=True)
class TrackerConfig:
    """Parameters of CanTracker (see the module docstring).

    max_missed (frames): a track unseen this many consecutive frames is dropped.
    gate_distance (m): a detection further than this from a track's predicted centre is
    not that can; radius_gate (m): nor is one whose radius differs by more.
    position_noise (m): std of a detection's base centre; accel_noise, max_accel (m/s^2): std
    of the white acceleration of the steady and the agile filter; init_speed (m/s): std of a
    new track's unknown speed; lag_gain (0..1): weight of the newest innovation in their mean;
    lag_sigmas: how far (in standard deviations) that mean may stray before the can counts as
    moving.
    axis_gain, size_gain (0..1): weight of a new measurement of the axis, and of the radius
    and height, once the running mean has seen 1/gain frames; axis_noise (rad): std of a
    detection's axis direction, for the axis' lag test.
    max_gap (s): a longer time between frames resets the tracks' velocities.
    confirm_hits (frames), rms_limit (m): of the confidence rule.
    """

    max_missed: int = 5
    gate_distance: float = 0.05
    radius_gate: float = 0.01
    position_noise: float = 0.0005
    accel_noise: float = 0.02
    max_accel: float = 3.0
    init_speed: float = 0.2
    lag_gain: float = 0.5
    lag_sigmas: float = 2.0
    axis_gain: float = 0.1
    size_gain: float = 0.1
    axis_noise: float = 0.01
    max_gap: float = 1.0
    confirm_hits: int = 3
    rms_limit: float = 0.006

    def validate(self):
        """Raises PerceptionError naming the first value that makes no sense."""
        require_positive(self, ("max_missed", "gate_distance", "radius_gate", "position_noise", "accel_noise",
                                "max_accel", "init_speed", "lag_sigmas", "axis_noise", "max_gap", "confirm_hits",
                                "rms_limit"))
        for name in ("axis_gain", "size_gain", "lag_gain"):
            if not 0 < getattr(self, name) <= 1:
                raise PerceptionError(f"TrackerConfig.{name} must be in (0, 1], got {getattr(self, name)}")


@dataclass(eq=False)
class Track:
    """One tracked can, in the frame of the detections. id; base_center (m): float64 (3,), the
    origin of its pose (a lying can's: one end); velocity (m/s): float64 (3,) of its centre;
    both filtered; axis: unit (3,); radius, height (m): smoothed; lying: whether the can lies on
    its side (height its length); age (frames since it
    started, 0 on its first), hits (frames seen), missed (consecutive frames unseen, 0 when seen
    this frame), misses (frames unseen in all); confidence (0..1); detection: the last detection
    assigned to it (its rms_error, arc_coverage, n_fit_points, indices, ...); moving: whether
    the last frame found the can moving (the agile filter in charge)."""

    id: int
    base_center: np.ndarray
    velocity: np.ndarray
    axis: np.ndarray
    radius: float
    height: float
    detection: object = field(repr=False)
    age: int = 0
    hits: int = 1
    missed: int = 0
    misses: int = 0
    confidence: float = 0.0
    steady: "_ConstantVelocity" = field(default=None, repr=False)
    agile: "_ConstantVelocity" = field(default=None, repr=False)
    mean_innovation: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)  # steady filter's (m)
    mean_axis_innovation: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)  # (unit vector)
    moving: bool = False
    lying: bool = False

    @property
    def center(self):
        """The point the filters track (m): the base centre, or the middle of a lying can's axis."""
        return g.footprint_center(self.base_center, self.axis, self.height, self.lying)

    @property
    def pose(self):
        """T_frame_from_can (4x4 float64): origin at base_center, z along axis, x the frame's x
        projected onto the base (geometry.plane_frame); a lying can's x is its last detection's
        (up from the table, as can_search poses it) when that has a T_sensor_from_can."""
        T = getattr(self.detection, "T_sensor_from_can", None) if self.lying else None
        if T is not None:
            return g.plane_frame(self.axis, self.base_center, sensor_x=np.asarray(T)[:3, 0])
        return g.plane_frame(self.axis, self.base_center)

    def snapshot(self):
        """A copy of the track as it is now, which later updates do not change."""
        return dataclasses.replace(self, base_center=self.base_center.copy(), velocity=self.velocity.copy(),
                                   axis=self.axis.copy(), steady=None, agile=None,
                                   mean_innovation=self.mean_innovation.copy(),
                                   mean_axis_innovation=self.mean_axis_innovation.copy())

    @property
    def seen(self):
        """Whether a detection was assigned to the track in the last frame."""
        return self.missed == 0


@dataclass(frozen=True, eq=False)
class TrackerUpdate:
    """What one CanTracker.update did. tracks: every live track (seen or coasting), by id, as
    snapshots (later updates leave them as they were);
    started: ids of tracks started this frame; ended: ids dropped this frame (unseen for
    max_missed frames, or all of them on a reset); assignment: detection index -> track id for
    every detection; reset: why the tracks were reset ("" when not); events: notes for a log
    (reset, gap)."""

    tracks: List[Track]
    started: List[int]
    ended: List[int]
    assignment: dict
    reset: str = ""
    events: List[str] = field(default_factory=list)


class CanTracker:
    """Tracks cans over frames: call update(detections, stamp) once per frame (see the module
    docstring). State: the live tracks, the last stamp and the next id."""

    def __init__(self, config=TrackerConfig()):
        config.validate()
        self.config = config
        self._tracks = []
        self._stamp = None
        self._next_id = 1

    @property
    def tracks(self):
        """The live tracks, by id (snapshots)."""
        return [t.snapshot() for t in self._tracks]

    def reset(self):
        """Forgets every track and the last stamp (ids keep counting up). Returns the ended ids."""
        ended = [t.id for t in self._tracks]
        self._tracks, self._stamp = [], None
        return ended

    def update(self, detections, stamp):
        """One frame: detections (sequence of objects with base_center, axis, radius, height,
        rms_error, arc_coverage, n_fit_points, optionally lying; frame of the tracks) seen at stamp (s). Returns
        a TrackerUpdate."""
        c = self.config
        stamp = float(stamp)
        if not np.isfinite(stamp):
            raise PerceptionError(f"the stamp must be a finite time in seconds, got {stamp}")
        detections = list(detections)
        measured = [_measurement(d, i) for i, d in enumerate(detections)]
        events, ended, reset = [], [], ""
        dt = 0.0 if self._stamp is None else stamp - self._stamp
        if dt < 0:
            reset = f"time went backwards by {-dt:.3f} s: every track ended"
            events.append(reset)
            ended = self.reset()
            dt = 0.0
        elif dt > c.max_gap:
            events.append(f"{dt:.3f} s since the last frame (max_gap {c.max_gap} s): velocities reset")
            for t in self._tracks:
                for f in (t.steady, t.agile):
                    f.forget_velocity(c.init_speed)
                t.velocity = t.steady.velocity.copy()
            dt = 0.0
        self._stamp = stamp

        for t in self._tracks:
            t.steady.predict(dt, c.accel_noise)
            t.agile.predict(dt, c.max_accel)
        predicted = [t.agile.position for t in self._tracks]  # the nearer one when a can moves
        pairs = self._associate(predicted, measured)
        assignment, started = {}, []
        matched_tracks = set()
        for k, i in pairs:
            track = self._tracks[k]
            self._correct(track, measured[i], detections[i])
            assignment[i] = track.id
            matched_tracks.add(k)
        for k, track in enumerate(self._tracks):
            if k not in matched_tracks:
                _place(track)
                track.age += 1
                track.missed += 1
                track.misses += 1
        alive = []
        for k, track in enumerate(self._tracks):
            if track.missed >= c.max_missed:
                ended.append(track.id)
            else:
                alive.append(track)
        for i, m in enumerate(measured):
            if i not in assignment:
                track = Track(id=self._next_id, base_center=m["base"].copy(), velocity=np.zeros(3),
                              axis=m["axis"].copy(), radius=m["radius"], height=m["height"], detection=detections[i],
                              steady=_ConstantVelocity(m["center"], c.position_noise, c.init_speed),
                              agile=_ConstantVelocity(m["center"], c.position_noise, c.init_speed), lying=m["lying"])
                self._next_id += 1
                alive.append(track)
                started.append(track.id)
                assignment[i] = track.id
        for track in alive:
            track.confidence = self._confidence(track)
        alive.sort(key=lambda t: t.id)
        self._tracks = alive
        return TrackerUpdate(tracks=[t.snapshot() for t in alive], started=started, ended=ended,
                             assignment=assignment, reset=reset, events=events)

    # --- filter ---------------------------------------------------------------------------------

    def _associate(self, predicted, measured):
        """(track index, detection index) pairs: minimum total distance within the gates."""
        if not predicted or not measured:
            return []
        c = self.config
        centers = np.array([m["center"] for m in measured])
        cost = np.linalg.norm(np.array(predicted)[:, None, :] - centers[None, :, :], axis=2)
        radii = np.array([m["radius"] for m in measured])
        allowed = (cost <= c.gate_distance) & (
            np.abs(np.array([t.radius for t in self._tracks])[:, None] - radii[None, :]) <= c.radius_gate)
        allowed &= np.array([t.lying for t in self._tracks])[:, None] == np.array([m["lying"] for m in measured])
        big = 1e6
        rows, cols = linear_sum_assignment(np.where(allowed, cost, big))
        return [(int(k), int(i)) for k, i in zip(rows, cols) if allowed[k, i]]

    def _correct(self, track, m, detection):
        c = self.config
        R = c.position_noise ** 2
        innovation, S = track.steady.correct(m["center"], R)
        track.agile.correct(m["center"], R)
        # The steady filter's innovations average out on noise; their exponential mean has per
        # axis the variance S w / (2 - w). Beyond lag_sigmas of it, the steady filter lags.
        w = c.lag_gain
        track.mean_innovation = (1 - w) * track.mean_innovation + w * innovation
        lag = float(track.mean_innovation @ track.mean_innovation) / (S * w / (2 - w)) / 3.0
        track.moving = lag > c.lag_sigmas ** 2
        if track.moving:
            track.steady = track.agile.copy()
            track.mean_innovation = np.zeros(3)
        track.hits += 1
        track.age += 1
        track.missed = 0
        n = max(1.0 / track.hits, c.axis_gain)
        if track.lying and not getattr(detection, "end_seen", True) and m["axis"] @ track.axis < 0:
            # The image's edge cuts the can's far end: its pose starts from the end seen, as the detection's.
            track.axis, track.mean_axis_innovation = -track.axis, -track.mean_axis_innovation
        axis = m["axis"] if m["axis"] @ track.axis >= 0 else -m["axis"]
        # As the centre's: innovations across the axis (2 degrees of freedom) that do not average out.
        track.mean_axis_innovation = (1 - w) * track.mean_axis_innovation + w * (axis - track.axis)
        lag = float(track.mean_axis_innovation @ track.mean_axis_innovation) / (c.axis_noise ** 2 * w / (2 - w)) / 2.0
        if lag > c.lag_sigmas ** 2:
            track.axis, track.mean_axis_innovation = axis.copy(), np.zeros(3)
        else:
            track.axis = track.axis + n * (axis - track.axis)
            track.axis /= np.linalg.norm(track.axis)
        n = max(1.0 / track.hits, c.size_gain)
        track.radius += n * (m["radius"] - track.radius)
        track.height += n * (m["height"] - track.height)
        track.detection = detection
        _place(track)

    def _confidence(self, track):
        c = self.config
        d = track.detection
        quality = min(1.0, float(d.arc_coverage) / np.pi) * max(0.0, 1.0 - float(d.rms_error) / c.rms_limit)
        presence = track.hits / (track.hits + track.misses)
        return float(min(1.0, track.hits / c.confirm_hits) * presence * (0.5 + 0.5 * quality))


class _ConstantVelocity:
    """A constant-velocity Kalman filter on a 3-D position whose axes share one 2x2 covariance
    (position, speed): the same noise on x, y and z makes them equal."""

    def __init__(self, position, position_noise, speed_noise):
        self.position = np.array(position, dtype=float)
        self.velocity = np.zeros(3)
        self.covariance = np.diag([position_noise ** 2, speed_noise ** 2])

    def copy(self):
        out = _ConstantVelocity(self.position, 1.0, 1.0)
        out.velocity, out.covariance = self.velocity.copy(), self.covariance.copy()
        return out

    def forget_velocity(self, speed_noise):
        self.velocity[:] = 0.0
        self.covariance = np.diag([self.covariance[0, 0], speed_noise ** 2])

    def predict(self, dt, accel_noise):
        """dt (s) later under white acceleration of std accel_noise (m/s^2)."""
        F = np.array([[1.0, dt], [0.0, 1.0]])
        Q = accel_noise ** 2 * np.array([[dt ** 4 / 4, dt ** 3 / 2], [dt ** 3 / 2, dt ** 2]])
        self.position = self.position + dt * self.velocity
        self.covariance = F @ self.covariance @ F.T + Q

    def correct(self, measured, measurement_variance):
        """Takes a measured position (m); returns (innovation (3,), its per-axis variance S)."""
        P = self.covariance
        innovation = measured - self.position
        S = P[0, 0] + measurement_variance
        K = P[:, 0] / S
        self.position = self.position + K[0] * innovation
        self.velocity = self.velocity + K[1] * innovation
        self.covariance = P - np.outer(K, P[0, :])
        return innovation, S


def _place(track):
    """Sets a track's base centre and velocity from its steady filter (which tracks its centre)."""
    position = track.steady.position
    track.base_center = position - 0.5 * track.height * track.axis if track.lying else position.copy()
    track.velocity = track.steady.velocity.copy()


def _measurement(detection, index):
    """The numbers the tracker uses from one detection, validated: base (its base centre), center
    (what the filters track: Track.center), axis (unit), radius, height, lying."""
    try:
        center = np.asarray(detection.base_center, dtype=float).reshape(3)
        axis = np.asarray(detection.axis, dtype=float).reshape(3)
        radius, height = float(detection.radius), float(detection.height)
    except (AttributeError, TypeError, ValueError) as e:
        raise PerceptionError(f"detection {index} is not a can (needs base_center, axis, radius, height): {e}")
    norm = np.linalg.norm(axis)
    if not (np.isfinite(center).all() and np.isfinite(axis).all() and norm > 0 and radius > 0 and height > 0):
        raise PerceptionError(f"detection {index} has a non-finite centre or axis, or a non-positive size")
    axis = axis / norm
    lying = bool(getattr(detection, "lying", False))
    middle = g.footprint_center(center, axis, height, lying)
    return {"base": center, "center": middle, "axis": axis, "radius": radius, "height": height, "lying": lying}
