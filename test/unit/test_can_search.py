"""Unit tests of example_pcl.can_search (issue 13): cans inside clusters, stacked, partly hidden, and
the objects that are no cans. Generated cases (example_pcl.scene_objects) are checked against their
ground truth; the real mOSD scenes (../shared/data/osd) against their labels and
bench/osd_objects.json, skipped when ../shared is absent.
"""
import dataclasses
import json
import pathlib
import sys

import numpy as np
import pytest

from example_pcl import auto_finder as af
from example_pcl import can_search as cs
from example_pcl import geometry as g
from example_pcl import lying
from example_pcl import scene as sc
from example_pcl import scene_objects as so
from example_pcl import transforms
from example_pcl.scene_objects import Obj

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "bench"))
import bench_cans  # noqa: E402
from bench_views import degraded, views, wrong  # noqa: E402

PROJECT = pathlib.Path(__file__).resolve().parents[2]
OSD = PROJECT / ".." / "shared" / "data" / "osd"
OBJECTS = PROJECT / "bench" / "osd_objects.json"
CENTRE_TOLERANCE = 0.002  # m
RADII = (af.AutoConfig().min_radius, af.AutoConfig().max_radius)  # a can's, m


def search(objects, **camera):
    """(scene, AutoResult, T_plane_from_camera) of a scene of `objects` (table frame)."""
    spec = sc.SceneSpec(cans=[], objects=objects, **{"camera_distance": 0.9, "tilt": 0.85, "seed": 7, **camera})
    scene = sc.generate_scene(spec)
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    return scene, af.find_cans(scene.xyz), to_table


def search_context(sensor, standing, rng, **fields):
    """A can_search._Context in the plane frame (T_sensor_from_plane the identity) with the default
    configs and nothing found yet: sensor (3,) and standing (float (N, 3)) in m; fields: any other."""
    return cs._Context(config=af.AutoConfig(), search=cs.CylinderSearchConfig(), T_sensor_from_plane=np.eye(4),
                       sensor=sensor, standing=standing, rng=rng, found=[], **fields)


def table_xy(to_table, can):
    return transforms.apply(to_table, can.base_center)


def nearest_can(cans, to_table, xy):
    """Of `cans`, the one whose base centre lies nearest xy (m, table frame)."""
    return min(cans, key=lambda c: np.hypot(*(table_xy(to_table, c)[:2] - xy[:2])))


def assert_cans_at(result, to_table, objects):
    """Exactly the upright cans among `objects` are found, each within CENTRE_TOLERANCE."""
    truth = [o for o in objects if o.kind == "can"]
    found = [table_xy(to_table, c) for c in result.cans]
    assert len(found) == len(truth), (result.message, [r.reason for r in result.rejected])
    for o in truth:
        errors = [np.hypot(f[0] - o.x, f[1] - o.y) for f in found]
        assert min(errors) < CENTRE_TOLERANCE, (o, found)


# --- the pieces -----------------------------------------------------------------------------------


def test_circumcircles_pass_through_their_points():
    """The circle through three points of a known circle is that circle; collinear points give inf."""
    angles = np.array([[0.1, 1.0, 2.5], [3.0, 4.0, 5.5]])
    pts = np.stack([0.03 * np.cos(angles) + 0.2, 0.03 * np.sin(angles) - 0.1], axis=-1)
    cx, cy, r = cs.circumcircles(pts[:, 0], pts[:, 1], pts[:, 2])
    np.testing.assert_allclose(np.c_[cx, cy, r], [[0.2, -0.1, 0.03]] * 2, atol=1e-12)
    line = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    assert np.isinf(cs.circumcircles(line[None, 0], line[None, 1], line[None, 2])[2][0])


def test_the_last_draw_retries_a_circle_a_tried_one_took_out_but_none_like_one_tried():
    """Of the first draw's circles, _suppressed_by keeps one that a circle tried took out as sharing its
    points though elsewhere, and not one like a circle tried (within eps), even when it shares the
    points of another one tried (held-out 1301: the same wide circle was verified twice and the can's
    own circle never)."""
    angle = np.linspace(-2.1, -1.0, 40)
    xy = np.c_[0.05 * np.cos(angle), 0.05 * np.sin(angle)]  # the front of a circle of r 5 cm at 0
    tried = [(0.0, 0.0, 0.05), (0.0, 0.02, 0.07)]  # that circle, and a wider one through its front
    circles = np.array([0.001, 0.0, 0.2]), np.array([0.0, 0.01, 0.2]), np.array([0.05, 0.06, 0.05])  # cx, cy, r
    kept = cs._suppressed_by(circles, tried, xy, 0.006, sensor=None)
    # 1 mm from the first one tried (sharing the second's points too): not again; a circle between both
    # sharing their points: again; one sharing none: not a duplicate.
    assert kept.tolist() == [False, True, False]


def test_the_first_draw_ranks_its_circles_on_the_points_off_the_flat_faces(monkeypatch):
    """A box's long front face (flat, 115 mm), its short side face (50 mm, too short to be flat) and a
    can of r 39 mm touching the face's end, its front in line with it (fresh 6019 of "can touching
    box"): ranked on the pool points off the faces, the can's own circle comes first, not a circle of
    40 mm tangent to the face through the box's corner, which the face's points would carry."""
    rng = np.random.default_rng(11)
    front = np.c_[np.linspace(-0.12, -0.005, 70), np.zeros(70)]
    side = np.c_[np.full(14, -0.12), np.linspace(0.008, 0.05, 14)]
    angle = np.radians(np.linspace(-150, -30, 15))
    can = np.c_[0.034 + 0.039 * np.cos(angle), 0.039 + 0.039 * np.sin(angle)]
    xy = np.concatenate([front, side, can]) + rng.normal(0, 0.0007, (99, 2))
    z = rng.uniform(0.01, 0.12, len(xy))
    r_eps = 0.006
    face = g.flat_faces(xy, 0.5 * r_eps, 0.06, 12, rng, radii=RADII)
    assert face[:70].mean() > 0.9 and not face[70:].any()
    ctx = search_context(sensor=np.array([0.0, -0.8, 0.7]), standing=np.c_[xy, z], rng=rng)
    circles = np.array([0.034, -0.08]), np.array([0.039, 0.04]), np.array([0.039, 0.04]), np.array([0.075, 0.075])
    monkeypatch.setattr(cs, "circle_hypotheses", lambda *args, **kwargs: circles)
    cx, cy, r, _, axy, az = next(cs._draws(xy, z, face, np.zeros(len(xy), bool), [], r_eps, ctx))
    assert cs.best_circles(axy, cx, cy, r, r_eps, 1, sensor=ctx.sensor, z=az) == [0]


def test_band_run_grows_from_the_fullest_side_band_over_small_gaps():
    """The run starts at the fullest band with no more inside than on, and stops at a long gap."""
    on = np.array([0, 5, 9, 0, 8, 9, 0, 0, 7, 30])
    inside = np.array([0, 0, 0, 0, 0, 0, 0, 0, 0, 40])  # the last band is a lid
    assert cs.band_run(on, inside, 0.2, 3, 1) == (1, 5)
    assert cs.band_run(np.zeros(4, int), np.zeros(4, int), 0.2, 3, 1) is None


def test_band_run_is_the_run_with_most_points_not_the_one_through_the_fullest_band():
    """A ring seen from above at one height (a wider cup's rim on a can, seen steeply) puts more points
    in one band than any band of the can's side: the run is the side's, which holds most of them
    ("cup on can" 3824: 84 points in the rim's band, 25-34 in each of the side's 14)."""
    on = np.array([0, 9, 27, 25, 25, 30, 26, 28, 31, 28, 31, 33, 31, 34, 28, 0, 0, 0, 0, 0, 0, 0, 84, 0])
    assert g.band_run(on, np.zeros(len(on), int), 0.2, 3, 1) == (1, 14)
    # Alone, the ring is a run of its own.
    on[:15] = 0
    assert g.band_run(on, np.zeros(len(on), int), 0.2, 3, 1) == (22, 22)
    # A later start's run does not reach into an earlier one's bands: the band under a side run, too
    # few points for it (9 of the fullest's 55 x 0.2), starts no run that takes the side's bands with
    # it ("box hides base" 1, its base hidden behind the box).
    on = np.array([0, 9, 23, 23, 23, 24, 27, 24, 55, 0, 0])
    assert g.band_run(on, np.zeros(len(on), int), 0.2, 3, 1) == (2, 8)


def test_band_run_stops_at_a_blocked_band_without_a_gap():
    """A blocked band (another object seen there) ends the run; it is not skipped as a gap."""
    on = np.array([9, 8, 9, 8, 1, 9, 8])
    inside = np.zeros(7, int)
    assert g.band_run(on, inside, 0.2, 3, 1) == (0, 6)
    assert g.band_run(on, inside, 0.2, 3, 1, blocked=np.arange(7) == 4) == (0, 3)


def test_band_run_crosses_a_longer_gap_only_where_across_says_the_side_is_hidden():
    """Fresh 7201's bands: the side below and above an object in front, two empty bands between. Without
    `across` the fuller run below is taken; across(first, last) asked about the gap (bands 7-8) joins
    the run above to it, and is not asked across a blocked band (a lid), nor below the run (a
    support's points lie there)."""
    on = np.array([0, 5, 14, 13, 15, 14, 12, 0, 0, 29, 31, 0, 0])
    inside = np.array([0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 71, 5])
    lid = inside > np.maximum(on, 3)
    asked = []

    def hidden(first, last):
        asked.append((first, last))
        return True

    assert g.band_run(on, inside, 0.2, 3, 1, lid) == (1, 6)
    assert g.band_run(on, inside, 0.2, 3, 1, lid, across=lambda first, last: False) == (1, 6)
    assert g.band_run(on, inside, 0.2, 3, 1, lid, across=hidden) == (1, 10)
    assert asked == [(7, 8)]
    # The fuller run above the gap: nothing below is joined.
    above = on.copy()
    above[9:11] = 90
    asked.clear()
    assert g.band_run(above, inside, 0.2, 3, 1, lid, across=hidden) == (9, 10)
    assert asked == []
    blocked = lid | (np.arange(len(on)) == 8)
    asked.clear()
    assert g.band_run(on, inside, 0.2, 3, 1, blocked, across=hidden) == (1, 6)
    assert asked == []


def test_config_rejects_nonsense():
    """A zero band height is a PerceptionError naming the field."""
    from example_pcl.errors import PerceptionError

    with pytest.raises(PerceptionError, match="band_height"):
        af.find_cans(np.zeros((4, 4, 3), np.float32),
                     config=af.AutoConfig(cylinders=cs.CylinderSearchConfig(band_height=0.0)))


# --- generated cases ------------------------------------------------------------------------------


def test_two_touching_cans_are_two_cans():
    """Two cans touching (one cluster) are both found, each with its own radius."""
    objects = [Obj("can", 0.0, 0.0, radius=0.033, height=0.12), Obj("can", 0.075, 0.0, radius=0.04, height=0.1)]
    _, result, to_table = search(objects)
    assert_cans_at(result, to_table, objects)
    assert sorted(c.radius for c in result.cans) == pytest.approx([0.033, 0.04], abs=0.002)  # as test_auto_finder


def test_two_touching_cans_fronts_on_one_wide_circle_are_two_round_objects():
    """The fronts of two touching cans (r 30 mm) and the wide circle fitted to both: each half of that
    side lies far closer to a circle of its own (split ratio above max_split_ratio, fresh 4316 of
    "cluttered table" 2.9); one can's front, noisy as a far one's, about 1."""
    rng = np.random.default_rng(2)
    angle = np.linspace(-np.pi / 2 - 0.8, -np.pi / 2 + 0.8, 60)
    front = np.c_[0.03 * np.cos(angle), 0.03 * np.sin(angle)]
    both = np.concatenate([front + (-0.03, 0.0), front + (0.03, 0.0)]) + rng.normal(0, 0.0005, (120, 2))
    cx, cy, r = (float(v[0]) for v in g.fit_circles_algebraic(both))
    assert g.split_ratio(both, cx, cy, r) > cs.CylinderSearchConfig().max_split_ratio
    one = front + rng.normal(0, 0.0015, (60, 2))
    assert g.split_ratio(one, 0.0, 0.0, 0.03) < 1.3
    assert np.isnan(g.split_ratio(one[:8], 0.0, 0.0, 0.03))


def test_split_circles_give_each_halfs_own_circle():
    """A can's front (r 30 mm, 1.6 rad) and a neighbour's side beside it, farther back, and a wider
    circle fitted to both: the half on the can (a part of its front, a Kasa circle) has its own
    circle within 2.5 mm of the can's, its radius within 2 mm, and the larger ratio is split_ratio;
    a half of fewer than min_points points: None."""
    rng = np.random.default_rng(5)
    angle = np.linspace(-np.pi / 2 - 0.8, -np.pi / 2 + 0.8, 60)
    front = np.c_[0.03 * np.cos(angle), 0.03 * np.sin(angle)]
    beside = np.c_[np.linspace(-0.06, -0.035, 25), np.linspace(0.004, -0.012, 25)]
    side = np.concatenate([front, beside]) + rng.normal(0, 0.0005, (85, 2))
    cx, cy, r = (float(v[0]) for v in g.fit_circles_algebraic(side))
    halves = g.split_circles(side, cx, cy, r)
    assert max(h[0] for h in halves) == pytest.approx(g.split_ratio(side, cx, cy, r))
    _, kx, ky, kr = min(halves, key=lambda h: np.hypot(h[1], h[2]))
    assert np.hypot(kx, ky) < 0.0025 and kr == pytest.approx(0.03, abs=0.002)
    assert g.split_circles(side[:8], cx, cy, r) is None


def test_a_wider_circle_over_a_can_and_its_neighbour_gives_way_to_the_cans_own():
    """Fresh 5134 of "cluttered table": a can (r 29.7 mm) seen above a bowl in front, 9 mm from a
    can beside it; a circle of r 39.9 mm tangent to its front and through the neighbour's side was
    verified first (rms 2.6 mm, split ratio 1.49, below max_split_ratio) and reported 11.5 mm off,
    standing on an object. The half of its side on the can has a circle of its own (inner_split),
    verified as a can with a lower rms: found within 1.5 mm, its radius within 1 mm, on the table."""
    truth, can, off = can_nearest_truth("cluttered table", 5134, lambda t: t["is_can"] and t["radius"] < 0.03)
    assert off < 0.0015
    assert can.radius == pytest.approx(truth["radius"], abs=0.001) and can.support == "table"


def can_nearest_truth(case, seed, pick):
    """(truth, can, off) in a generated scene: the first object of its truth that pick (a predicate
    on its dict) takes, the Can found nearest its axis and how far from it (m, on the table)."""
    scene = sc.generate_scene(so.case_spec(case, seed))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    truth = next(t for t in scene.truth["objects"] if pick(t))
    base = transforms.apply(to_table, truth["base_center"])
    cans = af.find_cans(scene.xyz).cans
    off = [np.hypot(*(table_xy(to_table, c)[:2] - base[:2])) for c in cans]
    k = int(np.argmin(off))
    return truth, cans[k], off[k]


def test_a_can_whose_pool_points_a_big_boxs_faces_crowd_out_is_found():
    """Fresh 12718 of "can touching box": a can (r 35.5 mm) touching a box 16 cm wide, whose faces
    drew 190 of the 200 pool points; the can kept 5 of them, no triplet on it, "nothing round left".
    The pool drawn again off the faces finds it, on the table, its full height."""
    truth, can, off = can_nearest_truth("can touching box", 12718, lambda t: t["is_can"])
    assert off < 0.002 and can.support == "table" and can.base_seen
    assert can.radius == pytest.approx(truth["radius"], abs=0.001)
    assert can.height == pytest.approx(truth["height"], abs=0.004)


def test_a_can_whose_front_lies_in_line_with_the_face_of_the_box_it_touches_is_found():
    """Fresh 13043 of "can touching box": the can's front lies in line with the box's face. A pool
    drawn off the faces' runs instead of the first lost it (the can's front went with the face; the
    circles left ran through box and can): that pool is drawn only when the first one fails."""
    truth, can, off = can_nearest_truth("can touching box", 13043, lambda t: t["is_can"])
    assert off < 0.002 and can.support == "table" and can.base_seen
    assert can.height == pytest.approx(truth["height"], abs=0.004)


@pytest.mark.parametrize("cup_first", [True, False])
def test_a_can_beside_a_cup_split_between_its_cluster_and_its_own_is_found(monkeypatch, cup_first):
    """Fresh 13116 of "cluttered table": a cup touching a can (r 44 mm) falls into two clusters, and
    its part in the can's took 200 of its 608 points, bending the can's circle ("shape error 1.50 mm,
    not round"). The cup, claimed in its own cluster, is taken out of the can's, whichever cluster
    is searched first."""
    if not cup_first:
        clusters = af._clusters
        monkeypatch.setattr(af, "_clusters", lambda *args, **kwargs: clusters(*args, **kwargs)[::-1])
    truth, can, off = can_nearest_truth("cluttered table", 13116,
                                        lambda t: t["is_can"] and abs(t["radius"] - 0.0444) < 0.0005)
    assert off < 0.002 and can.support == "table" and can.base_seen
    assert can.radius == pytest.approx(truth["radius"], abs=0.001)


def test_a_can_on_a_box_whose_face_lies_under_its_circle_stands_on_the_box():
    """Fresh 13218 of "can on box": the face of the box under the can, 4 mm inside its circle, lay
    near it (20 points a band, the side 42), and the run bridged the band of the box's top (no side
    on the circle, 131 points around it): a can 191 mm high from the table. The side starts above
    that surface."""
    truth, can, off = can_nearest_truth("can on box", 13218, lambda t: t["is_can"])
    assert off < 0.002 and can.support == "object" and can.base_seen
    assert can.support_height == pytest.approx(truth["support_height"], abs=0.005)
    assert can.height == pytest.approx(truth["height"], abs=0.005)


def test_a_box_top_touching_a_cans_side_is_no_surface_it_stands_on():
    """Fresh 13141 of "can touching box": the top of the box touching the can, 110-120 mm up, leaves
    a band with no side on the circle and crowded beside it (184 points) over 1.2 rad only: no
    surface around the can. It stands on the table, its full height (150 mm)."""
    truth, can, off = can_nearest_truth("can touching box", 13141, lambda t: t["is_can"])
    assert off < 0.002 and can.support == "table" and can.base_seen
    assert can.height == pytest.approx(truth["height"], abs=0.005)


def test_a_mugs_handle_verified_before_the_mug_is_withdrawn_when_the_mug_is_claimed():
    """Fresh 13518 of "cluttered table": the handle bent the mug's side ("not round", 1.58 mm), so a
    circle of r 19 mm about the handle and part of the mug's wall was verified first and taken for a
    can; the mug, claimed next by its far inner wall, showed the two share 8 mm. That can is withdrawn,
    its points searched again (no can there); the two true cans stay."""
    scene = sc.generate_scene(so.case_spec("cluttered table", 13518))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    result = af.find_cans(scene.xyz)
    truth = [transforms.apply(to_table, t["base_center"])[:2] for t in scene.truth["objects"] if t["is_can"]]
    found = [table_xy(to_table, c)[:2] for c in result.cans]
    assert len(found) == len(truth) == 2
    assert all(min(np.hypot(*(f - t)) for f in found) < 0.002 for t in truth)


def test_a_can_withdrawn_for_reaching_into_a_cup_is_searched_again():
    """Fresh 13822 of "cluttered table": a can (r 40 mm) between a cup and a thin box was first fitted
    wide (r 54 mm, 15 mm off) and reached into the cup claimed after it. Withdrawn, its points are
    searched again, not kept: a can is found there (r 49 mm, 10 mm off: the box still bends it)."""
    truth, can, off = can_nearest_truth("cluttered table", 13822,
                                        lambda t: t["is_can"] and abs(t["radius"] - 0.0397) < 0.0005)
    assert off < 0.012 and can.support == "table"


def test_two_touching_half_hidden_cans_are_not_the_wide_circle_tangent_to_both():
    """Fresh 4316 of "cluttered table": two touching cans, their near halves partly hidden, and a wider
    circle tangent to both fronts (r 53 mm, seen over 1.76 rad) was a can, and neither can found. Both
    are found within 3 mm now (geometry.split_ratio), and no upright can lies 15 mm or more from a
    true one. (Its fourth can, behind a taller box with a stripe of its lid seen, is 8 mm off.)"""
    scene = sc.generate_scene(so.case_spec("cluttered table", 4316))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    truth = [transforms.apply(to_table, t["base_center"])[:2] for t in scene.truth["objects"] if t["is_can"]]
    found = [table_xy(to_table, c)[:2] for c in af.find_cans(scene.xyz).cans if not c.lying]
    errors = np.array([[np.hypot(*(f - t)) for t in truth] for f in found])
    assert errors.min(axis=1).max() < 0.015
    assert np.sort(errors.min(axis=0))[:3].max() < 0.003


def test_can_touching_a_box_is_found_and_the_box_rejected_with_a_reason():
    """A can against a box: the can is found, the box is a rejected object with a reason."""
    objects = [Obj("can", 0.0, 0.0, radius=0.033, height=0.12), Obj("box", 0.084, 0.0, size=(0.1, 0.08, 0.15))]
    _, result, to_table = search(objects)
    assert_cans_at(result, to_table, objects)
    assert result.rejected and all(r.reason for r in result.rejected)


