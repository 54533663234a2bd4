"""Unit tests of lying cans in the tracker's per-frame path: example_pcl.local_fit's refit of a lying
can, its footprint in the scene-change check, adopt, and LocalFinder + CanTracker over a generated
sequence whose camera moves while a lying can rolls beside two upright ones.

Needs the compiled extension. Frames are rendered once and cached (example_pcl.scene_sequence).
"""
import numpy as np
import pytest

from example_pcl import local_fit as lf
from example_pcl import scene_sequence as ss
from example_pcl import tracking as tr
from example_pcl.errors import PerceptionError

YAW = 0.6  # rad, the lying can's axis in the table frame
ROLL = 0.04  # m, how far it rolls (across its axis) between frames 8 and 24


def lying_spec():
    """30 frames; the camera drifts 2 mm, 2 mrad of tilt and 5 mrad of yaw per frame (twice the
    default sequence's, so a can carried unchanged in the sensor frame is centimetres off by the
    periodic search); a lying can rolls 4 cm; an upright can stands 4 cm from its end."""
    across = np.array([-np.sin(YAW), np.cos(YAW)])
    x, y = -0.13, 0.09
    return ss.SequenceSpec(distance_step=0.002, tilt_step=0.002, yaw_step=0.005, seed=100, cans=[
        ss.SequenceCan(0, 0.033, 0.122, ((0, 0.0, 0.0),)),
        ss.SequenceCan(1, 0.033, 0.115, ((8, x, y), (24, x + ROLL * across[0], y + ROLL * across[1])), lying=True,
                       yaw=YAW),
        ss.SequenceCan(2, 0.04, 0.10, ((0, -0.10, 0.20),)),
    ])


@pytest.fixture(scope="module")
def frames():
    return ss.render_sequence(lying_spec())


def middle(can):
    """The middle of a can's axis (m): a Can's, a Track's or a truth dict's."""
    get = can.get if isinstance(can, dict) else (lambda k: getattr(can, k))
    return np.asarray(get("base_center"), float) + 0.5 * float(get("height")) * np.asarray(get("axis"), float)


def lying_truth(frame):
    return next(c for c in frame.truth["cans"] if c["lying"])


def pose_error(can, truth):
    """(distance between the axes' middles (m), angle between the axes (rad, either sense))."""
    cosine = abs(float(np.asarray(can.axis) @ np.asarray(truth["axis"])))
    return float(np.linalg.norm(middle(can) - middle(truth))), float(np.arccos(min(cosine, 1.0)))


def test_refit_lying_can_follows_the_camera_and_the_can(frames):
    """A lying can found in frame 12 and refitted in frame 13 (camera moved, can rolling) is within
    1.5 mm and 0.5 degree of the truth, its radius within 1 mm and its length within 3 mm, still
    lying and starting from the same end."""
    before = lf.search_frame(frames[12].xyz)
    previous = next(c for c in before.cans if c.lying)
    _, T = lf.refit_table(frames[13].xyz, before.table)
    others = [c for c in before.cans if not c.lying]
    can = lf.refit_lying_can(frames[13].xyz, T, previous, others=others)
    truth = lying_truth(frames[13])
    distance, angle = pose_error(can, truth)
    assert can.lying and distance < 0.0015 and angle < np.radians(0.5), (distance, angle)
    assert abs(can.radius - truth["radius"]) < 0.001 and abs(can.height - truth["height"]) < 0.003
    assert can.axis @ previous.axis > 0.99


def test_refit_lying_can_raises_when_the_can_is_gone(frames):
    """The same lying can looked for in a frame without it (the default sequence's first frame,
    same camera) is a PerceptionError naming what is missing."""
    found = lf.search_frame(frames[0].xyz)
    previous = next(c for c in found.cans if c.lying)
    empty = ss.render_sequence()[0].xyz
    _, T = lf.refit_table(empty, found.table)
    with pytest.raises(PerceptionError, match="lying can was"):
        lf.refit_lying_can(empty, T, previous)


def test_a_lying_can_is_no_new_standing_points(frames):
    """A known lying can's points stand in its region along its axis: they are not counted as new,
    though they would be without it (so a lying can alone does not trigger a search every frame)."""
    found = lf.search_frame(frames[5].xyz)
    standing, grid = lf.standing_grid(frames[5].xyz, found.T_sensor_from_plane)
    T_plane = np.linalg.inv(found.T_sensor_from_plane)
    config = lf.LocalFitConfig()
    upright = [c for c in found.cans if not c.lying]
    assert len(upright) == len(found.cans) - 1
    assert lf.new_standing_points(standing, grid, T_plane, found.cans, None, config) < config.min_new_points
    assert lf.new_standing_points(standing, grid, T_plane, upright, None, config) >= 5 * config.min_new_points


def test_adopt_keeps_the_fresher_refit_of_a_lying_can(frames):
    """A search of an earlier frame, adopted after the lying can rolled, leaves the refitted lying
    can (and the upright ones) in place of the search's older fits."""
    finder = lf.LocalFinder()
    old = lf.search_frame(frames[10].xyz)
    finder.process(frames[10].xyz)
    for f in frames[11:15]:
        refitted = finder.process(f.xyz)
        assert not refitted.searched, refitted.reason
    finder.adopt(old)
    kept = [c for c in finder._cans if c.lying]
    assert len(kept) == 1 and any(kept[0] is c for c in refitted.cans)
    assert len(finder._cans) == len(old.cans)