def test_a_can_against_a_tall_box_is_found_when_a_wider_circle_takes_the_first_choice():
    """A circle through the can's front and the box's edge is verified first and fails, having taken
    the can's own circles out as its duplicates; they are verified last (the camera of held-out
    seed 606 of "can touching box")."""
    objects = [Obj("can", -0.009, -0.008, radius=0.039, height=0.107),
               Obj("box", -0.0897, -0.0041, size=(0.0815, 0.0624, 0.189))]
    _, result, to_table = search(objects, camera_distance=0.703, tilt=0.787, yaw=-0.113)
    assert_cans_at(result, to_table, objects)


def test_a_taller_box_touching_a_can_does_not_carry_its_side_above_its_lid():
    """The box's edge lies on the can's circle above the lid: the side's run of bands stops at the
    lid's band (more points inside the disc than on the circle), so the lid is its top, not a far
    inner wall under a box-high rim (fresh seed 3700 of "can touching box": an "open top", missed)."""
    objects = [Obj("can", -0.0087, -0.0187, radius=0.031, height=0.108),
               Obj("box", -0.0798, -0.0062, size=(0.0781, 0.0606, 0.1445))]
    _, result, to_table = search(objects, camera_distance=0.850, tilt=0.976, yaw=0.375, seed=3700)
    assert_cans_at(result, to_table, objects)
    assert result.cans[0].height == pytest.approx(0.108, abs=0.004)


def test_a_taller_neighbours_top_reaching_in_over_a_wide_circle_is_no_lid():
    """A circle fitted 35 mm wide, 7 mm off a can of r 29 mm (lid 141 mm up), takes in the edge of the
    lid of a taller can touching it (157 mm): the lid is the can's own, not the neighbour's top,
    whose surface goes on beyond the circle (fresh 14228 of "cans touching": "open top"). A cup's
    rim, nothing beyond it, stays its top."""
    s = cs.CylinderSearchConfig()
    rng = np.random.default_rng(3)

    def disc(cx, cy, radius, z):  # a lid sampled every 2 mm, as a sensor's grid does
        x, y = (v.ravel() for v in np.meshgrid(*[np.arange(-radius, radius, 0.002)] * 2))
        x, y = x[np.hypot(x, y) <= radius], y[np.hypot(x, y) <= radius]
        return np.c_[cx + x, cy + y, z + rng.normal(0, 0.0005, len(x))]

    can_lid = disc(-0.001, -0.007, 0.029, 0.141)
    neighbour_lid = disc(0.0365, 0.0445, 0.033, 0.157)
    n_lid, n_both = len(can_lid), len(can_lid) + len(neighbour_lid)
    a = rng.uniform(0, 2 * np.pi, 400)
    side = np.c_[-0.001 + 0.029 * np.cos(a), -0.007 + 0.029 * np.sin(a), rng.uniform(0.01, 0.14, 400)]
    pts = np.concatenate([can_lid, neighbour_lid, side])
    dist = np.hypot(pts[:, 0], pts[:, 1])
    theirs = cs._top_from_beside(pts[:, :2], dist, np.abs(pts[:, 2] - 0.157) <= 0.5 * s.band_height, 0.035, 0.006)
    assert theirs[n_lid:n_both][dist[n_lid:n_both] <= 0.035].all() and not theirs[:n_lid].any()
    assert cs._lid(pts[:, :2], dist, pts[:, 2], 0.035, 0.006, 0.01, 0.14, s, fitted=True) == \
        pytest.approx(0.141, abs=0.002)
    # The same without the neighbour: the cup's rim (a ring at 157 mm) over its inside stays the top.
    rim = np.c_[0.031 * np.cos(a), 0.031 * np.sin(a), 0.157 + rng.normal(0, 0.0005, 400)]
    cup = np.concatenate([can_lid, rim, side])
    dist = np.hypot(cup[:, 0], cup[:, 1])
    assert cs._lid(cup[:, :2], dist, cup[:, 2], 0.035, 0.006, 0.01, 0.14, s, fitted=True) == \
        pytest.approx(0.157, abs=0.002)


def test_a_can_in_front_of_a_taller_one_it_touches_is_found_with_its_own_height():
    """Fresh 14228 of "cans touching": a can of r 29 mm, 142 mm high, in front of one of r 33 mm, 159
    mm, is found within 2 mm with its own height, not rejected as an open top."""
    scene = sc.generate_scene(so.case_spec("cans touching", 14228))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    result = af.find_cans(scene.xyz)
    for truth in scene.truth["objects"]:
        base = transforms.apply(to_table, truth["base_center"])
        can = nearest_can(result.cans, to_table, base)
        why = [r.reason for r in result.rejected]
        assert np.hypot(*(table_xy(to_table, can)[:2] - base[:2])) < CENTRE_TOLERANCE, why
        assert abs(can.height - truth["height"]) < 0.005, (can.height, truth["height"])


def test_a_can_behind_one_it_touches_seen_by_a_noisy_crescent_of_lid_is_found():
    """Fresh 14009 of "cans touching": a can of r 35 mm, 95 mm high, behind a taller one it touches,
    shows a crescent of lid (60 points at 1.2 m, the rest in the front can's shadow) and a sliver of
    side; its rim's noisy outline fits a circle 5 mm too wide that overlaps the front can. The circle
    refitted touching that can is the lid's: found within the tolerance, its base hidden."""
    scene = sc.generate_scene(so.case_spec("cans touching", 14009))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    result = af.find_cans(scene.xyz)
    why = [r.reason for r in result.rejected]
    assert len(result.cans) == 2, why
    for truth in scene.truth["objects"]:
        base = transforms.apply(to_table, truth["base_center"])
        can = nearest_can(result.cans, to_table, base)
        assert np.hypot(*(table_xy(to_table, can)[:2] - base[:2])) < CENTRE_TOLERANCE, why


def test_a_can_behind_a_lying_one_seen_by_a_sparse_lid_and_a_short_side_is_found():
    """Fresh 14728 of "lying can touching can": a can of r 28 mm, 100 mm high, behind a lying can
    whose end touches it, shows its lid (about 100 points) and 20 mm of side over the lying can, too
    little for the rounds (21 points on their circle). Its lid's sparse outline, fitted on its hull,
    gives a circle 3.9 mm off, through which its own side is seen; pinned by that side, the can is
    found within the tolerance, on the table, its base hidden, and the lying can lying."""
    scene = sc.generate_scene(so.case_spec("lying can touching can", 14728))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    result = af.find_cans(scene.xyz)
    why = [r.reason for r in result.rejected]
    upright = [c for c in result.cans if not c.lying]
    assert len(upright) == 1 and len(result.cans) == 2, why
    truth = next(t for t in scene.truth["objects"] if t["is_can"] and not t["lying"])
    base = transforms.apply(to_table, truth["base_center"])
    can = upright[0]
    assert np.hypot(*(table_xy(to_table, can)[:2] - base[:2])) < CENTRE_TOLERANCE, why
    assert can.radius == pytest.approx(truth["radius"], abs=0.0015)
    assert can.support == "table" and not can.base_seen


def test_a_can_behind_two_taller_ones_is_fitted_by_its_side_and_its_lids_rim():
    """A wide can behind two taller ones shows a 0.55-rad stripe of side through the gap between them
    (no circle fits it alone) and its lid's rim over 1.3 rad, the rest of the rim in the front cans'
    shadow: the circle through the stripe and the rim's unshadowed part is the can's (within 3 mm,
    radius within 1.5 mm; the camera and cans of held-out 1207 of "cluttered table")."""
    objects = [Obj("can", -0.1554, 0.1291, radius=0.0427, height=0.0947),
               Obj("can", -0.1966, 0.0533, radius=0.0365, height=0.1174),
               Obj("can", -0.1038, 0.0690, radius=0.0317, height=0.1296)]
    _, result, to_table = search(objects, camera_distance=0.704, tilt=0.634, yaw=-0.248)
    assert len(result.cans) == 3, [r.reason for r in result.rejected]
    errors = [np.hypot(*(table_xy(to_table, c)[:2] - (-0.1554, 0.1291))) for c in result.cans]
    can = result.cans[int(np.argmin(errors))]
    assert min(errors) < 0.003 and can.radius == pytest.approx(0.0427, abs=0.0015)
    assert can.arc_coverage < cs.CylinderSearchConfig().min_hidden_arc


def test_can_on_a_tin_stands_on_an_object_at_the_tin_height():
    """A can on a wide tin is reported with support 'object' and its base at the tin's top."""
    objects = [Obj("tin", 0.0, 0.0, radius=0.1, height=0.07), Obj("can", 0.01, 0.0, 0.07, radius=0.035, height=0.11)]
    _, result, to_table = search(objects)
    assert_cans_at(result, to_table, objects)
    can = result.cans[0]
    assert can.support == "object" and can.base_seen
    assert can.support_height == pytest.approx(0.07, abs=0.006)
    assert table_xy(to_table, can)[2] == pytest.approx(0.07, abs=0.006)
    assert can.height == pytest.approx(0.11, abs=0.01)


def test_cup_on_a_can_leaves_the_can_and_names_the_cup():
    """A wider cup on a can: the can is found, the cup rejected by the open-top rule."""
    objects = [Obj("can", 0.0, 0.0, radius=0.033, height=0.11), Obj("cup", 0.0, 0.0, 0.11, radius=0.042, height=0.09)]
    _, result, to_table = search(objects)
    assert_cans_at(result, to_table, objects)
    assert any(r.reason.startswith("open top") for r in result.rejected), [r.reason for r in result.rejected]


@pytest.mark.parametrize("tilt, distance", [(0.55, 0.74), (0.5, 0.9)])
def test_a_cup_on_a_tall_can_seen_from_low_is_open(tilt, distance):
    """Seen from low, a cup on a tall can shows only the top 2-3 cm of its far inner wall (2 r
    tan(elevation) below its rim): counted against its near side over as many centimetres, not
    open_window, the cup is open, not a can (fresh seed 2200 of "cup on can")."""
    objects = [Obj("can", 0.0, 0.0, radius=0.033, height=0.147),
               Obj("cup", 0.0, 0.0, 0.147, radius=0.041, height=0.0885, yaw=-2.4)]
    _, result, to_table = search(objects, tilt=tilt, camera_distance=distance)
    assert_cans_at(result, to_table, objects)
    assert any(r.reason.startswith("open top") for r in result.rejected), [r.reason for r in result.rejected]


def test_a_cup_on_a_can_seen_from_far_is_not_judged_on_one_circle_with_it():
    """From 1.3 m a circle between a can and the cup 8 mm wider on it lay within r_eps of both: its
    bands' points near it sat 2.5 mm inside below and 2 mm outside above, the run took both, and
    the cup's open top claimed the can with it (fresh seed 3801 of "cup on can"). The part above
    the step is judged alone: the cup is named, the can found."""
    spec = so.case_spec("cup on can", 3801)
    scene = sc.generate_scene(spec)
    result = af.find_cans(scene.xyz)
    assert_cans_at(result, transforms.invert(np.asarray(scene.truth["camera_from_table"])), spec.objects)
    assert any(r.reason.startswith("open top") for r in result.rejected), [r.reason for r in result.rejected]


def test_offset_step_splits_a_run_where_its_bands_move_off_the_circle():
    """Bands 0-9 2.5 mm inside the circle, 10-19 2 mm outside: the step (4.5 mm) splits the run and
    the part nearer the circle is kept, though it has fewer points (a hypothesis on a can under a
    wider cup, fresh 8712 of "cup on can"); a side within noise of its circle is not split."""
    bands = np.repeat(np.arange(20), [20] * 10 + [30] * 10)
    residual = np.where(bands < 10, -0.0025, 0.002)
    assert cs._offset_step(bands, residual, 0, 19, 0.003) == (10, 19)
    assert cs._offset_step(bands + 5, residual, 5, 24, 0.003) == (15, 24)
    assert cs._offset_step(bands, np.where(bands < 10, 0.0002, 0.0048), 0, 19, 0.003) == (0, 9)
    assert cs._offset_step(bands, np.where(bands < 10, -0.0005, 0.0005), 0, 19, 0.003) is None


@pytest.mark.parametrize("tilt", [0.7, 1.1])
def test_a_can_under_a_wider_cup_ends_where_the_cup_begins(tilt):
    """The cup's overhang hides the top of the can's side (more, the steeper the sensor looks down):
    the can's height is the cup's base, not the highest side point seen."""
    can = Obj("can", 0.0, 0.0, radius=0.033, height=0.11)
    _, result, to_table = search([can, Obj("cup", 0.0, 0.0, 0.11, radius=0.045, height=0.08)], tilt=tilt)
    assert_cans_at(result, to_table, [can])
    assert result.cans[0].height == pytest.approx(0.11, abs=0.004)


def test_base_hidden_behind_a_box_is_inferred_on_the_table():
    """A box in front hiding the lower part: the can is found, base_seen False, base on the table."""
    objects = [Obj("can", 0.0, 0.0, radius=0.035, height=0.15), Obj("box", 0.0, -0.08, size=(0.16, 0.03, 0.08))]
    scene, result, to_table = search(objects, tilt=0.6)
    assert not scene.truth["objects"][0]["base_seen"]
    assert_cans_at(result, to_table, objects)
    can = result.cans[0]
    assert not can.base_seen and can.support == "table"
    assert table_xy(to_table, can)[2] == pytest.approx(0.0, abs=0.002)  # the fitted table, not the true one
    assert can.height == pytest.approx(0.15, abs=0.01)


def test_cups_mugs_bowls_boxes_and_prisms_are_no_cans():
    """An open cup, a mug, a bowl, a turned box and a prism: no can, each rejection with a reason."""
    objects = [Obj("cup", -0.15, 0.0, radius=0.04, height=0.1),
               Obj("mug", 0.0, 0.12, radius=0.04, height=0.09, yaw=1.0),
               Obj("bowl", 0.15, 0.0, radius=0.07, height=0.06),
               Obj("box", 0.0, -0.1, size=(0.05, 0.05, 0.15), yaw=0.7),
               Obj("prism", 0.12, -0.15, radius=0.045, height=0.12)]
    _, result, _ = search(objects, camera_distance=1.0)
    assert result.cans == [], result.message
    assert len(result.rejected) >= 4 and all(r.reason for r in result.rejected)


@pytest.mark.parametrize("yaw_deg", [200, 205])
def test_a_mugs_handle_beside_it_is_no_can(yaw_deg):
    """Seen steeply from close by with its handle to the side (the camera of held-out seed 808 of
    "mug and bowl"), a circle through the handle and the mug's wall is no can: it lies in the mug."""
    mug = Obj("mug", -0.137, 0.026, radius=0.0414, height=0.083, yaw=np.radians(yaw_deg))
    _, result, _ = search([mug], camera_distance=0.7, tilt=1.056, yaw=0.142)
    assert result.cans == [], result.message
    assert any("open top" in r.reason for r in result.rejected)


@pytest.mark.parametrize("tilt", [0.5, 0.6, 0.85])
def test_a_thick_walled_cup_is_open_not_a_can(monkeypatch, tilt):
    """A cup with a 10 mm wall (a ceramic mug's; learn39's show their inner wall 8-12 mm inside the
    circle): its inner wall on the far half is the inside of a hollow cylinder."""
    monkeypatch.setattr(so, "CUP_WALL", 0.010)
    _, result, _ = search([Obj("cup", 0.0, 0.0, radius=0.04, height=0.095)], tilt=tilt)
    assert result.cans == [], result.message
    assert any(r.reason.startswith("open top") for r in result.rejected), result.message


def side_points(r, top, angles, dr=0.0, z=None, n=40):
    """Points (N, 3) at radius r + dr about the origin at the given angles (rad), at heights z (m;
    default 1 cm up to the top, evenly)."""
    z = np.linspace(0.01, top, n) if z is None else np.asarray(z, float)
    a, zz = np.meshgrid(angles, z)
    return np.column_stack([(r + dr) * np.cos(a.ravel()), (r + dr) * np.sin(a.ravel()), zz.ravel()])


def handle_of(points, r, top, r_eps, others=np.empty((0, 3))):
    """_handle's answer for a can of radius r about the origin, base on the table, top at `top` (m),
    seen from along +x, 0.8 m up, the cluster's points and `others` (another cluster's) standing on
    the table."""
    ctx = type("Ctx", (), {"search": cs.CylinderSearchConfig(), "standing": np.concatenate([points, others]),
                           "sensor": np.array([1.0, 0.0, 0.8])})()
    return cs._handle(points, 0.0, 0.0, np.hypot(points[:, 0], points[:, 1]), r, r_eps, 0.0, top, ctx)


@pytest.mark.parametrize("below_top, handle", [((0.008, 0.014), False), ((0.03, 0.06), True)])
def test_a_lid_lip_is_no_handle_but_the_same_bump_lower_is(below_top, handle):
    """Points 12-14 mm outside a can's circle over a narrow arc: a lid's lip when they lie within
    open_depth of the top (learn43's coffee canister, at one grid offset), a mug's handle lower down."""
    r, top, r_eps = 0.058, 0.2, 0.006
    side = side_points(r, top, np.linspace(-1.4, 1.4, 60))
    bump = np.concatenate([side_points(r, top, np.linspace(0.2, 0.4, 6), dr=dr, z=np.linspace(top - below_top[1], top - below_top[0], 4))
                           for dr in (0.0125, 0.0135)])
    why = handle_of(np.concatenate([side, bump]), r, top, r_eps)
    assert bool(why) == handle, why


@pytest.mark.parametrize("heights, handle", [((0.094, 0.0965), False), ((0.07, 0.08, 0.09, 0.1), True)])
def test_points_at_one_height_beside_a_can_are_no_handle(heights, handle):
    """Points 16-20 mm outside a can's circle over 0.4 rad, 5 cm below its top: the top of a prism
    touching it, the rest hidden, when all lie within 2 r_eps of one height (fresh held-out "cluttered
    table" 3009: 12 points within 2.4 mm); a handle when they span its height."""
    r, top, r_eps = 0.036, 0.147, 0.0068
    side = side_points(r, top, np.linspace(-1.4, 1.4, 60))
    bump = np.concatenate([side_points(r, top, np.linspace(0.2, 0.6, 4), dr=dr, z=heights) for dr in (0.016, 0.02)])
    why = handle_of(np.concatenate([side, bump]), r, top, r_eps)
    assert bool(why) == handle, why


@pytest.mark.parametrize("with_top, handle", [(True, False), (False, True)])
def test_a_prisms_edge_beside_a_can_whose_top_runs_on_beyond_the_reach_is_no_handle(with_top, handle):
    """A column of 10 points 17-22 mm outside a can's circle, 4-7 cm up (the edge of a prism beside it,
    its top and bottom hidden: fresh 4605 of "cluttered table"), its top at 10.3 cm going on from
    there to 6 cm beyond handle_reach (in another cluster): another object, no handle. The column
    alone is one."""
    r, top, r_eps = 0.036, 0.135, 0.006
    side = side_points(r, top, np.linspace(-1.4, 1.4, 60))
    z = np.linspace(0.042, 0.073, 10)
    out = r + 0.017 + 0.005 * (z - 0.042) / 0.031
    edge = np.column_stack([out * np.cos(0.3), out * np.sin(0.3), z])
    along = np.linspace(r + 0.022, r + 0.095, 25)  # the top, 5 mm apart, turning away
    angle = 0.3 - 0.2 * (along - along[0]) / 0.073
    prism_top = np.column_stack([along * np.cos(angle), along * np.sin(angle), np.full(25, 0.103)])
    why = handle_of(np.concatenate([side, edge]), r, top, r_eps, prism_top if with_top else np.empty((0, 3)))
    assert bool(why) == handle, why


@pytest.mark.parametrize("wall_in_front, handle", [(True, False), (False, True)])
def test_a_column_beside_a_can_whose_lower_end_is_hidden_in_front_is_no_handle(wall_in_front, handle):
    """A column of points 17-22 mm outside a can's circle, 17-70 mm up (a cup's front wall seen between
    the can and a taller one in front, 4 mm from the can: fresh 5445 of "cluttered table"), with a wall
    15 cm nearer the sensor (another cluster) hiding where it would go on below: it may reach the
    support, no handle. With nothing in front it is one."""
    r, top, r_eps = 0.033, 0.097, 0.006
    side = side_points(r, top, np.linspace(-1.4, 1.4, 60))
    z = np.linspace(0.017, 0.07, 12)
    out = r + 0.017 + 0.005 * (z - 0.017) / 0.053
    column = np.column_stack([out * np.cos(0.3), out * np.sin(0.3), z])
    y, h = np.meshgrid(np.arange(-0.02, 0.05, 0.003), np.arange(0.0, 0.138, 0.003))
    wall = np.column_stack([np.full(y.size, 0.2), y.ravel(), h.ravel()])
    why = handle_of(np.concatenate([side, column]), r, top, r_eps, wall if wall_in_front else np.empty((0, 3)))
    assert bool(why) == handle, why


def test_points_are_reached_step_by_step_among_the_allowed_ones_only():
    """_reached follows points no more than `step` apart seen from above (heights apart), only
    through the allowed ones: a chain 5 mm apart is reached to its end; a gap of 12 mm or a point
    not allowed stops it."""
    x = np.array([0.0, 0.005, 0.010, 0.015, 0.027, 0.032])
    points = np.column_stack([x, np.zeros(6), [0.0, 0.1, 0.0, 0.1, 0.0, 0.1]])
    start = np.array([True, False, False, False, False, False])
    every = np.ones(6, bool)
    assert cs._reached(points, start, every, 0.006).tolist() == [True, True, True, True, False, False]
    assert cs._reached(points, start, every, 0.013).all()
    cut = every.copy()
    cut[2] = False
    assert cs._reached(points, start, cut, 0.006).tolist() == [True, True, False, False, False, False]


@pytest.mark.parametrize("seed", [402, 414, 416, 413, 417])
def test_a_narrow_box_is_no_can(seed):
    """"boxes and prisms", development seeds where a 4 x 4 cm box passed every other rule: a circle
    touching both faces of its corner (the corner outside it, beyond r_eps; 402, 414, 416), or its top
    passed the lid's rim tests (413, 417: its faces, seen down to the table, judged as a side on the
    rim's circle, are no can's: not round, or no points on it). No can."""
    scene = sc.generate_scene(so.case_spec("boxes and prisms", seed))
    result = af.find_cans(scene.xyz)
    assert result.cans == [], result.message


def test_a_small_boxs_top_whose_faces_show_under_it_is_no_hidden_can():
    """Fresh 4111 of "cluttered table": a 4.4 x 4.5 cm box's top passed the lid's rim tests (r 24 mm)
    and its faces, seen down to 16 mm over the table, were taken for a hidden can's side: 43 of the 94
    points near the circle lay more than min_can_height under the lid, not more than half. As many as
    min_fit_points lower are judged as a side. The one can found (within 3 mm), nothing else."""
    scene = sc.generate_scene(so.case_spec("cluttered table", 4111))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    result = af.find_cans(scene.xyz)
    truth = [transforms.apply(to_table, t["base_center"])[:2] for t in scene.truth["objects"] if t["is_can"]]
    found = [table_xy(to_table, c)[:2] for c in result.cans]
    assert len(truth) == 1 and len(found) == 1, result.message
    assert np.hypot(*(found[0] - truth[0])) < 0.003


def test_a_corner_the_circle_touches_is_two_flat_faces():
    """The same box alone, turned so that a circle touches both faces of the corner facing the
    camera: a can when the two halves' straightness is not looked at, none when it is."""
    obj = Obj("box", 0.0, 0.0, size=(0.04, 0.04, 0.17), yaw=np.pi / 6)
    spec = sc.SceneSpec(cans=[], objects=[obj], camera_distance=0.9, tilt=0.7, seed=7)
    xyz = sc.generate_scene(spec).xyz
    blind = af.AutoConfig(cylinders=cs.CylinderSearchConfig(max_facet_ratio=0.0))
    assert len(af.find_cans(xyz, config=blind).cans) == 1
    assert af.find_cans(xyz).cans == []


@pytest.mark.parametrize("seed", [0, 2, 14])
def test_every_can_on_a_cluttered_table_is_found_and_nothing_else(seed):
    """"cluttered table", development seeds with every can at least half in view: each upright can
    found within 3 mm, each lying can reported lying, nothing else (seed 14: a can with a cup touching
    it, seen between it and a can in front, was a mug)."""
    scene = sc.generate_scene(so.case_spec("cluttered table", seed))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    result = af.find_cans(scene.xyz)
    upright = [transforms.apply(to_table, t["base_center"])[:2] for t in scene.truth["objects"] if t["is_can"]]
    found = [table_xy(to_table, c)[:2] for c in result.cans if not c.lying]
    assert len(found) == len(upright), result.message
    for p in upright:
        assert min(np.hypot(*(f - p)) for f in found) < 0.003, (p, result.message)
    assert sum(c.lying for c in result.cans) == sum(t["lying"] for t in scene.truth["objects"])


def test_a_can_behind_a_taller_one_is_found_by_its_lid():
    """A can 2 mm behind a taller, wider one, its side hidden, its lid seen above it: found there
    (centre within CENTRE_TOLERANCE, radius within 2 mm, height within 5 mm), its base not seen."""
    front, back = Obj("can", 0.0, 0.0, radius=0.04, height=0.15), Obj("can", 0.01, 0.072, radius=0.03, height=0.12)
    _, result, to_table = search([front, back], camera_distance=0.9, tilt=1.1)
    assert_cans_at(result, to_table, [front, back])
    can = nearest_can(result.cans, to_table, (back.x, back.y))
    assert not can.base_seen and can.support == "table"
    assert can.radius == pytest.approx(back.radius, abs=0.002) and can.height == pytest.approx(back.height, abs=0.005)


@pytest.mark.parametrize("kind", ["cup", "box", "prism"])
@pytest.mark.parametrize("tilt", [1.0, 1.1])
def test_what_shows_only_its_top_behind_a_can_is_no_can_unless_round_and_closed(kind, tilt):
    """An open cup, a box or a prism behind a taller can, only its top seen above it: no can there."""
    front = Obj("can", 0.0, 0.0, radius=0.04, height=0.15)
    behind = Obj(kind, 0.01, 0.072, radius=0.03, height=0.12, size=(0.06, 0.06, 0.12), yaw=0.5)
    _, result, to_table = search([front, behind], camera_distance=0.9, tilt=tilt)
    assert_cans_at(result, to_table, [front, behind])


def lying_truth(obj):
    """(middle of the axis (3,), unit axis (3,)) of a lying_can Obj, table frame (m)."""
    return np.array([obj.x, obj.y, obj.z + obj.radius]), np.array([np.cos(obj.yaw), np.sin(obj.yaw), 0.0])


def test_fit_lying_cylinder_recovers_a_horizontal_cylinder():
    """Noisy points of the upper half of a horizontal cylinder (and one end's disc): its direction,
    axis height and radius are recovered."""
    from example_pcl import lying

    rng = np.random.default_rng(3)
    yaw, r, length = 2.2, 0.032, 0.14
    u, n = np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])
    a = rng.uniform(0, length, 1500)
    phi = rng.uniform(-0.3, np.pi + 0.3, 1500)
    rho = r + rng.normal(0, 0.0008, 1500)
    side = np.column_stack([0.1 + a * u[0] + rho * np.cos(phi) * n[0], -0.2 + a * u[1] + rho * np.cos(phi) * n[1],
                            r + rho * np.sin(phi)])
    disc_r, disc_phi = r * np.sqrt(rng.uniform(0, 1, 300)), rng.uniform(0, np.pi, 300)
    end = np.column_stack([0.1 + disc_r * np.cos(disc_phi) * n[0], -0.2 + disc_r * np.cos(disc_phi) * n[1],
                           r + disc_r * np.sin(disc_phi)])
    fit = lying.fit_lying_cylinder(np.concatenate([side, end]), 0.006, 0.015, 0.08, 0.01)
    assert fit is not None
    assert abs(fit.direction @ u) > np.cos(np.radians(1))
    assert fit.radius == pytest.approx(r, abs=0.001) and fit.zc == pytest.approx(r, abs=0.001)
    middle = fit.point_on_axis(((np.array([0.1, -0.2]) + 0.5 * length * u) - fit.origin) @ fit.direction)
    np.testing.assert_allclose(middle, [0.1 + 0.5 * length * u[0], -0.2 + 0.5 * length * u[1], r], atol=0.001)


def test_distinct_lying_hypotheses_are_ranked_by_score_and_judged_duplicate_by_their_points():
    """lying._distinct takes hypotheses in the order of their score (a closeness, not a count) and
    drops one sharing more than half the smaller one's points with one taken; a score of 0 or fewer
    than 3 points is never taken."""
    members = np.zeros((5, 10), bool)
    members[0, :6] = True  # 6 points
    members[1, 2:8] = True  # shares 4 of 6 with 0 and with 4
    members[2, 7:10] = True  # shares 1 of 3 with 1, none with 0 or 4
    members[3, 8:10] = True  # 2 points
    members[4, :6] = True  # as 0, but scored 0
    score = np.array([2.0, 2.5, 1.0, 9.0, 0.0])
    assert lying._distinct(members, score, count=3) == [1, 2]
    assert lying._distinct(members, score, count=1) == [1]
    score[1] = 1.5
    assert lying._distinct(members, score, count=3) == [0, 2]


def test_a_failed_lying_hypothesis_hides_none_of_its_duplicates():
    """What a hypothesis gives (attempt) decides whether it is taken: one that fails (None) hides
    none of the hypotheses sharing its points, which are tried in its place, at most max_attempts
    times in all."""
    members = np.zeros((4, 10), bool)
    members[0, :6] = True
    members[1, 1:7] = True  # shares 5 of 6 with 0
    members[2, 2:8] = True  # shares 4 of 6 with 0, 5 with 1
    members[3, 7:10] = True  # apart
    score = np.array([4.0, 3.0, 2.0, 1.0])
    tried = []

    def attempt(h):
        tried.append(h)
        return None if h == 0 else f"fit {h}"

    assert lying._distinct(members, score, count=2, attempt=attempt) == ["fit 1", "fit 3"]
    assert tried == [0, 1, 3]
    tried.clear()
    assert lying._distinct(members, score, count=2, attempt=attempt, max_attempts=2) == ["fit 1"]
    assert tried == [0, 1]


@pytest.mark.parametrize("yaw", [0.4, 1.6, 2.7])
def test_a_lying_can_is_reported_lying_with_its_axis(yaw):
    """A can on its side is reported lying (not upright), its axis within 2 degrees of the truth, the
    middle of its axis within 3 mm, its radius within 2 mm and its length within 1 cm."""
    obj = Obj("lying_can", 0.02, -0.01, radius=0.035, height=0.15, yaw=yaw)
    _, result, to_table = search([obj])
    assert len(result.cans) == 1 and result.cans[0].lying, (result.message, [r.reason for r in result.rejected])
    can = result.cans[0]
    middle, axis = lying_truth(obj)
    found_axis = transforms.apply(to_table, can.base_center + can.axis) - transforms.apply(to_table, can.base_center)
    assert abs(found_axis @ axis) > np.cos(np.radians(2)), (found_axis, axis)
    found_middle = transforms.apply(to_table, can.base_center + 0.5 * can.height * can.axis)
    assert np.linalg.norm(found_middle - middle) < 0.003, (found_middle, middle)
    assert can.radius == pytest.approx(0.035, abs=0.002) and can.height == pytest.approx(0.15, abs=0.01)
    # The pose's frame is right-handed with x up from the table (the marker's cylinder lies along z).
    R = can.T_sensor_from_can[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-9)
    assert np.linalg.det(R) == pytest.approx(1.0)
    up = transforms.apply(to_table, can.base_center + R[:, 0]) - transforms.apply(to_table, can.base_center)
    assert up[2] > 0.99
    assert can.to_dict()["lying"] is True


@pytest.mark.parametrize("box_x", [0.0, -0.04])
def test_a_lying_can_split_by_a_box_across_it_is_one_can(box_x):
    """A box standing in front of a long lying can, at its middle or 4 cm off it, hides it (two
    clusters): one lying can of the whole length is reported, its axis the can's. With the box 4 cm
    off, the shorter part shows only its top next to the box: cut there, 3.9 cm long, less than a
    can's least length, it was dropped and the can reported 106 mm short (before the run along the
    axis went on behind the box: lying._through_hidden)."""
    obj = Obj("lying_can", 0.0, 0.0, radius=0.038, height=0.24, yaw=0.0)
    box = Obj("box", box_x, -0.06, size=(0.05, 0.04, 0.25))
    _, result, to_table = search([obj, box])
    lying_cans = [c for c in result.cans if c.lying]
    assert len(result.cans) == 1 and len(lying_cans) == 1, (result.message, [r.reason for r in result.rejected])
    error, angle, _, length_error = lying_pose_error(lying_cans[0], obj, to_table)
    assert error < 0.005 and angle < np.radians(0.5) and abs(length_error) < 0.015, (error, angle, length_error)


def test_a_lying_can_beside_a_big_tin_is_found_once_the_tin_is_claimed():
    """A lying can touching a tin of r 99 mm (one cluster, fresh seed 2003 of "cluttered table"): on
    the lying search's subsample the tin's circles outrank the can's, so it is looked for again on
    what the tin's claim leaves, lid and all. One lying can within 5 mm, 1 degree, 2 mm of radius and
    1.5 cm of length; the tin rejected for its radius."""
    obj = Obj("lying_can", -0.095, 0.110, radius=0.0287, height=0.118, yaw=2.74)
    _, result, to_table = search([obj, Obj("tin", -0.263, 0.119, radius=0.0994, height=0.0793)])
    assert len(result.cans) == 1 and result.cans[0].lying, (result.message, [r.reason for r in result.rejected])
    error, angle, radius_error, length_error = lying_pose_error(result.cans[0], obj, to_table)
    assert error < 0.005 and angle < np.radians(1) and abs(radius_error) < 0.002 and abs(length_error) < 0.015, (
        error, angle, radius_error, length_error)
    assert any(r.reason.startswith("radius ") for r in result.rejected), [r.reason for r in result.rejected]


@pytest.mark.parametrize("obj", [
    Obj("box", 0.0, 0.0, size=(0.15, 0.07, 0.07), yaw=0.4),
    Obj("box", 0.0, 0.0, size=(0.16, 0.06, 0.05), yaw=2.0),
    Obj("lying_can", 0.0, 0.0, radius=0.1, height=0.07, yaw=0.5),
    Obj("lying_can", 0.0, 0.0, radius=0.1, height=0.07, yaw=1.9),
])
def test_lying_boxes_and_tins_are_no_lying_cans(obj):
    """A box lying flat (flat faces) and a tin of radius 100 mm on its side are no cans, upright or
    lying; each is rejected with the reason it is no lying can either."""
    _, result, _ = search([obj])
    assert result.cans == [], result.message
    assert result.rejected and all(r.reason for r in result.rejected)
    assert any("lying: " in r.reason for r in result.rejected), [r.reason for r in result.rejected]


def lying_pose_error(can, obj, to_table):
    """(middle error (m, 3-D), axis angle (rad), radius error (m), length error (m)) of a lying Can
    against a lying_can Obj (table frame)."""
    middle, axis = lying_truth(obj)
    found_axis = transforms.apply(to_table, can.base_center + can.axis) - transforms.apply(to_table, can.base_center)
    found_middle = transforms.apply(to_table, can.base_center + 0.5 * can.height * can.axis)
    return (np.linalg.norm(found_middle - middle), np.arccos(min(1.0, abs(found_axis @ axis))),
            can.radius - obj.radius, can.height - obj.height)


@pytest.mark.parametrize("name, objects", [
    ("box along its side", [Obj("lying_can", 0.0, 0.0, radius=0.034, height=0.15, yaw=0.3),
                            Obj("box", -0.075 * np.sin(0.3), 0.075 * np.cos(0.3), size=(0.08, 0.12, 0.1),
                                yaw=0.3 + np.pi / 2)]),
    ("box at its end", [Obj("lying_can", 0.0, 0.0, radius=0.034, height=0.15, yaw=1.2),
                        Obj("box", (0.075 + 0.041) * np.cos(1.2), (0.075 + 0.041) * np.sin(1.2), size=(0.08, 0.1, 0.12),
                            yaw=1.2)]),
    ("upright can beside it", [Obj("lying_can", 0.0, 0.0, radius=0.034, height=0.15, yaw=0.3),
                               Obj("can", -0.071 * np.sin(0.3), 0.071 * np.cos(0.3), radius=0.036, height=0.12)]),
    ("two lying cans side by side", [Obj("lying_can", 0.0, 0.0, radius=0.034, height=0.15, yaw=0.3),
                                     Obj("lying_can", -0.067 * np.sin(0.3) + 0.02 * np.cos(0.3),
                                         0.067 * np.cos(0.3) + 0.02 * np.sin(0.3), radius=0.032, height=0.12,
                                         yaw=0.3)]),
])
def test_a_lying_can_touching_another_object_is_found_with_its_pose(name, objects):
    """A lying can touching a box (along its side or at its end), an upright can or another lying can
    (all 1 mm apart or less) is reported lying, its middle within 3 mm, its axis within 1 degree,
    radius within 1 mm and length within 1 cm; the upright can is found too, and nothing else."""
    _, result, to_table = search(objects)
    lying_objects = [o for o in objects if o.kind == "lying_can"]
    lying_cans = [c for c in result.cans if c.lying]
    assert len(lying_cans) == len(lying_objects), (name, result.message, [r.reason for r in result.rejected])
    for obj in lying_objects:
        errors = min((lying_pose_error(c, obj, to_table) for c in lying_cans), key=lambda e: e[0])
        assert errors[0] < 0.003 and errors[1] < np.radians(1), (name, errors)
        assert abs(errors[2]) < 0.001 and abs(errors[3]) < 0.01, (name, errors)
    assert_cans_at(dataclasses.replace(result, cans=[c for c in result.cans if not c.lying]), to_table, objects)


@pytest.mark.parametrize("case", ["lying can touching box", "lying can touching can", "lying cans touching"])
@pytest.mark.parametrize("seed", [0, 2, 4])
def test_generated_lying_cans_touching_are_found(case, seed):
    """On the generated cases of lying cans touching a box, an upright can or each other (development
    seeds), every lying can is found (middle of its axis within 5 mm, axis within 1 degree, radius
    within 1.5 mm), every upright can too, and nothing else."""
    assert_generated_lying_cans_found(case, seed)


@pytest.mark.parametrize("case, seed", [("lying can touching box", 1000), ("lying cans touching", 904),
                                        ("lying cans touching", 1007), ("lying can touching box", 601),
                                        ("lying can touching box", 803), ("lying can touching box", 1209),
                                        ("cluttered table", 1602), ("lying can touching box", 3514),
                                        ("cluttered table", 54), ("lying can touching box", 3834),
                                        ("lying cans touching", 4535), ("lying can touching can", 4542),
                                        ("cluttered table", 9503), ("cluttered table", 10001),
                                        ("cluttered table", 10143)])
def test_held_out_lying_misses_are_found_where_they_lie(case, seed):
    """Held-out seeds looked at since. 1000: a lying can whose end touches a box was found 3.4 cm short
    (every 7th point of the cluster, the fit's sample, left two bands next to the box with two points
    each, and the run of bands the circle explains ended there; counted on every point now). 904,
    1007: a lying can behind another, touching it, seen only above the front one over 1.73 and 1.52
    rad, less than min_arc (the rest of its near half is hidden: lying._rest_hidden). 601: a box at its
    end as wide and high as the can, its flank points 2-13 mm off the circle, 23 of 48 more than r_eps,
    was not cut off the can's run (4.5 cm too long; the flank test counts those off by r_eps / 2 now).
    803: a box 57 mm high along the can's side; the circles through the can and the box's top edge
    (r 53 mm, their bottom 34 mm under the table) scored most, failed to refine and hid the can's own
    as their duplicates (a circle reaching more than max_gap under the table is no hypothesis now).
    1209: a box at its end as high and as wide as the can; a circle around both (rms 1.9 mm) passed
    and was taken before the can's own (0.5 mm, lying._tighter).
    1602: a cup in front of one end, 18 mm from it and taller: only its top shows there, fewer
    points than band_fraction of the fullest band, and the can came out 69 mm long for 102, its
    middle 15.6 mm off (the run of bands goes on where the rest of its near half is hidden behind
    something nearer now: lying._through_hidden).
    3514 (fresh, first run of 3500-3549) and development 54 of "cluttered table": a box at the end, as
    wide as the can and 9 mm lower, its top meeting the circle on both flanks (and inside it between)
    and its face near the flank: the run went on over it, the can 49 and 16 mm too long (its middle 24
    and 10 mm off); a band whose crown holds as many points inside the circle as on it ends the run now.
    3834 (fresh): a box as wide as the can and 5 mm lower at its end, its flank 6.2 mm rms off the
    circle against 2.3 for the rest of the run, whose band at the other end (the end's disc's rim)
    scatters as much: the run went on over the box, 48 mm too long (the rest is judged without that
    band now: lying._without_flat_end).
    4535 (fresh): a lying can behind another, seen over 1.20 rad above it; past the front can's end its
    side shows lower, but only within the slab of r_eps at its own end, which the side leaves out, and
    its rest there was taken for unhidden (what is seen counts up to its ends now). 4542 (fresh): the
    upright can a lying can's end touches, found 99 mm high for 150 with a false can on it: its
    hypothesis, refined at the lying can's height, came out 7 mm small and its bands were judged on that
    circle (verified again from the fit when that moves by more than r_eps now, not 2 r_eps).
    9503 (fresh): a bowl's far wall 2 cm in front of a lying can's end crosses its circle: the run went
    on over the gap to it, the can 33 mm too long (a gap whose edge shows an end's disc parts the run
    now: lying._apart_at_seen_end).
    10001 and 10143 (fresh): a lying can behind an upright can, its top seen over it: the run stopped
    at a band whose only part not hidden was its far limb, where the samples lie 19 degrees apart and
    none fell (a part unseen by more than half the 12 degrees between the places looked at), 38 and 59
    mm short (a false can on the rest of 10143's); such a part counts as seen now.
    Each found as in test_generated_lying_cans_touching_are_found, a can behind another's radius
    within 2 mm (its circle seen over so short an arc is less sure)."""
    assert_generated_lying_cans_found(case, seed, radius_tolerance=0.002)