def test_the_refit_says_when_the_image_edge_cuts_a_lying_cans_end(frames):
    """Frames whose left part is holes up to a third of the lying can (as a Kinect's border), the
    upright cans still in view: the refit reports the lying can with end_seen False, its origin the
    end seen (within 5 mm of the truth's), its axis toward the end cut off."""
    finder = lf.LocalFinder()
    width = frames[10].xyz.shape[1]
    cols = next(c for c in finder.process(frames[10].xyz).cans if c.lying).indices % width
    cut = int(cols.min() + (cols.max() - cols.min()) // 3)
    for k in (11, 12, 13):
        xyz = frames[k].xyz.copy()
        xyz[:, :cut] = np.nan
        fit = finder.process(xyz)
        assert not fit.searched, fit.reason
        can = next(c for c in fit.cans if c.lying)
        assert not can.end_seen and can.base_seen
        truth = lying_truth(frames[k])
        ends = [np.asarray(truth["base_center"]), np.asarray(truth["base_center"]) + truth["height"] * np.asarray(
            truth["axis"])]
        seen, cut_off = sorted(ends, key=lambda e: np.linalg.norm(e - can.base_center))
        assert np.linalg.norm(seen - can.base_center) < 0.005
        assert can.axis @ (cut_off - seen) > 0


@pytest.fixture(scope="module")
def tracked(frames):
    """(FrameFits, TrackerUpdates) of the sequence through LocalFinder (a full search every 10
    frames) and CanTracker."""
    finder = lf.LocalFinder(lf.LocalFitConfig(search_period=10))
    tracker = tr.CanTracker()
    fits, updates = [], []
    for f in frames:
        fits.append(finder.process(f.xyz))
        updates.append(tracker.update(fits[-1].cans, f.stamp))
    return fits, updates


def test_sequence_lying_can_within_2_mm_and_1_degree_every_frame(frames, tracked):
    """On every frame the refit (or search) reports the lying can within 2 mm (middle of its axis)
    and 1 degree of the truth, and its track within 2 mm and 1.5 degrees (its smoothed axis follows
    the camera's turn in steps: tracking's axis lag test); the camera's drift puts a can carried
    unchanged in the sensor frame centimetres off."""
    fits, updates = tracked
    for f, fit, update in zip(frames, fits, updates):
        truth = lying_truth(f)
        lying = [c for c in fit.cans if c.lying]
        assert len(lying) == 1, f"frame {f.index}: {fit.reason}"
        distance, angle = pose_error(lying[0], truth)
        assert distance < 0.002 and angle < np.radians(1.0), (f.index, distance, angle)
        track = next(t for t in update.tracks if t.lying)
        distance, angle = pose_error(track, truth)
        assert track.seen and distance < 0.002 and angle < np.radians(1.5), (f.index, distance, angle)


def test_sequence_ids_stable_and_search_only_when_periodic(frames, tracked):
    """Every can keeps one track id over the sequence (the lying one across the periodic searches,
    the upright one 4 cm from its end too), lying and upright tracks stay apart, and the full search
    runs only on the first frame and periodically: the rolling lying can is neither lost nor new."""
    fits, updates = tracked
    ids = {}
    for f, update in zip(frames, updates):
        for truth in f.truth["cans"]:
            seen = [t for t in update.tracks if t.seen and t.lying == truth["lying"]]
            track = min(seen, key=lambda t: np.linalg.norm(middle(t) - middle(truth)))
            ids.setdefault(truth["id"], set()).add(track.id)
        assert len(update.tracks) == len(f.truth["cans"]), f.index
    assert all(len(v) == 1 for v in ids.values()) and len(set.union(*ids.values())) == len(ids), ids
    assert [i for i, fit in enumerate(fits) if fit.searched] == [0, 10, 20], [fit.reason for fit in fits]


def test_sequence_lying_track_velocity_is_the_cans_in_the_camera_frame(frames, tracked):
    """The lying track's velocity (of the middle of its axis, camera frame: the camera's drift, then
    the can's roll too) is within 10 mm/s of the truth's (central difference of the true middles)
    while only the camera moves (frames 2-7: the fits' frame-to-frame noise of about 0.2 mm is 6 mm/s
    at 30 Hz while the filter settles), and within 50 mm/s (the steady filter's lag as the roll speeds
    up, to 0.1 m/s in 0.1 s) from frame 2 on."""
    _, updates = tracked
    rate = lying_spec().rate
    for k in range(2, len(frames) - 1):
        track = next(t for t in updates[k].tracks if t.lying)
        truth = (middle(lying_truth(frames[k + 1])) - middle(lying_truth(frames[k - 1]))) * rate / 2
        error = np.linalg.norm(track.velocity - truth)
        assert error < (0.01 if k <= 7 else 0.05), (k, track.velocity, truth)