def test_a_lying_cans_run_parts_at_a_gap_whose_edge_shows_an_ends_disc():
    """Bands 0-1 another object's wall (20 points on the circle), band 2 a gap, 3-11 a can's side
    (15 each): with the can's end disc (6 points inside its circle, 1 mm thick along the axis, 2 cm
    across) at band 3's edge next to the gap, the run keeps bands 3-11; the disc on band 3's far half,
    or no disc, leaves the run whole."""
    band, a0 = 0.01, 0.0
    band_on = np.array([20, 20, 1] + [15] * 9)
    rng = np.random.default_rng(0)

    def run_with(disc_axial):
        axial = np.concatenate([a0 + (np.arange(len(band_on)) + 0.5) * band, disc_axial])
        inside = np.r_[np.zeros(len(band_on), bool), np.ones(len(disc_axial), bool)]
        dl = np.r_[np.zeros(len(band_on)), rng.uniform(-0.01, 0.01, len(disc_axial))]
        dz = np.r_[np.zeros(len(band_on)), rng.uniform(-0.01, 0.01, len(disc_axial))]
        bands = ((axial - a0) / band).astype(np.int64)
        band_inside = np.bincount(bands[inside], minlength=len(band_on))
        return lying._apart_at_seen_end((0, 11), band_on, band_inside, bands, axial, dl, dz, inside, a0, band,
                                        0.2, 3)

    assert run_with(0.0305 + 0.001 * rng.random(6)) == (3, 11)
    assert run_with(0.0375 + 0.001 * rng.random(6)) == (0, 11)
    assert run_with(np.zeros(0)) == (0, 11)


def _flat_end_bands(spread, flank_off, n=40, diagonal=12):
    """Points within 3 r_eps of a lying can's circle, per band b: `diagonal` on the flank, on the
    circle or, where flank_off[b], spread[b] (m) outside it; the rest spread[b] in or out in turn.
    Returns (bands, residuals (m), on the flank)."""
    bands, residual, flank = [], [], []
    for b, (a, off) in enumerate(zip(spread, flank_off)):
        res = a * (-1.0) ** np.arange(n)
        res[:diagonal] = a if off else 0.0
        bands.append(np.full(n, b))
        residual.append(res)
        flank.append(np.arange(n) < diagonal)
    return np.concatenate(bands), np.concatenate(residual), np.concatenate(flank)


def test_a_box_at_a_lying_cans_end_is_cut_off_its_run_not_the_cans_ends():
    """Bands 0 and 12 are the can's ends (their discs' rims scatter, 6-7.5 mm rms, the flank on the
    circle), 1-11 its side (0.8 mm), 13-19 a box beyond its end (6.5 mm, the flank off): the run ends
    at band 12. The other end's band counts in no ratio (with it the box scattered less than 3 times
    the rest's rms: fresh 3834 of "lying can touching box"), and the last band stays for its flank
    though it scatters 3 times the rest's (held-out 1403)."""
    spread = [0.009] + [0.001] * 11 + [0.007] + [0.0065] * 7
    bands, residual, flank = _flat_end_bands(spread, [False] * 13 + [True] * 7)
    assert lying._without_flat_end(bands, residual, flank, (0, 19), 0.006) == (0, 12)
    # A can whose side scatters alike throughout keeps its run.
    bands, residual, flank = _flat_end_bands([0.001] * 20, [False] * 20)
    assert lying._without_flat_end(bands, residual, flank, (0, 19), 0.006) == (0, 19)


def test_a_lying_can_whose_end_touches_a_tall_box_is_found():
    """Held-out seed 902 of "lying can touching box", looked at since: a box 131 mm high at the can's
    end. Of the can's own subset, the circle ranked first by its number of points (57, against 56 of
    the next direction's) refined onto a circle of r 20 mm and hid the next, which refines onto the
    can; ranked by its points' closeness to the circle, the can is found. Its end at the box is
    12 mm short (what the box's shadow leaves of it), so its middle is within 8 mm."""
    assert_generated_lying_cans_found("lying can touching box", 902, middle_tolerance=0.008)


def _wall(x0, x1, y, height=0.25, spacing=0.003):
    """Points (float (N, 3), m) of a vertical wall across x0..x1 at y, from the table up to height."""
    x, z = np.meshgrid(np.arange(x0, x1, spacing), np.arange(0.0, height, spacing))
    return np.column_stack([x.ravel(), np.full(x.size, y), z.ravel()])


def _lying_side(start, length, radius, spacing=0.003):
    """Points (float (N, 3), m) of the upper half of a lying can's side along x from start."""
    a, t = np.meshgrid(np.arange(0.0, length, spacing), np.linspace(0.0, np.pi, 40))
    return np.column_stack([start[0] + a.ravel(), start[1] + radius * np.cos(t.ravel()),
                            start[2] + radius * np.sin(t.ravel())])


@pytest.mark.parametrize("wall, hidden", [(None, (False, False)), ((0.08, 0.25), (False, True)),
                                          ((-0.15, 0.03), (True, False)), ((-0.15, 0.25), (True, True))])
def test_an_end_behind_a_wall_in_front_is_hidden(wall, hidden):
    """A lying can 0.12 m long along x (r 30 mm), the sensor in front of it: an end is hidden where a
    wall standing between the sensor and it covers the places beyond it, not otherwise; the can's own
    side, the nearest points to the sensor there, hides neither end."""
    start, sensor = np.array([0.0, 0.0, 0.03]), np.array([0.06, -0.6, 0.5])
    own = _lying_side(start, 0.12, 0.03)
    occluders = own if wall is None else np.vstack([own, _wall(*wall, -0.17)])
    assert lying.hidden_ends(start, [1.0, 0.0, 0.0], 0.12, 0.03, 0.006, sensor, occluders) == hidden


@pytest.mark.parametrize("projector, hidden", [(None, (False, False)), ((0.6, -0.6, 0.5), (False, True)),
                                               ((-0.5, -0.6, 0.5), (False, False))])
def test_an_end_in_the_projectors_shadow_is_hidden(projector, hidden):
    """The lying can above; a wall to the front right of its +x end, beside the sensor's rays to the
    places beyond that end (it hides nothing from the sensor), but across the light to them from a
    projector to the sensor's right: that end is hidden (no depth in the shadow, fresh 6847 of
    "cluttered table"); not with no projector known, nor with one to the left."""
    start, sensor = np.array([0.0, 0.0, 0.03]), np.array([0.06, -0.6, 0.5])
    occluders = np.vstack([_lying_side(start, 0.12, 0.03), _wall(0.16, 0.4, -0.1)])
    assert lying.hidden_ends(start, [1.0, 0.0, 0.0], 0.12, 0.03, 0.006, sensor, occluders,
                             projector=None if projector is None else np.array(projector)) == hidden


def test_an_end_past_which_the_side_goes_on_where_the_rest_is_hidden_is_hidden():
    """The lying can above, a wall 17 cm high in front hiding the lower part of its near half past its
    +x end, over which its top shows (60-120 degrees from its lateral axis): that end is seen with
    nothing past it but the wall; with the can's own top seen going on past it, it is hidden (fresh
    10024 of "cluttered table": a lying can going on behind an upright can, a strip of its top seen)."""
    r = 0.03
    start, sensor = np.array([0.0, 0.0, r]), np.array([0.06, -0.6, 0.5])
    wall = _wall(0.08, 0.3, -0.17, 0.17)
    a, phi = np.meshgrid(np.arange(0.127, 0.16, 0.003), np.radians(np.linspace(60, 120, 13)))
    top = np.column_stack([a.ravel(), r * np.cos(phi.ravel()), r + r * np.sin(phi.ravel())])
    assert lying.hidden_ends(start, [1.0, 0.0, 0.0], 0.12, r, 0.006, sensor, wall) == (False, False)
    assert lying.hidden_ends(start, [1.0, 0.0, 0.0], 0.12, r, 0.006, sensor, wall, own=top) == (False, True)


def test_a_lying_sides_samples_thin_out_toward_its_limbs():
    """A lying can (r 30 mm) 0.8 m from the sensor, its near half seen but for 12 degrees at its far
    limb, nothing in front: with the grid's ray angle known (3.5 mrad), samples lie 20 degrees apart
    there (5.3 facing the sensor) and that part counts as seen (fresh 10001 of "cluttered table"); without, it is a part
    unseen, not hidden."""
    r = 0.03
    sensor = np.array([0.06, -0.6, 0.5])
    toward = np.arctan2(*lying._toward_sensor(0.0, 0.0, r, sensor)[::-1])
    angles = g.near_half_angles(toward)
    seen = np.linspace(angles.min() + np.radians(12), angles.max(), 60)
    nothing = np.array([[1.0, 1.0, 0.0]])
    assert not lying._hidden_where_unseen((0.0, 0.0, r, r), [0.06], seen, sensor, nothing)
    assert lying._hidden_where_unseen((0.0, 0.0, r, r), [0.06], seen, sensor, nothing, ray_angle=0.0035)
    arc = lying._sample_arc(angles, toward, r, 0.8, 0.0035)
    assert np.degrees(arc[0]) == pytest.approx(20.0, abs=1.0) and np.degrees(arc[6]) == pytest.approx(5.3, abs=0.1)


@pytest.mark.parametrize("seed", [3531, 3542, 10024])
def test_a_lying_can_whose_end_a_box_in_front_hides_starts_from_the_end_seen(seed):
    """Fresh seeds 3531 and 3542 of "cluttered table", looked at since: a tall box standing apart in
    front of one end of a lying can hides 33 and 48 mm of it; 10024: an upright can 16 cm high in front
    hides the far 45 mm but for a strip along its top, 1-2 points a band wide, found 88 mm long, its
    end seen (lying.hidden_ends: the side seen going on past it). Reported from the end seen (within 5
    mm of the truth's), end_seen False, its axis toward the end hidden; found so by bench_cans'
    scoring."""
    spec = so.case_spec("cluttered table", seed)
    scene = sc.generate_scene(spec)
    to_plane, cans, lying_truth_ = bench_cans.generated_truth(spec, scene)
    result = af.find_cans(scene.xyz)
    hidden = [c for c in result.cans if c.lying and not c.end_seen]
    assert len(hidden) == 1 and hidden[0].base_seen and hidden[0].ends_hidden == (False, True)
    can = hidden[0]
    origin = transforms.apply(to_plane, can.base_center)
    truth = min(lying_truth_, key=lambda t: np.linalg.norm(t["center"][:2] - origin[:2]))
    ends = [truth["center"] + s * 0.5 * truth["length"] * truth["axis"] for s in (-1.0, 1.0)]
    seen, cut = sorted(ends, key=lambda e: np.linalg.norm(e[:2] - origin[:2]))
    assert np.linalg.norm(origin[:2] - seen[:2]) < 0.005
    assert (transforms.apply(to_plane, can.base_center + can.axis) - origin) @ (cut - seen) > 0
    tally = bench_cans.Tally()
    bench_cans.score(tally, result.cans, cans, lying_truth_, to_plane, 0.015)
    assert (tally.missed, tally.false, tally.lying) == (0, 0, tally.lying_total)


def test_a_lying_can_whose_end_lies_in_a_tall_cans_shadow_starts_from_the_end_seen():
    """Fresh 6847 of "cluttered table": a lying can 199 mm long behind a can 147 mm high, its near 57 mm
    behind that can or, beside its silhouette, in its shadow from the IR projector (no depth there),
    was found 140 mm long from the hidden end (its middle 28 mm off: a false can and a miss). Its
    near end is hidden: reported from the end seen, within 5 mm of the truth's."""
    spec = so.case_spec("cluttered table", 6847)
    scene = sc.generate_scene(spec)
    to_plane, cans, lying_truth_ = bench_cans.generated_truth(spec, scene)
    result = af.find_cans(scene.xyz)
    ends = [t["center"] + s * 0.5 * t["length"] * t["axis"] for t in lying_truth_ for s in (-1.0, 1.0)]
    seen = max(ends, key=lambda e: e[1])  # the far end, (0.029, 0.27) m
    can = min((c for c in result.cans if c.lying),
              key=lambda c: np.linalg.norm(transforms.apply(to_plane, c.base_center)[:2] - seen[:2]))
    assert not can.end_seen and can.ends_hidden == (False, True)
    assert np.linalg.norm(transforms.apply(to_plane, can.base_center)[:2] - seen[:2]) < 0.005
    tally = bench_cans.Tally()
    bench_cans.score(tally, result.cans, cans, lying_truth_, to_plane, 0.015)
    assert (tally.missed, tally.false, tally.lying) == (0, 0, tally.lying_total)


@pytest.mark.parametrize("case, seed", [("lying can touching can", 6017), ("cluttered table", 6003)])
def test_a_lying_cans_run_goes_on_through_a_projector_shadow(case, seed):
    """Fresh 6017 and 6003: a lying can whose side lies, near one end, in the shadow an object beside it
    casts from the IR projector (no depth there; 6017: an upright can 160 mm high touching it) was cut
    short there, 128.5 of 137 mm and 118.1 of 124 mm long: the search's run goes on over bands hidden
    from the sensor or unlit by the projector (geometry.without_depth), as its ends' test does; now
    within 3 mm of the truth's length."""
    spec = so.case_spec(case, seed)
    scene = sc.generate_scene(spec)
    to_plane, cans, lying_truth_ = bench_cans.generated_truth(spec, scene)
    result = af.find_cans(scene.xyz)
    truth = min(lying_truth_, key=lambda t: t["center"][1])  # the front one (6003 has two)
    can = min((c for c in result.cans if c.lying), key=lambda c: np.linalg.norm(
        transforms.apply(to_plane, c.base_center + 0.5 * c.height * c.axis)[:2] - truth["center"][:2]))
    assert abs(can.height - truth["length"]) < 0.003, (can.height, truth["length"])


@pytest.mark.parametrize("seed", [61, 62, 90])
def test_an_end_touching_a_box_is_seen(seed):
    """Development seeds of "lying can touching box" with the box at the can's end, taller than it:
    the box touching the end is in the can's cluster and bounds it there, it does not hide it
    (end_seen and base_seen True; counted as hiding, a box at the end marked the lying can of 28 of the
    case's 100 development scenes)."""
    result = af.find_cans(sc.generate_scene(so.case_spec("lying can touching box", seed)).xyz)
    lying_cans = [c for c in result.cans if c.lying]
    assert len(lying_cans) == 1 and lying_cans[0].end_seen and lying_cans[0].base_seen
    assert lying_cans[0].ends_hidden == (False, False)


@pytest.mark.parametrize("seed", [7144, 7205, 7334, 6408, 5434, 7830])
def test_a_lying_can_along_a_taller_box_is_found_without_the_boxs_points(seed):
    """Fresh seeds of "lying can touching box" (first runs of 2026-12-05 and earlier): a box taller
    than the lying can touches its side, its points in every subset of the can's, whose circles
    failed to refine; drawn again without the box's points (lying._taller_box), the can is found.
    7830's box is told on every point of the cluster: the fit's subsample of its top filled 0.89 of
    its rectangle (0.98 on all of it)."""
    assert_generated_lying_cans_found("lying can touching box", seed)


@pytest.mark.parametrize("seed", [7710, 7428])
def test_a_lying_can_whose_circles_a_taller_box_pulled_wide_is_found_without_the_boxs_points(seed):
    """Fresh 7710 and 7428 of "lying can touching box" (first runs of 2026-12-05): a lying can seen
    nearly along its axis, its end against a taller box's face; the circles drawn with the box's
    points fitted a cylinder that failed judgement (7710: r 67 mm around both, its axis 50 mm up;
    7428: r 30 mm, 57 mm up), so no second draw was made. Drawn again without the box's points
    whenever no fit is a can, the can is found."""
    assert_generated_lying_cans_found("lying can touching box", seed)


def test_a_lying_can_drawn_without_a_taller_boxs_points_is_refitted_without_them():
    """Fresh 8400 of "lying can touching box" (first run of 8400-8449): a lying can (r 29.4 mm) along
    a taller box's face. Its circle drawn without the box's points (r 30.0 mm, rms 1.1 mm) was
    refitted along its run with them: the face, within the refit's cut-off on the half facing the
    sensor, pulled it to r 32.3 mm, 3 mm low, "not round". Refitted without them, it is found."""
    assert_generated_lying_cans_found("lying can touching box", 8400)


@pytest.mark.parametrize("radius", [0.028, 0.035, 0.05])
@pytest.mark.parametrize("noise", [0.0007, 0.002])
def test_a_lying_cans_top_strip_is_no_boxs_top(radius, noise):
    """A lying can alone (r 28-50 mm, depth noise 0.7-2 mm): its top within 3 mm of level is a strip 3-3.5
    cm wide filling its rectangle as a box's top does, but bent across (4-17 /m fitted; boxes' tops in
    "lying can touching box" and the cluttered table: 0-2.5): no box."""
    rng = np.random.default_rng(0)
    a, phi = rng.uniform(0, 0.15, 3000), rng.uniform(0.1 * np.pi, 0.9 * np.pi, 3000)
    can = np.c_[a, radius * np.cos(phi), radius + radius * np.sin(phi)] + rng.normal(0, noise, (3000, 3))
    assert lying._level_face(can[:, :2], can[:, 2], 0.003, 0.03).any()
    assert lying._taller_box(can[:, :2], can[:, 2], 0.003) is None


def test_a_lying_can_along_a_taller_box_4_cm_deep_is_found_without_the_boxs_points():
    """Fresh 8845 of "lying can touching box" (first run of 8800-8849): a lying can along a box 13 cm
    high and 4.4 cm deep, whose circles failed to refine; the box's top, narrower than the 5 cm a box's
    top had to span, was not told, so the can was not drawn again without it. Told from 3 cm, it is."""
    assert_generated_lying_cans_found("lying can touching box", 8845)


def test_a_lying_cans_run_is_found_again_until_its_axis_turns_no_more():
    """Fresh 8801 of "lying cans touching" (first run of 8800-8849): a lying can 186 mm long beside a
    shorter one. Its first fit pointed 8 degrees off, its refit on the run found along that 4 degrees
    off, and the run of that axis, cut 4 cm short of the near end, stood: the can was reported 147 mm
    long, 2 cm off its middle, and its end left a cluster of its own."""
    assert_generated_lying_cans_found("lying cans touching", 8801)


def test_a_lying_cans_run_is_found_again_when_its_refit_circle_grows():
    """Fresh 10917 of "lying can touching box" (first run of 10900-10949): a lying can (r 33 mm) end to
    end with a box 55 mm high. A circle drawn over both (r 28 mm, 4 mm low) met the box's top along its
    flanks and explained a run over both; refitted on it, r 32 mm, whose circle holds the box's top
    inside, on the same axis, the run stood: 44 mm too long, a lying miss and a false can. The run is
    found again when the refit's radius moves by more than r_eps / 2, as when its axis turns."""
    assert_generated_lying_cans_found("lying can touching box", 10917)


def test_a_lower_boxs_edge_beyond_a_lying_cans_end_is_no_side_of_it():
    """Fresh 10928 of "lying can touching box" (first run of 10900-10949): a lying can (r 35 mm) end to
    end with a box 45 mm high, wider than it. Past the can's end only the box's top edge and face met
    its circle, 4-8 points a band at 72-91 degrees from the top (the can's own: 25-36 over -25-75),
    enough for the run of bands, which went on 35 mm over the box. A band at the run's end whose points
    come near fewer than half its facing half, the rest in view of the sensor, is left out now."""
    assert_generated_lying_cans_found("lying can touching box", 10928)


def test_a_lower_narrower_boxs_level_top_beyond_a_lying_cans_end_is_no_side_of_it():
    """Fresh 11428 of "lying can touching box" (first run of 11400-11449): a lying can (r 38 mm) end to
    end with a box 7 mm lower and 63 mm wide. Its top and side faces lie within r_eps (6 mm) of the
    can's circle all across, scattering 4.4 mm rms against the can's 0.5, and its corner on the flank
    within 3 mm: the run went on 45 mm over it, a lying miss and a false can. Its crown is level, a
    can's bends down (1 / 2r); the bands at the run's end with a level crown are left out now."""
    assert_generated_lying_cans_found("lying can touching box", 11428)


def test_a_lying_can_is_found_when_a_circle_over_it_and_a_box_fails_to_refine():
    """Fresh 8312 of "lying can touching box" (first run of 8300-8349): a lying can end to end with a
    box 4 mm lower, seen from its far end. The best circle, drawn over the can's top and the box's,
    failed to refine and hid the circles of the can's own end, which share its points. A hypothesis
    that fails hides none now: the can is found."""
    assert_generated_lying_cans_found("lying can touching box", 8312)


@pytest.mark.parametrize("depth", [0.06, 0.04])
def test_a_box_is_told_only_when_it_stands_taller_than_something_beside_it(depth):
    """A box 12 cm high (8 cm wide, 6 or 4 cm deep: fresh 8845's box was 4.4 cm) and a lying can (r 3
    cm) along its front: the points under the box's top are the box's, the can's none. The box alone
    (nothing beside it), something beside it higher than it, or an upright can (a lid, no rectangle)
    beside the lying one: no box. Asked of a subsample (`at`), it answers for those points."""
    rng = np.random.default_rng(1)
    top = np.c_[rng.uniform(0, 0.08, 400), rng.uniform(0, depth, 400), np.full(400, 0.12)]
    front = np.c_[rng.uniform(0, 0.08, 300), np.zeros(300), rng.uniform(0, 0.12, 300)]
    side = np.c_[np.full(200, 0.08), rng.uniform(0, depth, 200), rng.uniform(0, 0.12, 200)]
    box = np.concatenate([top, front, side]) + rng.normal(0, 0.0007, (900, 3))
    a, phi = rng.uniform(0, 0.08, 300), rng.uniform(0.6 * np.pi, 1.4 * np.pi, 300)  # the half seen from the front
    can = np.c_[a, -0.031 + 0.03 * np.cos(phi), 0.03 + 0.03 * np.sin(phi)]

    def box_of(points):
        return lying._taller_box(points[:, :2], points[:, 2], 0.003)

    found = box_of(np.concatenate([box, can]))
    assert found[:900].mean() > 0.99 and not found[900:].any()
    # Asked of a subsample (`at`), it answers for those points, told on all of them.
    both = np.concatenate([box, can])
    at = lying._taller_box(both[:, :2], both[:, 2], 0.003, at=both[::7, :2])
    assert np.array_equal(at, found[::7])
    assert box_of(box) is None
    assert box_of(np.concatenate([box, can + [0.0, 0.0, 0.07]])) is None
    angle, height = rng.uniform(0, 2 * np.pi, 600), rng.uniform(0, 0.12, 600)
    lid = np.sqrt(rng.uniform(0, 1, 400)) * 0.035
    upright = np.concatenate([np.c_[0.035 * np.cos(angle[:200]), 0.035 * np.sin(angle[:200]), height[:200]],
                              np.c_[lid * np.cos(angle[200:]), lid * np.sin(angle[200:]), np.full(400, 0.12)]])
    assert box_of(np.concatenate([upright + [0.04, 0.035, 0.0], can])) is None


def assert_generated_lying_cans_found(case, seed, radius_tolerance=0.0015, middle_tolerance=0.005):
    scene = sc.generate_scene(so.case_spec(case, seed))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    result = af.find_cans(scene.xyz)
    truth = [t for t in scene.truth["objects"] if t["lying"]]
    lying_cans = [c for c in result.cans if c.lying]
    assert len(lying_cans) == len(truth), (result.message, [r.reason for r in result.rejected])
    for t in truth:
        obj = Obj("lying_can", *transforms.apply(to_table, np.add(t["base_center"], 0.5 * t["height"] * np.asarray(
            t["axis"])))[:2], radius=t["radius"], height=t["height"], yaw=t["yaw"])
        errors = min((lying_pose_error(c, obj, to_table) for c in lying_cans), key=lambda e: e[0])
        assert errors[0] < middle_tolerance and errors[1] < np.radians(1) and abs(errors[2]) < radius_tolerance, errors
    upright = [t for t in scene.truth["objects"] if t["is_can"]]
    assert len(result.cans) == len(truth) + len(upright), result.message
    for t in upright:
        base = transforms.apply(to_table, t["base_center"])
        assert min(np.hypot(*(table_xy(to_table, c)[:2] - base[:2])) for c in result.cans if not c.lying) < 0.002


def test_the_rest_of_a_lying_cans_side_is_hidden_only_behind_something_nearer():
    """A lying can (axis along x, r 35 mm) seen from the front above only over its top, where a lying
    can in front of it, touching it, leaves it in view: the rest of its near half is hidden behind
    that can; not behind nothing, nor behind a can beside it along its axis; seen all over its near
    half, nothing is left to hide."""
    r = 0.035
    fit = lying.LyingFit(direction=np.array([1.0, 0.0]), origin=np.zeros(2), offset=0.0, zc=r, radius=r, rms=0.0,
                         n_inliers=0)
    sensor = np.array([0.0, -0.8, 0.6])

    def surface(lateral, axial_from, axial_to):
        a, phi = np.meshgrid(np.arange(axial_from, axial_to, 0.002), np.linspace(0, 2 * np.pi, 120))
        return np.column_stack([a.ravel(), lateral + r * np.cos(phi).ravel(), r + r * np.sin(phi).ravel()])

    # Seen: the points of its section facing the sensor whose rays pass the front can (axis at
    # lateral -71 mm) by more than its radius.
    phi = np.linspace(0.0, 2 * np.pi, 361)
    p = np.column_stack([r * np.cos(phi), r + r * np.sin(phi)])
    ray = (sensor[1:] - p) / np.linalg.norm(sensor[1:] - p, axis=1)[:, None]
    to_front = np.array([-0.071, r]) - p
    facing = np.cos(phi) * ray[:, 0] + np.sin(phi) * ray[:, 1] > 0
    seen = facing & (np.abs(to_front[:, 0] * ray[:, 1] - to_front[:, 1] * ray[:, 0]) > r)
    assert 1.0 < np.ptp(phi[seen]) < 1.8  # less than min_arc, more than min_occluded_arc
    top_lateral, top_z = p[seen, 0], p[seen, 1]
    hidden = lying._rest_hidden
    assert hidden(fit, top_lateral, top_z, -0.07, 0.07, 0.005, sensor, surface(-0.071, -0.08, 0.08))
    assert not hidden(fit, top_lateral, top_z, -0.07, 0.07, 0.005, sensor, np.empty((0, 3)))
    assert not hidden(fit, top_lateral, top_z, -0.07, 0.07, 0.005, sensor, surface(0.0, 0.08, 0.2))
    assert hidden(fit, p[facing, 0], p[facing, 1], -0.07, 0.07, 0.005, sensor, np.empty((0, 3)))


def test_a_band_at_a_lying_cans_end_showing_a_stripe_of_its_side_in_view_leaves_the_run():
    """A lying can (axis along x, r 35 mm) whose side fills bands 0-9 (1 cm each) over its half facing
    the sensor, and bands 10-12 beyond show only a stripe at 60-66 degrees from the lateral axis (a
    lower box's edge, its top inside the circle in band 12): in a run of bands 0-11, bands 10-11
    leave it where the rest of that half would be in view; a wall in front hiding it keeps them, and
    a stripe at the run's start goes as one at its end. One band alone so is the can's own, its end
    within it (a lying can's last band, seen over its top only, development 31 of "lying can"), and
    no other object's points beyond the run is the image's edge across the can: the run stays."""
    r = 0.035
    fit = (0.0, 0.0, r, r)
    sensor = np.array([0.0, -0.8, 0.6])
    a, phi = np.meshgrid(np.arange(0.0005, 0.13, 0.002), np.radians(np.arange(56.0, 235.0, 2.0)))
    a, phi = a.ravel(), phi.ravel()
    keep = (a < 0.1) | (phi <= np.radians(66))
    a, phi = a[keep], phi[keep]
    dl, dz = r * np.cos(phi), r * np.sin(phi)
    bands, on = (a / 0.01).astype(np.int64), np.ones(len(a), bool)
    # The box's top beyond, inside the circle: no point of the can's side.
    bands, on = np.append(bands, np.full(5, 12)), np.append(on, np.zeros(5, bool))
    dl, dz = np.append(dl, np.linspace(-0.01, 0.01, 5)), np.append(dz, np.full(5, 0.02))

    def run(occluders, start=(0, 11)):
        return lying._without_bare_ends(start, bands, on, dl, dz, fit, 0.0, 0.01, 0.006, sensor, occluders, (0.0, 0.0))

    assert run(np.empty((0, 3))) == (0, 9)
    ya, yz = np.meshgrid(np.arange(0.09, 0.14, 0.002), np.arange(0.0, 0.2, 0.002))
    wall = np.column_stack([ya.ravel(), np.full(ya.size, -0.1), yz.ravel()])
    assert run(wall) == (0, 11)
    assert run(np.empty((0, 3)), start=(0, 10)) == (0, 10)
    assert run(np.empty((0, 3)), start=(0, 12)) == (0, 12)
    bands = 12 - bands  # the stripe at the start
    assert run(np.empty((0, 3)), start=(1, 12)) == (3, 12)


def test_a_level_crown_at_a_lying_cans_end_leaves_the_run():
    """A lying can (axis along x, r 38 mm, Kinect-like noise 0.5 mm) over bands 0-11 (1 cm each) and a
    box beyond it over bands 12-15, 7 mm lower and 63 mm wide: its top and side faces within r_eps
    (6 mm) of the circle, its top level. The box's bands leave the run, at either end; the can alone,
    or a box whose top bends as a can's side (a second can end to end with it), keeps its run."""
    r, width, top = 0.038, 0.0315, 0.069
    rng = np.random.default_rng(5)
    phi = np.radians(rng.uniform(-30.0, 130.0, 2000))  # about the half a sensor above and beside it sees
    a = rng.uniform(0.0, 0.12, 2000)
    can = np.c_[a, r * np.cos(phi), r * np.sin(phi)]
    # The box's profile across the axis: its side face at dl = width up to its top, then the top.
    s = rng.uniform(0.0, 1.0, 800)
    side_height, top_width = top - r, 2 * width
    along = s * (side_height + top_width)
    dl = np.where(along < side_height, width, width - (along - side_height))
    dz = np.where(along < side_height, along, top - r)
    box = np.c_[rng.uniform(0.12, 0.16, 800), dl, dz]
    keep = np.hypot(box[:, 1], box[:, 2]) > 0.6 * r
    box = box[keep]

    def run(points, start):
        points = points + rng.normal(0.0, 0.0005, points.shape)
        residual = np.hypot(points[:, 1], points[:, 2]) - r
        near = np.abs(residual) <= 3 * 0.006
        return lying._without_level_crown(start, (points[near, 0] / 0.01).astype(np.int64), points[near, 1],
                                          points[near, 2], residual[near], r)

    assert run(np.concatenate([can, box]), (0, 15)) == (0, 11)
    mirrored = np.concatenate([can, box]) * [-1.0, 1.0, 1.0] + [0.16, 0.0, 0.0]
    assert run(mirrored, (0, 15)) == (4, 15)
    assert run(can, (0, 11)) == (0, 11)
    other_can = can[can[:, 0] < 0.04] + [0.12, 0.0, 0.0]
    assert run(np.concatenate([can, other_can]), (0, 15)) == (0, 15)


def test_a_flat_face_is_no_lying_can_where_a_short_arc_is():
    """A lying cylinder (axis along x at 25 mm, r 32 mm) judged with the least arc of a hidden can
    (min_occluded_arc) on the circle's 0.7 rad facing the sensor, or on a box's vertical face there
    from 10 to 38 mm high that the circle crosses (1 mm inside it, as a fit puts it), both with the
    noise of a Kinect at 0.7 m: the arc is a lying can, the face is not (the real learn21 with its
    columns reversed: a box's front under an overhanging box, as round as its noise otherwise)."""
    rng = np.random.default_rng(21)
    config, search = af.AutoConfig(), cs.CylinderSearchConfig()
    r, zc, sigma, n = 0.032, 0.025, 0.0007, 300
    r_eps = max(config.r_eps, config.r_eps_sigmas * sigma)
    fit = lying.LyingFit(direction=np.array([1.0, 0.0]), origin=np.zeros(2), offset=0.0, zc=zc, radius=r, rms=0.0,
                         n_inliers=0)
    sensor = np.array([0.04, -0.45, 0.6])  # in front (-y) and above
    axial = rng.uniform(0.0, 0.08, n)
    phi = np.pi + rng.uniform(-0.35, 0.35, n)
    arc = np.c_[axial, r * np.cos(phi), zc + r * np.sin(phi)]
    face = np.c_[axial, np.full(n, 0.001 - r), rng.uniform(0.010, 0.038, n)]
    outcome = {}
    for name, points in (("arc", arc), ("face", face)):
        outcome[name] = lying.judge_lying(points + rng.normal(0.0, sigma, (n, 3)), fit, r_eps, sigma, config, search,
                                          sensor, min_arc=search.min_occluded_arc)
    assert outcome["arc"][0] is not None, outcome["arc"][1]
    assert outcome["face"][0] is None and "closer to a line" in outcome["face"][1], outcome["face"][1]


def test_the_run_along_a_lying_can_goes_on_where_its_side_is_hidden_behind_something_nearer():
    """A lying can (axis along x, r 30 mm, bands of 10 mm from x = -50 mm) whose three first bands
    show only the part of its near half above a wall 50 mm high in front of them: its run (bands 3-9)
    goes on over the bands the wall hides, not over those it does not, nor over a band with more
    points inside the circle than on it."""
    r = 0.03
    fit = (0.0, 0.0, r, r)
    sensor = np.array([0.0, -0.8, 0.3])
    # The section facing the sensor, and what of it shows over the wall (at lateral -60 mm).
    phi = np.linspace(0.0, 2 * np.pi, 361)
    p = np.column_stack([r * np.cos(phi), r + r * np.sin(phi)])
    ray = (sensor[1:] - p) / np.linalg.norm(sensor[1:] - p, axis=1)[:, None]
    facing = np.cos(phi) * ray[:, 0] + np.sin(phi) * ray[:, 1] > 0
    over = facing & (p[:, 1] + (-0.06 - p[:, 0]) / ray[:, 0] * ray[:, 1] > 0.05)
    assert 0 < over.sum() < facing.sum()
    bands, angles = np.repeat(np.arange(10), facing.sum()), np.tile(phi[facing], 10)
    seen = (bands >= 3) | np.tile(over[facing], 10)
    a, z = np.meshgrid(np.arange(-0.05, -0.02, 0.002), np.arange(0.0, 0.05, 0.002))
    wall = np.column_stack([a.ravel(), np.full(a.size, -0.06), z.ravel()])
    side_like = np.ones(10, bool)

    def run(occluders, side_like=side_like):
        may_join = side_like & (np.bincount(bands[seen], minlength=10) >= 3)
        return lying._through_hidden((3, 9), may_join, bands, seen, r * np.cos(angles), r * np.sin(angles), fit,
                                     -0.05, 0.01, 0.004, sensor, occluders, (0.0, 0.0))

    assert run(wall) == (0, 9)
    assert run(np.empty((0, 3))) == (3, 9)
    assert run(wall[wall[:, 0] >= -0.025]) == (2, 9)
    assert run(wall, side_like=np.arange(10) != 1) == (2, 9)


@pytest.mark.parametrize("seed", [1, 7])
def test_a_lying_can_with_a_lower_box_at_its_end_is_found_with_its_length(seed):
    """"lying can touching box", development seeds 1 and 7: a box 41-47 mm high at the can's end (the
    can 57-64 mm high), its top inside the circle beyond the end, was taken for the end's disc: the
    can came out 14-17 mm long, its middle 7-8 mm off. Found as test_generated_lying_cans_touching_are_found
    asks, and its length within 1 cm."""
    assert_generated_lying_cans_found("lying can touching box", seed)
    scene = sc.generate_scene(so.case_spec("lying can touching box", seed))
    truth = next(t for t in scene.truth["objects"] if t["lying"])
    (can,) = [c for c in af.find_cans(scene.xyz).cans if c.lying]
    assert abs(can.height - truth["height"]) < 0.01, (can.height, truth["height"])


def test_a_lying_cans_end_is_its_disc_not_a_lower_box_top_beyond_it():
    """Beyond the extent its circle explains (to 70 mm along the axis), a lying can's end is where
    the points inside its circle stand across the axis (its end's disc, at 72 mm); a lower box's top
    touching the end lies along it (72-80 mm, one height) and is not the can's."""
    rng = np.random.default_rng(2)
    r, zc, r_eps = 0.032, 0.032, 0.005
    side_axial = rng.uniform(-0.07, 0.07, 2000)
    side_angle = rng.uniform(0.2, np.pi - 0.2, 2000)
    disc_rho, disc_angle = 0.8 * r * np.sqrt(rng.uniform(0, 1, 200)), rng.uniform(0, np.pi, 200)
    # (axial, height above the axis, lateral), m
    disc = (0.072 + rng.normal(0, 0.0005, 200), disc_rho * np.sin(disc_angle), disc_rho * np.cos(disc_angle))
    top = (rng.uniform(0.072, 0.08, 200), 0.012 + rng.normal(0, 0.0005, 200), rng.uniform(-0.02, 0.02, 200))

    def ends(beyond, with_z=True):
        axial = np.concatenate([side_axial, beyond[0]])
        dz = np.concatenate([r * np.sin(side_angle), beyond[1]])
        dl = np.concatenate([r * np.cos(side_angle), beyond[2]])
        return lying.end_positions(axial, np.hypot(dl, dz), r, r_eps, (-0.07, 0.07), 0.01, zc + dz if with_z else None)

    assert ends(disc)[1] == pytest.approx(0.072, abs=0.001)
    assert ends(top)[1] == pytest.approx(0.07, abs=0.001)
    assert ends(top, with_z=False)[1] > 0.075
    assert ends(disc)[0] == pytest.approx(-0.07, abs=0.001)


@pytest.mark.parametrize("seed", [67, 78])
def test_a_box_top_beyond_a_lying_cans_end_is_not_its_side(seed):
    """A box touching a lying can's end, its top about as high as the can (75 and 59 mm, the cans'
    tops 75 and 62 mm), meets the can's circle along a stripe near its top: the box's top was taken
    for the can's side and the can reported 7 and 5 cm too long (development seeds of "lying can
    touching box"). Now it is its own length to within 1 cm, its middle within 5 mm."""
    scene = sc.generate_scene(so.case_spec("lying can touching box", seed))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    result = af.find_cans(scene.xyz)
    (t,) = [t for t in scene.truth["objects"] if t["lying"]]
    lying_cans = [c for c in result.cans if c.lying]
    assert len(lying_cans) == 1, (result.message, [r.reason for r in result.rejected])
    obj = Obj("lying_can", *transforms.apply(to_table, np.add(t["base_center"], 0.5 * t["height"] * np.asarray(
        t["axis"])))[:2], radius=t["radius"], height=t["height"], yaw=t["yaw"])
    errors = lying_pose_error(lying_cans[0], obj, to_table)
    assert errors[0] < 0.005 and abs(errors[3]) < 0.01, errors


@pytest.mark.parametrize("objects", [
    [Obj("box", 0.0, 0.0, size=(0.15, 0.07, 0.07), yaw=0.4), Obj("box", 0.0, 0.09, size=(0.12, 0.1, 0.14), yaw=0.4)],
    [Obj("box", 0.0, 0.0, size=(0.16, 0.06, 0.05), yaw=2.0), Obj("can", 0.0, 0.07, radius=0.035, height=0.12)],
    [Obj("lying_can", 0.0, 0.0, radius=0.1, height=0.07, yaw=0.5), Obj("box", 0.0, 0.17, size=(0.1, 0.1, 0.1))],
])
def test_lying_boxes_and_tins_touching_other_objects_are_no_lying_cans(objects):
    """A box lying flat beside a standing box or an upright can, and a tin on its side beside a box, are
    no lying cans (the upright can is still found)."""
    _, result, to_table = search(objects)
    assert not any(c.lying for c in result.cans), result.message
    assert_cans_at(result, to_table, objects)


@pytest.mark.parametrize("case", so.CASES)
def test_generated_cases_find_cans_near_the_truth_and_nothing_else(case):
    """On each case (development seed 3), no upright can is reported where there is none and at most one
    can is missed, a lying can is reported only where there is one (the middle of its axis within 5 mm);
    every result carries fit rms, arc, points, support and base_seen."""
    scene = sc.generate_scene(so.case_spec(case, 3))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    truth = [t for t in scene.truth["objects"] if t["is_can"]]
    lying = [t for t in scene.truth["objects"] if t["lying"]]
    result = af.find_cans(scene.xyz)
    matched = 0
    for can in result.cans:
        d = can.to_dict()
        assert {"rms_error", "arc_coverage", "n_points", "support", "base_seen"} <= set(d)
        if can.lying:
            p = transforms.apply(to_table, can.base_center + 0.5 * can.height * can.axis)
            middles = [transforms.apply(to_table, np.add(t["base_center"], 0.5 * t["height"] * np.asarray(t["axis"])))
                       for t in lying]
            assert middles and min(np.linalg.norm(p - m) for m in middles) < 0.005, (case, p)
            continue
        p = table_xy(to_table, can)
        errors = [np.hypot(*(p[:2] - transforms.apply(to_table, t["base_center"])[:2])) for t in truth]
        assert errors and min(errors) < 0.005, (case, p)
        matched += 1
    assert matched >= len(truth) - 1


def test_the_issue_5_finder_stays_selectable():
    """search='clusters' is the one-cluster-one-can finder: it misses the can on a tin."""
    objects = [Obj("tin", 0.0, 0.0, radius=0.1, height=0.07), Obj("can", 0.01, 0.0, 0.07, radius=0.035, height=0.11)]
    spec = sc.SceneSpec(cans=[], objects=objects, camera_distance=0.9, tilt=0.85, seed=7)
    scene = sc.generate_scene(spec)
    assert af.find_cans(scene.xyz, config=af.AutoConfig(search="clusters")).cans == []
    assert len(af.find_cans(scene.xyz).cans) == 1


# --- real scenes ----------------------------------------------------------------------------------

needs_osd = pytest.mark.skipif(not OSD.is_dir(), reason=f"the real mOSD scenes are absent ({OSD})")


@needs_osd
@pytest.mark.parametrize("name", ["learn31", "learn40", "learn42", "learn43", "learn44"])
def test_real_cans_are_found_on_their_labelled_points(name):
    """Every labelled can of the scene is found: its points are mostly that object's."""
    from example_pcl.pcd import read_pcd

    cloud = read_pcd(str(OSD / f"{name}.pcd"))
    objects = json.loads(OBJECTS.read_text())["scenes"][name]
    labels = cloud.points["label"].reshape(-1).astype(int) // 10
    result = af.find_cans(cloud.xyz, viewpoint=cloud.origin)
    for obj in (o for o in objects if o["kind"] == "can"):
        owners = [np.mean(labels[c.indices] == obj["label"]) for c in result.cans]
        assert owners and max(owners) > 0.9, (name, obj, result.message)


@needs_osd
@pytest.mark.parametrize("name", ["learn30", "learn32", "learn43"])
def test_real_lying_cans_are_reported_lying_along_their_labelled_points(name):
    """The lying Pringles of the scene (learn30, learn32: behind a box that splits it in two) is one
    lying can, most of its points that object's, its axis within 1 degree and the middle of its axis
    within 2.5 mm of the cylinder its labelled points lie on (bench_cans.lying_truth; the two parts
    of learn32 joined along the first part's axis were 3.2 degrees and 4.6 mm off)."""
    from example_pcl.pcd import read_pcd

    cloud = read_pcd(str(OSD / f"{name}.pcd"))
    obj = next(o for o in json.loads(OBJECTS.read_text())["scenes"][name] if o["kind"] == "lying_can")
    labels = cloud.points["label"].reshape(-1).astype(int) // 10
    result = af.find_cans(cloud.xyz, viewpoint=cloud.origin)
    lying_cans = [c for c in result.cans if c.lying]
    assert len(lying_cans) == 1, result.message
    can = lying_cans[0]
    assert np.mean(labels[can.indices] == obj["label"]) > 0.9
    # The plane frame of the labelled table, as the benchmark's.
    to_plane, _, (truth,) = bench_cans.real_truth(cloud, [obj])
    axis = transforms.apply(to_plane, can.base_center + can.axis) - transforms.apply(to_plane, can.base_center)
    middle = transforms.apply(to_plane, can.base_center + 0.5 * can.height * can.axis)
    assert abs(axis[:2] @ truth["axis"][:2]) > np.cos(np.radians(1)), (axis, truth)
    assert np.linalg.norm(middle - truth["center"]) < 0.0025, (middle, truth)


@needs_osd
@pytest.mark.parametrize("name", ["learn0", "learn33", "learn36", "learn39"])
def test_real_scenes_without_cans_have_none(name):
    """Boxes, tins, bowls, pots and open mugs on a real table: no can."""
    from example_pcl.pcd import read_pcd

    cloud = read_pcd(str(OSD / f"{name}.pcd"))
    result = af.find_cans(cloud.xyz, viewpoint=cloud.origin)
    assert result.cans == [], result.message


@needs_osd
def test_a_tins_rim_along_a_lying_fits_axis_is_no_lying_can():
    """learn43 with depth noise of one sigma added (bench_views' draw 2): a round tin's rim, 105 points
    left beside what the upright search took, with a few points at its ends fitted a horizontal
    cylinder of r 29.9 mm over 2.13 rad, whose 1 cm bands each spanned 0.23 rad at the median: no
    lying can. The Pringles lying beside it still is one."""
    from example_pcl.pcd import read_pcd

    cloud = read_pcd(str(OSD / "learn43.pcd"))
    xyz = dict(degraded(cloud, 3, af.AutoConfig().noise_coefficient))["noise +1 sigma, draw 2"]
    result = af.find_cans(xyz, viewpoint=cloud.origin)
    labels = cloud.points["label"].reshape(-1).astype(int) // 10
    lying_cans = [c for c in result.cans if c.lying]
    assert len(lying_cans) == 1, [(c.radius, c.height) for c in lying_cans]
    assert np.mean(labels[lying_cans[0].indices] == 2) > 0.9


def test_a_lying_sides_arc_is_seen_along_it_a_rims_is_not():
    """lying._band_arc: the points of a half cylinder's side (r 30 mm) span about its half circle in
    every 1 cm band along it; a rim along its top with a few points down its ends spans next to none
    in each band, though all of them together span 2 rad."""
    rng = np.random.default_rng(3)
    axial, angle = rng.uniform(0, 0.12, 400), rng.uniform(0, np.pi, 400)
    assert lying._band_arc(axial, angle, 0.01) > 0.8 * np.pi
    rim_axial = np.r_[rng.uniform(0, 0.12, 80), np.full(6, 0.0), np.full(6, 0.12)]
    rim_angle = np.r_[np.pi / 2 + rng.normal(0, 0.05, 80), np.linspace(-0.3, 1.5, 6), np.linspace(1.6, 1.7, 6)]
    assert lying._band_arc(rim_axial, rim_angle, 0.01) < 0.3
    assert lying._band_arc(np.array([0.0]), np.array([1.0]), 0.01) == 0.0


@needs_osd
def test_an_open_mug_whose_run_ends_under_its_rim_is_no_can():
    """learn33 with a fifth of its pixels dropped (bench_views' draw 1): an open mug's run of bands
    ended 20 mm under its rim, and the far rim above it, 8 mm of height, taken for an object standing
    on a lid, moved the lid 19 mm down, below the mug's inside: a can. What stands on a lid spans 2
    bands (can_search._lid)."""
    from example_pcl.pcd import read_pcd

    cloud = read_pcd(str(OSD / "learn33.pcd"))
    rng = np.random.default_rng(1)
    xyz = cloud.xyz.copy()
    rng.standard_normal(xyz.shape[:2])  # bench_views' draw adds its noise (none here) first
    xyz[rng.random(xyz.shape[:2]) < 0.2] = np.nan
    result = af.find_cans(xyz, viewpoint=cloud.origin)
    assert result.cans == [], [c.to_dict()["base_center"] for c in result.cans]


@needs_osd
def test_an_upside_down_bowls_foot_is_no_can_with_any_search_seed():
    """learn37 (a lying tin and an upside-down bowl) in all sixteen views with the search's seeds 0-7:
    with seed 3, mirrored at offset 1,0, the rounds claimed the bowl's tapered side and its foot, left
    above the claim, was a can seen by its lid alone (r 59 mm; _top_of_claimed). With seed 7 at offset
    1,0, the bowl's rim, a stripe 5 mm high on its circle, was a can's side under its foot 24 mm higher
    (r 69 mm; a side spans half what it must explain). No can in any."""
    from example_pcl.pcd import read_pcd

    cloud = read_pcd(str(OSD / "learn37.pcd"))
    for seed in range(8):
        config = af.AutoConfig(cylinders=cs.CylinderSearchConfig(seed=seed))
        for view, xyz, _ in views(cloud):
            result = af.find_cans(xyz, viewpoint=cloud.origin, config=config)
            assert result.cans == [], (view, seed, result.message)


def _false_cans(case, seed, search_seeds):
    """(search seed, how many) of the cans found in a generated scene that are none of its true cans
    (bench_cans.score, within 15 mm), for each of the search's seeds that finds any."""
    spec = so.case_spec(case, seed)
    scene = sc.generate_scene(spec)
    to_plane, cans, lying_cans = bench_cans.generated_truth(spec, scene)
    false = []
    for search_seed in search_seeds:
        config = af.AutoConfig(cylinders=cs.CylinderSearchConfig(seed=search_seed))
        result = af.find_cans(scene.xyz, config=config)
        tally = bench_cans.Tally()
        bench_cans.score(tally, result.cans, cans, lying_cans, to_plane, 0.015)
        if tally.false:
            false.append((search_seed, tally.false))
    return false


def test_a_box_tops_rim_pins_no_narrow_side_with_any_search_seed():
    """Fresh 6140 of "boxes and prisms", search seeds 0-11: a 4 x 4 cm box 1.26 m away, its front face
    seen over 0.74 rad of a circle of r 24 mm in its corner, its top's outline fitted that circle
    within the noise (rms 2.8 mm) and pinned it (seeds 8 and 10: a false can). A lid filling its
    rectangle is a box's top (0.93; _lid_at's rule), and pins no side."""
    assert _false_cans("boxes and prisms", 6140, range(12)) == []


def test_a_box_across_a_lying_cans_end_is_no_lying_can_with_any_search_seed():
    """Fresh 8146 of "lying can touching box", search seeds 0-3: a box 63 mm high across the end of a
    lying can 78 mm high, what the can left of it (its top and the strips of its faces under the top's
    edges) fitted a lying cylinder of r 31 mm along the top, shape error 0.76 mm, 3.7 times closer to
    the circle than to one line (each seed: a false can). Each half of that side lies closer to a line
    than to the circle (0.56): two flat faces, as the upright search's corner. The can is found."""
    assert _false_cans("lying can touching box", 8146, range(4)) == []
    spec = so.case_spec("lying can touching box", 8146)
    scene = sc.generate_scene(spec)
    to_plane, cans, lying_cans = bench_cans.generated_truth(spec, scene)
    tally = bench_cans.Tally()
    bench_cans.score(tally, af.find_cans(scene.xyz).cans, cans, lying_cans, to_plane, 0.015)
    assert (tally.lying, tally.lying_total) == (1, 1)


def test_a_tall_boxs_face_tangent_to_its_tops_rim_is_no_hidden_can_with_any_search_seed():
    """Fresh 7506 of "boxes and prisms", search seeds 0-5: a box 19 cm high, its top seen sparsely (a
    "lid" of r 20 mm passing the rim tests), its front face tangent to that circle: 262 points near the
    circle under the lid, none on the side verify judged (their bands off the circle), were too few to
    judge a side by, a hidden can's (seed 0: a false can). Too few to judge is hidden only when most
    of the points near the circle are on that side. Fresh 9705, search seeds 0-3: a 4 x 4 cm box's top
    seen whole, its circle r 21 mm, 103 points near it under the lid and none on its side, the circle
    refitted with them not round (each seed a false can): a refit that fails is hidden only when a
    stripe of the rim circle's own side is seen."""
    assert _false_cans("boxes and prisms", 7506, range(6)) == []
    assert _false_cans("boxes and prisms", 9705, range(4)) == []


def test_the_lower_part_of_a_claimed_mug_is_no_can_with_any_search_seed():
    """Fresh 6128 of "cluttered table", search seeds 0-11: a mug behind a cup, its inside seen above
    60 mm, claimed from there up as hollow; its side below, seen beside the cup over 0.69 rad on the
    same circle, was a can 60 mm high whose rest the cup hid (seeds 3 and 7). A wall on a claimed
    object's circle that ends at the claim's foot is that object's."""
    assert _false_cans("cluttered table", 6128, range(12)) == []


def test_a_mugs_handle_below_where_the_mug_is_seen_is_no_can_with_any_search_seed():
    """Fresh 7626 of "cluttered table", search seeds 0-5: a mug behind a box, claimed hollow from 60 mm
    up where its inside showed; its handle, seen beside the box from 20 mm up, and four points of its
    inner wall made a can of r 31.7 mm, 75 mm high, reaching 15 mm into the mug (every seed). A mug
    whose centre is off a circle stands on no can there: its wall goes on down below what is seen."""
    assert _false_cans("cluttered table", 7626, range(6)) == []


def test_a_can_beside_a_mug_seen_only_high_up_may_not_reach_into_it():
    """_inside_cup: a mug (r 33 mm) claimed hollow where it is seen, 60-100 mm up. A circle of r 32 mm
    50 mm off its centre (15 mm into it) from the table to 75 mm is no can: the mug's centre is off
    the circle, so it stands on no can there and its wall goes on down. The same circle 55 mm high
    (a band under the mug's lowest point seen) may be a can the mug overhangs; one under the mug,
    its centre within the circle, is judged on the heights seen (15 mm shared: may be its support).
    A mug whose far wall was not seen on its circle (only points inside it) keeps no space."""
    ctx = search_context(sensor=np.zeros(3), standing=np.empty((0, 3)), rng=np.random.default_rng(0),
                         claimed=[cs._Claim(0.0, 0.0, 0.033, 0.060, 0.100, True, True)])
    assert "into a cup or mug" in cs._inside_cup(0.05, 0.0, 0.032, 0.0, 0.075, 0.006, ctx)
    assert cs._inside_cup(0.05, 0.0, 0.032, 0.0, 0.055, 0.006, ctx) == ""
    assert cs._inside_cup(0.01, 0.0, 0.032, 0.0, 0.075, 0.006, ctx) == ""
    assert "into a cup or mug" in cs._inside_cup(0.01, 0.0, 0.032, 0.0, 0.095, 0.006, ctx)
    ctx.claimed[0] = ctx.claimed[0]._replace(keeps_space=False)
    assert cs._inside_cup(0.05, 0.0, 0.032, 0.0, 0.075, 0.006, ctx) == ""


def test_a_cup_stands_on_a_narrower_can_whose_near_side_lies_within_r_eps_inside_it():
    """Fresh 8712 of "cup on can": a cup (r 39.8 mm, its lowest side point 107 mm up) on a can 8 mm
    narrower set 4.3 mm toward the sensor, whose near side under it lies 34-37 mm from the cup's
    axis, within r_eps (6 mm) inside its circle: the cup stands on it and does not float. Its own side
    going on below, on its circle, is no support."""
    rng = np.random.default_rng(3)
    angle = rng.uniform(np.radians(-150), np.radians(-30), 120)
    z = rng.uniform(0.078, 0.102, 120)
    can = np.c_[0.0319 * np.cos(angle), 0.0319 * np.sin(angle) - 0.0043, z]
    own = np.c_[0.0398 * np.cos(angle), 0.0398 * np.sin(angle), z] + rng.normal(0, 0.001, (120, 3)) * (1, 1, 0)
    for points, stands in ((can, True), (own, False)):
        ctx = search_context(sensor=np.array([0.0, -0.8, 0.7]), standing=points, rng=rng)
        support = cs._support(points, 0.0, 0.0, 0.0398, 0.107, 0.006, 0.001, ctx)
        assert (support[0] is not None) == stands, support


def test_a_supports_top_is_its_top_layer_not_the_median_with_its_side():
    """"can on can" 6723: the points at the upper can's base level (111.6 mm) are the lower can's lid
    (104.5 mm) and, more of them, its side's below it (down to 85 mm): the support's top is the lid's
    height, not their median; a flat top alone gives its median; a top layer more than sigma above
    the base is no support's (fresh 6129 of "cluttered table"), one within sigma is (fresh 13909 of
    "can on can"); points spread evenly over the window (a neighbour's side: fresh 13906 and 13920 of
    "cluttered table") hold no support's top."""
    rng = np.random.default_rng(5)
    lid = 0.1045 + rng.normal(0, 0.0006, 6)
    side = rng.uniform(0.085, 0.100, 9)
    assert np.median(np.concatenate([lid, side])) < 0.101
    assert abs(cs._top_layer(np.concatenate([lid, side]), 0.1116, 0.0006) - 0.1045) < 0.0005
    assert cs._top_layer(lid, 0.1116, 0.0006) == pytest.approx(np.median(lid), abs=0.0003)
    assert cs._top_layer(np.concatenate([lid, side]), 0.103, 0.0006) is None
    assert abs(cs._top_layer(np.concatenate([lid, side]), 0.1043, 0.0006) - 0.1045) < 0.0005
    # A side 30 points over the window, 1 mm of noise; with a layer of 10 points on top it is a support.
    neighbour = np.linspace(0.0615 - 0.028, 0.0615 + 0.005, 30)
    assert cs._top_layer(neighbour, 0.0615, 0.001) is None
    top = np.concatenate([neighbour[neighbour < 0.061], 0.061 + rng.normal(0, 0.0005, 10)])
    assert abs(cs._top_layer(top, 0.0615, 0.001) - 0.061) < 0.0005


@pytest.mark.parametrize("case, seed, xy", [("can on can", 13909, (0.0306, 0.0211)),
                                            ("cluttered table", 6129, (-0.2484, -0.0423)),
                                            ("cluttered table", 13906, (-0.1178, -0.0464)),
                                            ("cluttered table", 13920, (0.0413, -0.0266)),
                                            ("cluttered table", 14438, (-0.1253, 0.0431)),
                                            ("cluttered table", 14657, (0.0001, 0.0204)),
                                            ("cluttered table", 14679, (0.2970, 0.0587))])
def test_a_cans_base_is_on_its_support(case, seed, xy):
    """The can at xy (m, table frame) is found within 2 mm of its axis, its base and height within 5
    mm: 13909, the upper of two stacked cans, on the lower one's lid 0.2 sigma above its lowest side
    point (put 12 mm low); 6129, 13906 and 13920, cans on the table whose bases are hidden, put on a
    prism's slanted face or a neighbour's side beside them (42, 47 and 37 mm up); 14438, one whose
    base a bowl hides, put on the bowl's rim in front of it (62 mm up: 35 mm high, missed); 14657,
    one behind a bowl claimed on a circle too wide, put on its rim (64 mm up); 14679, one behind a
    bowl, a tin's top touching it on one side, put on the tin (55 mm up)."""
    scene = sc.generate_scene(so.case_spec(case, seed))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    truth = next(t for t in scene.truth["objects"]
                 if t["is_can"] and np.hypot(*(transforms.apply(to_table, t["base_center"])[:2] - xy)) < 1e-3)
    base = transforms.apply(to_table, truth["base_center"])
    can = nearest_can([c for c in af.find_cans(scene.xyz).cans if not c.lying], to_table, base)
    assert np.hypot(*(table_xy(to_table, can)[:2] - base[:2])) < 0.002
    assert abs(table_xy(to_table, can)[2] - base[2]) < 0.005, (table_xy(to_table, can), base)
    assert abs(can.height - truth["height"]) < 0.005, (can.height, truth["height"])


def test_a_neighbours_top_beside_a_can_whose_side_goes_on_down_is_no_support():
    """A level surface beside a can's base (m, the lowest point of its run) is a neighbour's top, no
    support, when the can's side goes on down its circle to the table, curved, over a can's arc: then it
    stands on the table. Not when what lies on the circle below is a box's face crossing it straight, or
    nothing does, or a low support's top all round it."""
    rng = np.random.default_rng(11)
    angle = rng.uniform(np.radians(-160), np.radians(-20), 600)
    z = rng.uniform(0.0, 0.14, 600)
    side = np.c_[0.03 * np.cos(angle), 0.03 * np.sin(angle), z]
    # A tin's top 60 mm up, its rim 3 mm beside the can's left.
    top_angle = rng.uniform(np.radians(150), np.radians(210), 60)
    reach = rng.uniform(0.037, 0.055, 60)
    tin_top = np.c_[reach * np.cos(top_angle), reach * np.sin(top_angle), rng.normal(0.06, 0.0005, 60)]
    face = np.c_[rng.uniform(-0.012, 0.012, 300), np.full(300, -0.031), rng.uniform(0.0, 0.072, 300)]
    upper = side[z >= 0.072]
    # A low box's top 34 mm up, all round the can's base and on its circle too, is its support (its front
    # face, 30 mm from the axis, lies on the circle's near side below it: development 460 of "can on box").
    around = rng.uniform(0, 0.06, (2000, 2)) - 0.03
    box_top = np.c_[around, rng.normal(0.034, 0.0005, 2000)][np.hypot(*around.T) > 0.03 - 0.006]
    box_front = np.c_[rng.uniform(-0.03, 0.03, 300), np.full(300, -0.03), rng.uniform(0.0, 0.034, 300)]
    cases = ((np.vstack([side, tin_top]), 0.072, "table", 0.0),
             (np.vstack([upper, face, tin_top]), 0.072, "object", 0.06),
             (np.vstack([upper, tin_top]), 0.072, "object", 0.06),
             (np.vstack([side[z >= 0.04], box_top, box_front]), 0.04, "object", 0.034))
    for points, base, support, height in cases:
        ctx = search_context(sensor=np.array([0.0, -0.8, 0.7]), standing=points, rng=rng)
        answer = cs._support(points, 0.0, 0.0, 0.03, base, 0.006, 0.001, ctx)
        assert answer[0] == support and answer[2] == pytest.approx(height, abs=0.002), (support, answer)


def test_a_can_on_a_tin_claimed_before_it_stands_on_the_tins_lid():
    """Fresh 12448 of "can on tin": a can (r 39.5 mm) on a tin too wide for a can (r 92 mm, 69.5 mm
    high). The tin was judged first and claimed with its lid; the lid gone, nothing lay at the can's
    base, the tin's front stood as high as it, and the can was reported on the table, its base hidden
    behind the tin, 163 mm high. It stands on the tin's lid, seen."""
    truth, can, off = can_nearest_truth("can on tin", 12448, lambda t: t["is_can"])
    assert off < 0.002 and can.support == "object" and can.base_seen
    assert can.support_height == pytest.approx(0.0695, abs=0.004)
    assert can.height == pytest.approx(truth["height"], abs=0.004)


def test_a_can_beside_a_tins_rim_stands_on_the_table_not_the_tin():
    """Fresh 11848 of "cluttered table": a can (r 30 mm, 143 mm high) 3 mm from a tin 60 mm high, whose
    rim just outside its circle shifted the bands at its height off it: the side's run started above
    them, the can stood on the tin at 60 mm and the 73 points of its side below were a second can. It
    stands on the table, its full height, and no can is false."""
    truth, can, off = can_nearest_truth("cluttered table", 11848, lambda t: t["is_can"] and t["radius"] < 0.031)
    assert off < 0.002 and can.support == "table" and can.base_seen
    assert can.height == pytest.approx(truth["height"], abs=0.004)
    assert _false_cans("cluttered table", 11848, [0]) == []


def test_a_lids_side_is_seen_in_the_points_on_its_circles_near_half_under_it():
    """_side_seen: the points within r_eps of the circle on its near half (the sensor toward -y)
    under the lid, not the far half's, the lid's or those farther off the circle."""
    angle = np.radians(np.linspace(-160, -20, 29))
    near = np.c_[0.03 * np.cos(angle), 0.03 * np.sin(angle), np.full(29, 0.05)]
    points = np.vstack([near, near * (1, -1, 1), near * (0.5, 0.5, 2.0), near * (1.25, 1.25, 1.0)])
    ctx = search_context(sensor=np.array([0.0, -0.8, 0.7]), standing=points, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(cs._side_seen(points, 0.0, 0.0, 0.03, 0.006, 0.09, ctx), near[:, :2])
    assert len(cs._side_seen(points, 0.0, 0.0, 0.03, 0.006, 0.04, ctx)) == 0


def test_a_cups_inner_wall_seen_through_a_small_circle_makes_it_no_can():
    """Fresh 6735 of "cluttered table": a cup (r 35.9 mm) behind a lower tin, its near wall seen over
    0.95 rad and fitted 6 mm small (r 29.9 mm); its far inner wall lay just outside that circle, no
    "far inner wall" of it, but a solid can there would hide it (48 points seen through it). No false
    can, the scene's two cans found."""
    assert _false_cans("cluttered table", 6735, [0]) == []
    scene = sc.generate_scene(so.case_spec("cluttered table", 6735))
    assert len(af.find_cans(scene.xyz).cans) == 2


def test_points_beyond_the_circle_are_no_far_inner_wall():
    """_open_top: points on the circle's far half 30 mm under its top, 3 mm inside the circle (r 40
    mm), are a hollow cylinder's far inner wall; 4 mm outside it they are not (another object's side,
    beyond a circle a can touching it pulled wide: fresh held-out 3206 of "cluttered table"), seen
    from above (0.2 m off the axis, 0.8 m up). Seen from lower (0.8 m off, 0.6 m up), a solid can
    there would hide them: seen through it, they make it hollow too, but its far wall is not seen
    where its circle puts it (it keeps no space)."""
    r, top = 0.04, 0.10
    near_angle = np.radians(np.linspace(-150, -30, 8))
    z = np.linspace(0.055, 0.095, 5)
    near = np.array([[r * np.cos(a), r * np.sin(a), h] for a in near_angle for h in z])
    far_angle = np.radians(np.linspace(60, 120, 10))
    for dr, sensor, reason, wall in ((-0.003, (0.0, -0.2, 0.8), "points on the far inner wall", True),
                                     (0.004, (0.0, -0.2, 0.8), None, False),
                                     (0.004, (0.0, -0.8, 0.6), "points seen through", False)):
        far = np.array([[(r + dr) * np.cos(a), (r + dr) * np.sin(a), 0.07] for a in far_angle])
        points = np.vstack([near, far])
        ctx = search_context(sensor=np.array(sensor), standing=points, rng=np.random.default_rng(0))
        why, wall_seen = cs._open_top(points, 0.0, 0.0, r, 0.006, 0.0, top, ctx)
        assert (why.startswith("open top") and reason in why) if reason else why == "", (dr, sensor, why)
        assert wall_seen == wall


def test_a_can_whose_circle_a_touching_can_pulls_wide_is_no_cup():
    """Fresh held-out 3206 of "cluttered table": a can's circle pulled wide by the can touching it (40
    mm for 36) saw that can's side beyond it on its far half, and the can was claimed as a cup: every
    can is found, that one within 8 mm (its circle still pulled), no other upright can."""
    scene = sc.generate_scene(so.case_spec("cluttered table", 3206))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    upright = [c for c in af.find_cans(scene.xyz).cans if not c.lying]
    truth = [t for t in scene.truth["objects"] if t["is_can"]]
    assert len(upright) == len(truth) == 3
    for t in truth:
        base = transforms.apply(to_table, t["base_center"])
        assert min(np.hypot(*(table_xy(to_table, c)[:2] - base[:2])) for c in upright) < 0.008


def test_a_lid_over_a_round_object_claimed_below_it_is_its_top():
    """_top_of_claimed: a lid inside the disc of a round object claimed as no can (r 81 mm, up to 60 mm)
    and less than min_can_height above it is that object's top; beside it, or as high above it as a
    can standing on it would reach, it is not."""
    ctx = search_context(sensor=np.zeros(3), standing=np.empty((0, 3)), rng=np.random.default_rng(0),
                         claimed=[cs._Claim(0.07, 0.066, 0.081, 0.016, 0.060, False)])
    assert cs._top_of_claimed(0.074, 0.054, 0.059, 0.070, 0.006, ctx)
    assert not cs._top_of_claimed(0.074, 0.054, 0.059, 0.060 + ctx.config.min_can_height, 0.006, ctx)
    assert not cs._top_of_claimed(0.2, 0.054, 0.059, 0.070, 0.006, ctx)


@needs_osd
@pytest.mark.parametrize("name", sorted(json.loads(OBJECTS.read_text())["scenes"], key=lambda n: int(n[5:])))
def test_real_scenes_give_the_same_cans_in_every_view(name):
    """Every labelled can found upright and every lying one lying, each on that object's points, and
    nothing else, in all sixteen views of the scene (bench_views: grid offsets, mirrored, upside down,
    columns reversed; learn39's open mug was a can at one offset, learn43's coffee canister a mug at
    another, the front of learn21's lowest box a lying can with its columns reversed). learn38's
    upside-down mugs, handles hidden, are reported as cans (docs/can_search.md, Upside-down mugs):
    expected to fail there."""
    from example_pcl.pcd import read_pcd

    if name == "learn38":
        pytest.xfail("upside-down mugs with hidden handles are reported as cans (no depth feature separates them)")
    cloud = read_pcd(str(OSD / f"{name}.pcd"))
    objects = json.loads(OBJECTS.read_text())["scenes"][name]
    for view, xyz, labels in views(cloud):
        result = af.find_cans(xyz, viewpoint=cloud.origin)
        why = wrong(result, labels, objects)
        assert not why, (view, why, result.message)


def test_batched_algebraic_circles_match_the_one_at_a_time_fit():
    """fit_circles_algebraic on K masks gives fit_circle_algebraic of each subset; collinear -> NaN."""
    from example_pcl import geometry as g

    rng = np.random.default_rng(4)
    angle = rng.uniform(0.0, 2.5, 300)
    xy = np.c_[0.4 + 0.05 * np.cos(angle), -0.2 + 0.05 * np.sin(angle)] + rng.normal(0.0, 0.001, (300, 2))
    masks = rng.random((5, 300)) < 0.4
    batched = np.array(g.fit_circles_algebraic(xy, masks)).T
    np.testing.assert_allclose(batched, [g.fit_circle_algebraic(xy[m]) for m in masks], atol=1e-9)
    line = np.c_[np.arange(5.0), 2 * np.arange(5.0)]
    assert np.isnan(g.fit_circles_algebraic(line)[2][0])
    # One circle (no masks) is the same fit as one mask of every point.
    np.testing.assert_allclose(np.ravel(g.fit_circles_algebraic(xy)),
                               np.ravel(g.fit_circles_algebraic(xy, np.ones((1, 300), bool))), atol=1e-12)


def test_lying_circles_from_moments_match_each_direction_fitted_alone():
    """The lying search's Kasa circles of every direction and subset, from the subsets' moments
    (lying._kasa), are fit_circles_algebraic of the points projected across each direction."""
    from example_pcl import geometry as g

    rng = np.random.default_rng(7)
    along, angle = rng.uniform(0.0, 0.12, 250), rng.uniform(0.3, 2.8, 250)
    # A lying can of r 33 mm along 0.5 rad, far from the origin, seen with 1 mm noise.
    q = np.c_[along, 0.033 * np.cos(angle)] @ [[np.cos(0.5), np.sin(0.5)], [-np.sin(0.5), np.cos(0.5)]]
    q += np.array([0.8, -0.3]) + rng.normal(0.0, 0.001, (250, 2))
    z = 0.033 + 0.033 * np.sin(angle) + rng.normal(0.0, 0.001, 250)
    theta = np.arange(36) * np.pi / 36
    masks = np.vstack([np.ones(250, bool), rng.random((4, 250)) < 0.5])
    cl, cz, r = lying._kasa(q, z, theta, masks)
    for d, t in enumerate(theta):
        lateral = -q[:, 0] * np.sin(t) + q[:, 1] * np.cos(t)
        alone = np.array(g.fit_circles_algebraic(np.c_[lateral, z], masks))
        np.testing.assert_allclose(np.c_[cl[:, d], cz[:, d], r[:, d]], alone.T, atol=1e-9)


def test_lean_circle_fit_matches_fit_cylinder():
    """fit_circle_geometric converges to fit_cylinder's circle from the same start."""
    from example_pcl import geometry as g

    rng = np.random.default_rng(5)
    angle = rng.uniform(-1.5, 1.5, 200)
    xy = np.c_[0.1 + 0.035 * np.cos(angle), 0.3 + 0.035 * np.sin(angle)] + rng.normal(0.0, 0.001, (200, 2))
    fit = g.fit_cylinder(xy, (0.104, 0.297), 0.031, 0.006, max_iterations=20, tol=1e-5, min_inliers=30)
    lean = g.fit_circle_geometric(xy, (0.104, 0.297), 0.031, 0.006, max_iterations=20, tol=1e-5, min_inliers=30)
    np.testing.assert_allclose(lean, (fit.cx, fit.cy, fit.radius), atol=1e-9)


def test_robust_circle_fit_ignores_a_face_touching_the_circle():
    """A box face tangent to the circle near one end of the arc pulls the least-squares circle by
    millimetres; the biweight circle started there comes back to the can (within 0.5 mm) and its scale
    is the noise's."""
    from example_pcl import geometry as g

    rng = np.random.default_rng(6)
    r, noise = 0.045, 0.0004
    angle = rng.uniform(-2.6, 0.3, 300)
    arc = np.c_[r * np.cos(angle), r * np.sin(angle)]
    # The face x = r touches the circle at angle 0, seen from y = -0.02 to 0.03 (beyond the arc's end).
    face = np.c_[np.full(120, r), rng.uniform(-0.02, 0.03, 120)]
    xy = np.r_[arc, face] + rng.normal(0.0, noise, (420, 2))
    least = g.fit_circle_geometric(xy, (0.0, 0.0), r, 0.006, max_iterations=50, tol=1e-7, min_inliers=30)
    assert np.hypot(*least[:2]) > 0.002  # the drift the robust fit is for
    cx, cy, fitted, scale = g.fit_circle_robust(xy, least[:2], least[2], 0.006, max_iterations=50, tol=1e-7)
    assert np.hypot(cx, cy) < 0.0005 and abs(fitted - r) < 0.0005
    assert 0.5 * noise < scale < 3 * noise


def test_a_least_squares_circle_bent_through_a_neighbours_points_is_replaced():
    """A neighbour's wall curving away from a can's circle at one end of its arc, from 5.5 to 16 mm off
    it (fresh 7929 of "cluttered table": a cup's), pulls the least-squares circle 17 mm wide with no
    outliers left around it, and it is not round; the refit is the can's circle (within 0.5 mm), with a
    cut-off that leaves the neighbour's points out. A round least-squares circle with no outliers stands
    (cut-off inf), as before."""
    rng = np.random.default_rng(7)
    r, noise = 0.038, 0.0003
    angle = np.radians(rng.uniform(-155, -50, 200))
    arc = np.c_[r * np.cos(angle), r * np.sin(angle)]
    beside = rng.uniform(-40, -15, 45)
    off = 0.0055 + 0.00042 * (beside + 40)
    neighbour = np.c_[(r + off) * np.cos(np.radians(beside)), (r + off) * np.sin(np.radians(beside))]
    xy = np.r_[arc, neighbour] + rng.normal(0.0, noise, (245, 2))
    ctx = search_context(sensor=np.array([0.0, -0.8, 0.7]), standing=np.zeros((0, 3)), rng=rng)
    least = g.fit_circle_geometric(xy, (0.0, 0.0), r, 0.006, max_iterations=50, tol=1e-7, min_inliers=30)
    assert least[2] - r > 0.01 and g.shape_error(xy, *least, 8) > 0.001  # bent, not round
    cx, cy, fitted, cutoff = cs._robust_refit(xy, *least, 0.006, ctx)
    assert np.hypot(cx, cy) < 0.0005 and abs(fitted - r) < 0.0005
    assert cutoff < 0.005
    clean = g.fit_circle_geometric(xy[:200], (0.0, 0.0), r, 0.006, max_iterations=50, tol=1e-7, min_inliers=30)
    assert cs._robust_refit(xy[:200], *clean, 0.006, ctx) == (*clean, np.inf)


SENSOR = np.array([0.0, -0.8, 0.6])  # plane frame (m)


def _round_object(bottom_radius, top_radius, height, seed, noise=0.001, n_side=1500, n_lid=300):
    """Points (plane frame, m) that a sensor at SENSOR sees of a closed round object on the table
    at the origin: a can when both radii are equal, else a frustum (an upside-down bowl or pot when
    narrower at the top), with depth-like noise along the surface normal."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.0, height, n_side)
    angle = rng.uniform(-np.pi, np.pi, n_side)
    radius = bottom_radius + (top_radius - bottom_radius) * z / height
    normal = np.c_[np.cos(angle), np.sin(angle)]
    side = np.c_[radius[:, None] * normal, z]
    facing = normal @ SENSOR[:2] > 0  # the half facing the sensor
    side = side[facing] + np.c_[rng.normal(0.0, noise, (int(facing.sum()), 1)) * normal[facing], np.zeros(facing.sum())]
    lid_r, lid_a = top_radius * np.sqrt(rng.uniform(0, 1, n_lid)), rng.uniform(-np.pi, np.pi, n_lid)
    lid = np.c_[lid_r * np.cos(lid_a), lid_r * np.sin(lid_a), height + rng.normal(0.0, noise, n_lid)]
    return np.r_[side, lid]


def _search_one(points):
    """can_search.search on one cluster of plane-frame points, the plane frame as the sensor frame."""
    return cs.search([points], points, np.eye(4), SENSOR, af.AutoConfig())


def test_radius_taper_measures_a_cone_and_not_a_cylinder():
    """radius_taper: a side 10 mm narrower over 100 mm gives -5 mm between halves 50 mm apart; a
    cylinder's change is ~0."""
    rng = np.random.default_rng(8)
    z = rng.uniform(0.0, 0.1, 2000)
    change, apart, n_low, n_up = cs.radius_taper(0.045 - 0.1 * z, z)
    assert change == pytest.approx(-0.005, abs=5e-4) and apart == pytest.approx(0.05, abs=5e-3)
    assert n_low + n_up == 2000
    flat = cs.radius_taper(0.04 + rng.normal(0.0, 0.001, 2000), z)[0]
    assert abs(flat) < 3e-4
    assert cs.radius_taper(np.full(4, 0.04), z[:4]) is None


def test_a_tapered_round_object_is_rejected_as_tapered_and_a_can_is_not():
    """An upside-down pot (radius 45 -> 36 mm over 10 cm, 5 degrees) is rejected as tapered; a can of
    the same size seen the same way is found; with the rule off (max_taper huge), the pot is reported
    as a can (or as two, each over a part of its height)."""
    pot = _round_object(0.045, 0.036, 0.1, seed=1)
    cans, rejected = _search_one(pot)
    assert cans == [], [c.radius for _, c in cans]
    assert any(r.reason.startswith("tapered") for _, r in rejected), [r.reason for _, r in rejected]
    cans, _ = _search_one(_round_object(0.04, 0.04, 0.1, seed=1))
    assert len(cans) == 1 and cans[0][1].radius == pytest.approx(0.04, abs=0.002)
    off = af.AutoConfig(cylinders=cs.CylinderSearchConfig(max_taper=10.0, taper_sigmas=1e3))
    assert len(cs.search([pot], pot, np.eye(4), SENSOR, off)[0]) >= 1


# Development seeds (0-49) of issue 13's cases where a can was missed before, one per cause: a wide
# circle tangent to the can outranked its own circle (touching box 2), a circle through a box's corner
# took the can with its disc (12), a box's face nearly tangent to the can was a "handle" (28), a big
# box's faces crowded the can's triplets out (1, 47), a narrower can on a can made the lower one's
# lid too high and "open" (can on can 34), triplets with a point on the can and one on the cup on it
# gave circles between the two, the cup's circle was rejected for its inside without claiming it
# (cup on can 22, 27, 30, 32, 34); a can's own side below its run (its lower part partly hidden by
# a box or a lying can in front) was taken for a narrower object it stands on (box hides base 1,
# lying can touching can 1); a cup on a can seen from low showed 12 % of its inside, under the open-top
# rule's 15 % then, and was a can on the can (cup on can 418). Seeds 40-99: circles through a big box's
# corners took both verifications (can touching box 45, 47); a taller box touching the can raised its
# lid, and the lid was then the inside of a cup (57); wide circles tangent to the can outranked its own
# (97) or were verified instead of it (79); the rim of a lying can's end touching the upright can was a
# mug's handle (lying can touching can 40).
# Heights: a wider cup's overhang hid the
# top 17-23 mm of the can's side (cup on can 10, 15); the cup's base taken for the top only where it is
# seen around the axis, not a taller neighbour's side (cans touching 2, 29; can touching box 31). A can
# behind another, touching it, seen beside the front one's silhouette over 0.86-0.93 rad only, less than
# min_hidden_arc (cans touching 15, 23; 0 and 5 in test_can_behind_a_can_is_found). A taller can behind
# another, its side seen only 3.0-3.9 cm above the front one's lid, was a bowl (one circle over less than
# min_can_height) though the rest of its side is hidden (cans touching 426, 443). Held out, looked at
# since: a can seen steeply from above behind a lower object, 18 side points on the search's grid, 4 of
# them more than min_can_height under its lid, was not hidden below by the lid rule's 20 % (now half;
# cluttered table 1002); so was a can behind another, 12 of 33 lower (cans touching 605). A can between a
# taller can and a box showing a stripe of its side down to the table, 0.49 rad wide: fitted to the
# stripe, its circle came out 47 mm for 31; judged on its lid's rim, 0.77 rad (cluttered table 1400). A
# wide can behind a narrower, taller one, its lid cut short by it and its side seen at one limb only
# (0.6 rad): the lid's circle 4 mm off put that stripe 5 mm outside it (cluttered table 1507). A can
# behind a taller one showing a stripe of its side over 0.57 rad, fitted to it r 36 mm for 30, so the rest
# of its near half did not lie behind the front can; pinned by its lid's rim first (cluttered table 2605).
# A can behind another, touching it, its lid's rim seen whole, its side hidden but for 21-28 points near the
# circle, most of them low: too few to judge as a side, judged hidden (cans touching 3202, 3208). A lid the
# can in front cuts short, its rim over 2.2-2.3 rad, pinned by the stripe of side under it (cans touching
# 2408, cluttered table 73); not a low box's top, its faces seen over 2.5 rad (cluttered table 83). A can
# under a cup 8 mm wider seen steeply from above: the cup's rim put more points in its band than any band of
# the can's side held, and the run of bands was the rim's alone (cup on can 3824; geometry.band_run). A can
# whose front is in line with the face of a box it touches: the face's run took 32 mm of the can's front past
# a gap of 16 mm, and no triplet was drawn on the can (can touching box 4134; flat_faces). A can under a cup
# 8 mm wider: the cup's own front, its noise a millimetre beyond its circle, was taken for an object in front
# hiding its base, and its claim as an open cup went down to the table, taking the can (cup on can 4630; an
# occluder lies beyond r_eps). A can behind a prism whose edge shows beside it, 17-22 mm out, its top and
# bottom hidden: a "handle" (cluttered table 4605; the prism's top runs on from it beyond handle_reach). A can
# of r 29 mm 4 mm off the axis of one of 44 mm it stands on: its side rose through the lower lid's ring, the
# lid came out 18 mm high and its points under it an open top's inside (can on can 4825; _lid). A 46 x 42 mm
# box's top behind a taller mug, seen at 1.2 m, taken for a can's lid alone (cluttered table 5048; its
# rectangularity). A can under a cup 8 mm wider seen at 1.2 m (noise 2 mm): the rounds' circles took both,
# "not round", and the cup's rim told it only after them (cup on can 5047; the lid's cup claimed, the rounds
# search again). A can behind a cup touching it, seen steeply at 1.2 m: the circle fitted to its side took
# the cup's too (r 50 mm), "not round" (cluttered table 5113; the half of that side on the can verified on
# its own circle, inner_split); a can above a bowl, 9 mm from another, reported 11 mm off on a circle
# tangent to both, and a can behind a taller box seen by a sparse lid, missed (cluttered table 5134; the
# same, and the lid's outline on the hull of its points). A can touching a box at 1.2 m: a circle of r 95 mm
# over both at their base, no can's radius, claimed the can as a round object (can touching box 5342; the
# can's own circle verified first). A can's lid at 93 mm beside a box's top at 100 (fuller) and another's at
# 197: the two box tops took both lid levels, the lid's band was next to one tried (cluttered table 5329; a
# box's top is no lid tried, its points and the faces under its edge leave the lids looked for next). A mug
# behind a taller box, its rim and 10 mm of inner wall seen over it: a false can of its "lid" (cluttered table
# 5119; a lid is flat, _not_flat). A can behind a wider one 8 mm lower, touching it, its lid whole: 25 of its
# points on the circle refitted to its rim and side, too few to judge a side by, and dropped (cans touching
# 5731; too few is hidden, verify's _TooFew). A can's lid at 128 mm touching a box's top at 132, its side hidden
# by the box: the lid went with the top, within a lid's 5 mm of it (can touching box 5035; a box's top is its
# own height within 3 sigma). A box's front seen over 0.4 rad and two stray points of its side 0.5 rad beyond:
# a side over 2.06 rad, a false can (cluttered table 5004; a side's arc is over its points with neighbours). A
# can of r 32 mm seen over 0.64 rad at 1.15 m, no lid to pin it: fitted r 53 mm, 21 mm off (cluttered table
# 5028; a side no lid pins fixes its radius to max_radius_error). A prism's top between two cans, its rim
# seen over 1.8 rad in 11 noisy samples, r 25.5 mm +- 6.4: a false can of its "lid" alone (cluttered table
# 6203; a lid alone no side pins fixes its radius to max_radius_error too). A can 4 mm from a cup whose front
# wall, seen between the can and a taller one in front hiding the rest of the cup, stuck out of its side:
# a mug's "handle" (cluttered table 5445; its lower end lies behind what stands in front). A can touching a
# box's end, its front tangent to the face's line: the face took the front, nearly straight within eps of the
# line (can touching box 7330; and 6922, its front with a gap; flat_faces judges the points near the piece).
@pytest.mark.parametrize("case, seed", [("can touching box", 2), ("can touching box", 12), ("can touching box", 28),
                                        ("can touching box", 1), ("can touching box", 47),
                                        ("can touching box", 45), ("can touching box", 57), ("can touching box", 97),
                                        ("can touching box", 79),
                                        ("lying can touching can", 40),
                                        ("can on can", 34),
                                        ("cup on can", 22), ("cup on can", 27), ("cup on can", 30),
                                        ("cup on can", 32), ("cup on can", 34), ("box hides base", 1),
                                        ("lying can touching can", 1), ("cup on can", 418),
                                        ("cup on can", 10), ("cup on can", 15), ("cans touching", 2),
                                        ("cans touching", 29), ("can touching box", 31),
                                        ("cans touching", 15), ("cans touching", 23), ("cans touching", 426),
                                        ("cans touching", 443), ("cluttered table", 406),
                                        ("cluttered table", 82), ("cans touching", 452),
                                        # held out before, looked at since
                                        ("box hides base", 909), ("can touching box", 606),
                                        ("cluttered table", 1002), ("cans touching", 605), ("cluttered table", 1301),
                                        ("cans touching", 1309), ("cluttered table", 1400),
                                        ("cluttered table", 1507), ("cluttered table", 1207),
                                        ("can touching box", 1708), ("cluttered table", 1800),
                                        ("can touching box", 1909), ("cluttered table", 2605),
                                        ("cans touching", 3202), ("cans touching", 3208), ("cans touching", 2408),
                                        ("cluttered table", 73), ("cluttered table", 83), ("cup on can", 3824),
                                        ("can touching box", 4134), ("cup on can", 4630), ("cluttered table", 4605),
                                        ("can on can", 4825), ("cluttered table", 5048), ("cup on can", 5047),
                                        ("cluttered table", 5113), ("cluttered table", 5134),
                                        ("can touching box", 5342), ("cluttered table", 5329),
                                        ("cluttered table", 5119), ("cans touching", 5731),
                                        ("can touching box", 5035), ("cluttered table", 5004),
                                        ("cluttered table", 5028), ("cluttered table", 6203),
                                        ("cluttered table", 5445), ("can touching box", 6019),
                                        ("cans touching", 6713), ("cluttered table", 7201),
                                        ("can touching box", 7330), ("can touching box", 6922),
                                        ("cluttered table", 7549), ("cluttered table", 7929),
                                        ("cluttered table", 8019), ("cluttered table", 8136),
                                        ("cup on can", 8641), ("cup on can", 8712), ("cluttered table", 8749),
                                        ("cluttered table", 9109), ("cluttered table", 9210),
                                        ("cluttered table", 6013), ("cluttered table", 9402),
                                        ("cluttered table", 11019)])
def test_development_misses_are_found_where_they_stand(case, seed):
    """Every can of these generated scenes is found within 3 mm of its axis, on its support (base
    within 1 cm, height within 1.5 cm of the truth), and no other upright can is reported."""
    scene = sc.generate_scene(so.case_spec(case, seed))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    truth = [t for t in scene.truth["objects"] if t["is_can"]]
    result = af.find_cans(scene.xyz)
    upright = [c for c in result.cans if not c.lying]
    assert len(upright) == len(truth), [r.reason for r in result.rejected]
    for t in truth:
        base = transforms.apply(to_table, t["base_center"])
        errors = [np.hypot(*(table_xy(to_table, c)[:2] - base[:2])) for c in upright]
        can = upright[int(np.argmin(errors))]
        assert min(errors) < 0.003, (t, errors)
        assert abs(can.support_height - t["support_height"]) < 0.01, (can.support, can.support_height, t)
        assert abs(can.height - t["height"]) < 0.015, (can.height, t["height"])
        assert can.support == t["support"]


@pytest.mark.parametrize("seed", [0, 75, 5])
def test_a_can_seen_over_a_narrow_arc_is_pinned_by_its_lid(seed):
    """A can behind another whose side shows over less than min_hidden_arc ("cans touching",
    development seeds 0, 75 and 5) has its circle refitted to that side and its lid's rim: within
    1.5 mm of its axis (3.1, 5.4 and 4.9 mm fitted to the side alone). Seed 5's lid is cut short by
    the taller front can's shadow: its rim shows over 1.2 rad, 2.25 with the side."""
    scene = sc.generate_scene(so.case_spec("cans touching", seed))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    upright = [c for c in af.find_cans(scene.xyz).cans if not c.lying]
    for t in (t for t in scene.truth["objects"] if t["is_can"]):
        base = transforms.apply(to_table, t["base_center"])
        assert min(np.hypot(*(table_xy(to_table, c)[:2] - base[:2])) for c in upright) < 0.0015


@pytest.mark.parametrize("case, seed", [("cans touching", 4536), ("cluttered table", 4006)])
def test_a_can_seen_by_its_lid_alone_behind_a_taller_one_touches_it(case, seed):
    """A can behind a taller one, touching it, seen by its lid alone, whose rim the front can's shadow
    cuts short: the rim's circle came out 3 mm too wide (fresh 4536 of "cans touching": r 35.3 mm for
    32.3) and overlapping the front can, and the can was dropped as the front can's. Its outline lies
    clear of the front can (the rim less half the sample spacing), and its circle touches it
    (geometry.RimCircle.touching): each can found within 2.5 mm of its axis (4.7 and 6.8 mm without)."""
    assert_upright_cans_found(case, seed, 0.0025)


def test_a_can_the_image_edge_cuts_seen_steeply_is_found_by_its_lid_and_side():
    """Fresh 6845 of "cluttered table": a can (r 32.6 mm) the image's bottom edge cuts, seen by its lid
    and 0.51 rad of side; its lid pins its circle, and the rest of its near half lies beyond the
    image or in the IR projector's shadow (that side has no depth), not behind an object. Found,
    within 1 mm of its axis, with every other can."""
    assert_upright_cans_found("cluttered table", 6845, 0.001)


def test_the_side_in_the_projectors_shadow_is_hidden():
    """_rest_hidden: a can's near half (r 40 mm, the sensor 1 m off at -y, 0.5 m up) seen but near
    its -x limb is hidden there when it faces away from the projector (0.5 m to the sensor's +x side:
    it does not light it); not with no projector, nor with one to the -x side, which lights it."""
    r = 0.04
    seen = np.radians(np.linspace(-150, -20, 40))  # -90 degrees faces the sensor; the limbs at -164.5, -15.5
    side = np.column_stack([r * np.cos(seen), r * np.sin(seen)])
    for projector, hidden in ((None, False), ((0.5, -1.0, 0.5), True), ((-0.5, -1.0, 0.5), False)):
        ctx = search_context(sensor=np.array([0.0, -1.0, 0.5]), standing=np.zeros((0, 3)),
                             rng=np.random.default_rng(0), projector=None if projector is None else np.array(projector))
        assert cs._rest_hidden(side, 0.0, 0.0, r, 0.006, 0.02, 0.1, ctx) == hidden, projector


def test_the_rounds_search_again_after_a_can_found_by_its_lid():
    """Fresh 6723 of "can on can": cans of r 40 and 33 mm, stacked, seen with 6 mm of noise band
    (r_eps): one circle grew over both sides (r 37 mm, "not round"); the upper can was found by its
    lid's rim, and the lower one, its side now alone, was never looked for again. Both found, each
    within 1 mm of its axis and 5 mm of its height."""
    assert_upright_cans_found("can on can", 6723, 0.001, max_height_error=0.005)


@pytest.mark.parametrize("seed", [0, 5, 4048, 4121, 4306])
def test_can_behind_a_can_is_found(seed):
    """A can behind another, touching it, seen only beside the front one's silhouette (0.55-0.86 rad of
    its side; development seeds 0, 5 of "cans touching") is found: every part of its near half not seen
    lies behind the front can. Over so short an arc the circle is less sure: within 6 mm of the axis.
    Fresh 4048: its lid whole, 31 points near its circle under it, 22 of them low: too few to judge as a
    side or to refit the rim with, and it was dropped; hidden now (can_search._lid_judged). Fresh 4121:
    no side seen at all, its lid's rim over 2.43 rad (the front can's shadow cuts it), less than
    lid_arc; over min_arc will do with something higher in front (can_search._lid_rim). Fresh 4306: its
    lid's rim cut short at both ends by the front can's shadow, the two ends 11 and 17 mm inside the
    circle: they made the rim look like a box's corner (facet ratio 0.87; 1.44 without them, as its rms
    is taken: geometry.RimCircle.kept)."""
    assert_upright_cans_found("cans touching", seed, 0.006, max_height_error=0.015)


def test_a_sparse_lid_is_judged_on_its_outline_on_the_hull():
    """A can (r 35.5 mm) behind a taller box at 1.1 m shows its lid alone, 82 points every 2nd pixel,
    its near part in the box's shadow (fresh 5134 of "cluttered table"). Sectors of its outline hold
    points up to 19 mm inside the rim, whose circle came out 7 mm small and 7 mm off, and the can was
    missed. Judged on the samples on the hull of its points (can_search._hull_rim): found within 3 mm
    of its axis, its radius within 1.5 mm, its base not seen."""
    truth, can, off = can_nearest_truth("cluttered table", 5134,
                                        lambda t: t["is_can"] and t["visible_points"] < 400)
    assert off < 0.003
    assert can.radius == pytest.approx(truth["radius"], abs=0.0015) and not can.base_seen and not can.lying


def test_a_box_tops_corner_is_not_refitted_on_its_hull():
    """Fresh 10039 of "cluttered table", search seeds 0-3: a 68 x 53 mm box's top 1 m below the sensor,
    the rest of the box hidden behind a taller can and box. Its outline's far corner fits no circle (rms
    4.4 mm, both halves over twice as near lines: facet ratio 0.42), but the 10 samples on the hull of its
    points fit one (r 37 mm, facet ratio 1.22): a can seen by its lid alone on every seed. A corner is
    refitted on no subset of its outline."""
    assert _false_cans("cluttered table", 10039, range(4)) == []


def test_a_box_tops_edge_is_not_refitted_on_its_hull():
    """Fresh 10849 of "cluttered table", search seeds 0-3: a 100 x 46 x 49 mm box behind a can, its top
    seen past it, one half of its outline along the edge over its side face (three times as near a
    line as its circle: 0.30), the other round enough (1.19): refitted on the 8 samples on the hull
    of its points, a can of r 27 mm seen by its lid. An edge is refitted on no subset of the outline."""
    assert _false_cans("cluttered table", 10849, range(4)) == []


@pytest.mark.parametrize("case, seed", [("cluttered table", 10528), ("cluttered table", 312)])
def test_a_box_face_under_its_top_pins_no_lid(case, seed):
    """Fresh 10528 of "cluttered table" (a 69 x 44 mm box's top cut short by a taller can's shadow) and
    development 312 (a prism's top behind a taller can), search seeds 0-3: the stripe under the top's
    edge is the box's face, in line with it, twice as near a line as the circle refitted to both (0.42,
    0.38): a can of r 23 mm seen by its lid, pinned by its side. A flat face pins no lid, nor lets a
    shorter rim pass."""
    assert _false_cans(case, seed, range(4)) == []


@pytest.mark.parametrize("seed", [9530, 9640])
def test_a_round_lids_sparse_outline_is_no_corner(seed):
    """Fresh 9530 and 9640 of "cans touching": a can behind a wider one 1.1-1.3 m away, seen by its lid
    alone, its outline's halves as near lines as its circle (facet ratio 0.97: noise and sparse
    samples), is refitted on the samples on the hull of its points as a corner is not: found within 4
    mm of its axis, its base not seen."""
    truth, can, off = can_nearest_truth("cans touching", seed, lambda t: t["is_can"] and t["visible_points"] < 400)
    assert off < 0.004 and not can.base_seen and not can.lying


@pytest.mark.parametrize("sigma", [0.0006, 0.0013, 0.0025])
def test_a_lid_is_flat_a_rim_over_an_inner_wall_is_not(sigma):
    """A lid's heights spread as the noise does (even with the noise 1.4 times what the sensor model
    says, as in bench_views' degraded scenes); a mug's rim with 10 mm of its inner wall under it (or
    8 sigma where the noise would hide 10 mm), 40 % of its points, spreads further (fresh 5119 of
    "cluttered table": 8.5 mm, sigma 1.3 mm)."""
    rng = np.random.default_rng(1)
    lid = 0.090 + 1.4 * sigma * rng.standard_normal(200)
    assert not cs._not_flat(lid, sigma)
    wall = max(0.010, 8 * sigma)
    rim_and_wall = np.r_[0.088 + sigma * rng.standard_normal(120), rng.uniform(0.088 - wall, 0.088, 80)]
    assert cs._not_flat(rim_and_wall, sigma)


def test_a_lid_holds_its_points_but_not_anothers_top_seen_apart_from_it():
    """A lid (r 30 mm, samples 3.6 mm apart) holds its points; a ring of points up to 12 mm beyond its
    rim, joined to it, is a wider top (no can's lid); a row of points 10 mm clear of the lid's circle
    and r_eps, apart from it, is another object's top (a cup's rim in front): it does not count."""
    spacing = 0.0036
    grid = np.mgrid[-0.05:0.05:spacing, -0.05:0.05:spacing].reshape(2, -1).T
    reach = np.hypot(grid[:, 0], grid[:, 1])
    lid = np.c_[grid[reach <= 0.030], np.full(np.count_nonzero(reach <= 0.030), 0.1)]
    assert cs._holds_lid(lid, 0.0, 0.0, 0.030, 0.006, spacing, RADII)
    beyond = (reach > 0.030) & (reach <= 0.042)
    ring = np.c_[grid[beyond], np.full(np.count_nonzero(beyond), 0.1)]
    wider = np.r_[lid, ring]
    assert not cs._holds_lid(wider, 0.0, 0.0, 0.030, 0.006, spacing, RADII)
    # A row of 16 points 16 mm beyond the rim, 5 mm lower: more than 5 % of them all.
    apart = np.c_[np.linspace(-0.027, 0.027, 16), np.full(16, -0.046), np.full(16, 0.095)]
    assert len(apart) > 0.05 * (len(lid) + len(apart))
    assert cs._holds_lid(np.r_[lid, apart], 0.0, 0.0, 0.030, 0.006, spacing, RADII)


def test_a_lid_holds_its_points_but_not_a_round_neighbours_rim_joined_to_it():
    """A lid (r 30 mm, r_eps 5 mm, samples 3.6 mm apart, its points out to its circle and r_eps, as
    noise spreads them) and, one spacing beyond those, the near part of a cup's rim (r 38 mm, 7 mm of
    its top seen) as high: joined to the lid, but another round object's rim beside it (fresh 9109
    of "cluttered table"), so the lid holds. A straight strip there (a box's edge) or a cup's rim
    around the lid (a can in a cup) is no rim beside it: the lid does not hold."""
    spacing, r, r_eps = 0.0036, 0.030, 0.005
    grid = np.mgrid[-0.09:0.09:spacing, -0.09:0.09:spacing].reshape(2, -1).T
    reach = np.hypot(grid[:, 0], grid[:, 1])
    lid = np.c_[grid[reach <= r + r_eps], np.full(np.count_nonzero(reach <= r + r_eps), 0.1)]

    def holds(beyond):  # beyond: which grid points out to 7.5 cm are the other object's
        band = beyond & (reach > r + r_eps) & (reach <= 0.075)
        other = np.c_[grid[band], np.full(np.count_nonzero(band), 0.1)]
        assert len(other) > 0.05 * (len(lid) + len(other))
        return cs._holds_lid(np.r_[lid, other], 0.0, 0.0, r, r_eps, spacing, RADII)

    to_cup = np.hypot(grid[:, 0], grid[:, 1] - 0.074)  # the cup's near edge at 36 mm
    assert holds((to_cup >= 0.031) & (to_cup <= 0.0385))
    assert not holds(np.abs(grid[:, 1] - 0.038) <= 0.0025)
    assert not holds((reach >= 0.037) & (reach <= 0.040))


def test_a_lid_beside_a_top_as_high_apart_from_it_is_a_piece_of_its_own():
    """A lid (r 33 mm, samples 3.6 mm apart) and a prism's triangular top as high, 1 cm clear of it:
    two pieces, the larger first, each whole; a lid alone is one piece (none to judge apart), and so
    is a lid with a piece smaller than min_points beside it (the same lid less a few points)."""
    spacing = 0.0036
    grid = np.mgrid[-0.1:0.1:spacing, -0.1:0.1:spacing].reshape(2, -1).T
    disc = np.hypot(grid[:, 0], grid[:, 1]) <= 0.033
    # The triangle's near edge 1 cm beyond the lid's far rim, its apex 4.5 cm farther.
    u = grid[:, 1] - 0.043
    triangle = (u >= 0) & (u <= 0.045) & (np.abs(grid[:, 0] + 0.02) <= 0.025 * (1 - u / 0.045))
    lid = np.c_[grid[disc | triangle], np.full(np.count_nonzero(disc | triangle), 0.126)]
    pieces = cs._lid_pieces(lid, 10)
    assert [len(p) for p in pieces] == [np.count_nonzero(disc), np.count_nonzero(triangle)]
    assert np.all(np.hypot(pieces[0][:, 0], pieces[0][:, 1]) <= 0.033)
    assert cs._lid_pieces(lid, np.count_nonzero(triangle) + 1) == []
    assert cs._lid_pieces(lid[np.hypot(lid[:, 0], lid[:, 1]) <= 0.033], 10) == []


def _not_stray(points, r_eps):
    """can_search._not_stray of points (float (N, 3), plane frame, m) seen from 0.8 m toward -y, 0.6 m up."""
    ctx = search_context(sensor=np.array([0.0, -0.8, 0.6]), standing=points, rng=np.random.default_rng(0))
    return cs._not_stray(points, r_eps, ctx)


def test_stray_points_do_not_stretch_a_sides_arc():
    """_not_stray: a side seen over 0.4 rad (columns and rows 4 mm apart, r 39 mm) and two points 21 mm
    apart 0.5 rad beyond it (the edge of a box's side face, fresh 5004 of "cluttered table", where they
    made the arc 2.06 rad and a box a can): the side's points stay, the two go, the arc is the side's."""
    r = 0.039
    angles = np.linspace(-1.77, -1.37, 5)
    side = np.array([[r * np.cos(a), r * np.sin(a), z] for a in angles for z in np.arange(0.02, 0.09, 0.004)])
    stray = np.array([[r * np.cos(a), r * np.sin(a), z] for a, z in ((-0.87, 0.05), (-0.33, 0.07))])
    points = np.vstack([side, stray])
    kept = _not_stray(points, 0.003)
    assert kept[:len(side)].all() and not kept[len(side):].any()
    assert g.arc_coverage(points[:, :2], 0.0, 0.0) > 1.4
    assert g.arc_coverage(points[kept, :2], 0.0, 0.0) == pytest.approx(0.4)


def test_a_pair_of_points_apart_from_a_side_does_not_stretch_its_arc():
    """_not_stray: a side seen over 0.35 rad (r 24 mm) and a pair of points 5 mm apart 1.2 rad round it,
    each the other's neighbour (fresh 12545 of "cluttered table": a mug's wall at its foot beyond a
    circle through the face of its handle, which made that face a can seen over 1.79 rad): the pair
    goes, the arc is the side's, and the scene has no false can."""
    r = 0.024
    angles = np.linspace(-1.16, -0.81, 8)
    side = np.array([[r * np.cos(a), r * np.sin(a), z] for a in angles for z in np.arange(0.02, 0.06, 0.004)])
    pair = np.array([[r * np.cos(a), r * np.sin(a), 0.015] for a in (-2.59, -2.40)])
    points = np.vstack([side, pair])
    kept = _not_stray(points, 0.006)
    assert kept[:len(side)].all() and not kept[len(side):].any()
    assert g.arc_coverage(points[kept, :2], 0.0, 0.0) == pytest.approx(0.35)
    assert _false_cans("cluttered table", 12545, [0]) == []


def assert_upright_cans_found(case, seed, max_off, max_height_error=np.inf):
    """As many upright cans found in the generated scene as it holds, each within max_off (m) of its
    axis and max_height_error (m) of its height."""
    scene = sc.generate_scene(so.case_spec(case, seed))
    to_table = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    truth = [t for t in scene.truth["objects"] if t["is_can"]]
    upright = [c for c in af.find_cans(scene.xyz).cans if not c.lying]
    assert len(upright) == len(truth)
    for t in truth:
        base = transforms.apply(to_table, t["base_center"])
        can = nearest_can(upright, to_table, base)
        assert np.hypot(*(table_xy(to_table, can)[:2] - base[:2])) < max_off
        assert abs(can.height - t["height"]) < max_height_error, (can.height, t["height"])
