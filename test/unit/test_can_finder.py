"""Tests of example_pcl.can_finder: the find_can pipeline on generated scenes, without ROS."""
import functools

import numpy as np
import pytest

from example_pcl import scene as sc
from example_pcl.auto_finder import AutoConfig
from example_pcl.can_finder import CanFinder, FinderConfig, Mode
from example_pcl.errors import PerceptionError


@functools.lru_cache(maxsize=None)
def make_scene(distance=1.0, tilt=0.9, second_can=None, seed=5):
    """A generated scene (cached): one can at the aim point, and optionally a second one (x, y)."""
    cans = [(0.0, 0.0, 0.033, 0.122)] + ([(second_can[0], second_can[1], 0.033, 0.122)] if second_can else [])
    return sc.generate_scene(sc.SceneSpec(camera_distance=distance, tilt=tilt, cans=cans, seed=seed))


def rect(xyz, v, u, half):
    return xyz[v - half:v + half + 1, u - half:u + half + 1]


def table_patch(scene, half=5):
    """A (2 half + 1)^2-pixel patch whose pixels all see the table top, far from the cans."""
    vs, us = np.nonzero(scene.labels == sc.LABEL_TABLE)
    for qv, qu in ((0.8, 0.2), (0.8, 0.8), (0.5, 0.15), (0.3, 0.5)):
        v, u = int(np.quantile(vs, qv)), int(np.quantile(us, qu))
        if (rect(scene.labels, v, u, half) == sc.LABEL_TABLE).all():
            return rect(scene.xyz, v, u, half)
    raise AssertionError("no table patch found")


def can_patch(scene, can=0, qv=0.5, qu=0.5, half=3):
    """A patch around the given quantiles of the pixels of a can's side."""
    vs, us = np.nonzero(scene.labels == sc.LABEL_CAN_SIDE + can)
    assert len(vs) > 50, "the can is not visible"
    return rect(scene.xyz, int(np.quantile(vs, qv)), int(np.quantile(us, qu)), half)


def run(scene, can=0, patch=None, config=FinderConfig()):
    """The seed's walkthrough; returns (finder, results of modes 0..3)."""
    f = CanFinder(scene.xyz, config)
    f.select(table_patch(scene))
    results = [f.process(0), f.process(1)]
    f.select(can_patch(scene, can) if patch is None else patch)
    results += [f.process(2), f.process(3)]
    return f, results


def table_point(scene, x, y, z=0.0):
    """A point given in the table frame (m; z up from the top), in the camera frame."""
    return (np.asarray(scene.truth["camera_from_table"]) @ (x, y, z, 1.0))[:3]


def centre_error(scene, can, estimate):
    return np.linalg.norm(estimate.base_center - np.asarray(scene.truth["cans"][can]["base_center"]))


SWEEP = [(d, t, pos) for d in (0.6, 1.0, 1.5) for t in (0.6, 0.9, 1.3) for pos in (None, (0.12, 0.08), (-0.1, -0.06))]


@pytest.mark.parametrize("distance, tilt, second", SWEEP)
def test_walkthrough_accuracy(distance, tilt, second):
    """Modes 0..3 put the can's base centre within 3 mm and its axis within 1 deg of the truth,
    for cans at the image centre and off it, 0.6-1.5 m away, camera tilts 0.6-1.3 rad."""
    scene = make_scene(distance, tilt, second)
    can = 0 if second is None else 1
    _, results = run(scene, can)
    estimate = results[3].can
    assert centre_error(scene, can, estimate) < 3e-3
    axis = np.asarray(scene.truth["cans"][can]["axis"])
    assert np.degrees(np.arccos(min(1.0, estimate.axis @ axis))) < 1.0
    assert estimate.converged and 0 < estimate.rms_error < 3e-3
    assert "converged in" in results[3].message and "RMS radial error" in results[3].message


def test_table_plane_matches_truth():
    """Mode 0 finds the table's normal within 0.2 deg and offset within 1 mm from an 11x11 patch,
    and its inliers are the table's points (top and the top of its edge)."""
    scene = make_scene(1.2, 0.7)
    f = CanFinder(scene.xyz)
    f.select(table_patch(scene))
    result = f.process(Mode.IDENTIFY_PLANE)
    truth = scene.truth["table"]
    assert np.degrees(np.arccos(f.plane.normal @ truth["normal"])) < 0.2
    assert abs(f.plane.d - truth["d"]) < 1e-3
    labels = scene.labels.reshape(-1)[f.plane_indices]
    assert np.isin(labels, [sc.LABEL_TABLE, sc.LABEL_TABLE_EDGE]).mean() > 0.99  # the edge's top centimetre too
    assert len(result.model) == len(f.plane_indices)
    assert "inliers within 10 mm" in result.message


def test_tilted_small_patch_is_refined():
    """A 5x5-pixel table patch at 1.5 m, whose own normal is degrees off, still yields the table
    within 0.2 deg after refinement."""
    scene = make_scene(1.5, 0.9)
    f = CanFinder(scene.xyz)
    f.select(table_patch(scene, half=2))
    f.process(0)
    assert np.degrees(np.arccos(f.plane.normal @ scene.truth["table"]["normal"])) < 0.2


def test_points_above_are_not_table_or_floor():
    """Mode 1 keeps the cans' points and hardly any table, edge or floor point."""
    scene = make_scene(1.0, 0.9)
    f = CanFinder(scene.xyz)
    f.select(table_patch(scene))
    f.process(0)
    result = f.process(1)
    labels = scene.labels.reshape(-1)[f.above_indices]
    on_can = (labels >= sc.LABEL_CAN_SIDE) & (labels < sc.LABEL_BOX)
    assert on_can.mean() > 0.98
    assert not np.isin(labels, [sc.LABEL_FLOOR]).any()
    assert len(result.model) == len(f.above_indices)


@pytest.mark.parametrize("distance", [0.6, 1.0, 1.5])
def test_any_patch_on_the_visible_half_converges_to_the_same_centre(distance):
    """Patches on the left, middle, right, top and bottom of the can's visible side all converge
    to centres within 2 mm of each other."""
    scene = make_scene(distance, 0.9)
    f = CanFinder(scene.xyz)
    f.select(table_patch(scene))
    f.process(0)
    f.process(1)
    centres = []
    for qv, qu in ((0.5, 0.2), (0.5, 0.5), (0.5, 0.8), (0.2, 0.5), (0.8, 0.5)):
        f.select(can_patch(scene, qv=qv, qu=qu, half=2))
        f.process(2)
        centres.append(f.process(3).can.base_center)
    centres = np.array(centres)
    assert np.linalg.norm(centres - centres.mean(axis=0), axis=1).max() < 1e-3  # all pairs within 2 mm


def test_initial_guess_is_one_radius_behind_the_patch():
    """Mode 2's centre lies within a few mm of the truth (the patch centroid moved one radius away
    from the sensor), and the model it returns surrounds that axis at the can's radius."""
    scene = make_scene(1.0, 0.9)
    f, results = run(scene)
    initial = results[2].can
    assert centre_error(scene, 0, initial) < 5e-3
    assert initial.iterations == 0
    local = (np.asarray(results[2].model, float) - initial.base_center) @ f.T_sensor_from_plane[:3, :3]
    radius = np.hypot(local[:, 0], local[:, 1])
    assert radius.max() == pytest.approx(0.033, abs=1e-5)
    assert "moved 33 mm away from the sensor" in results[2].message


def test_can_patch_with_table_points():
    """A can patch reaching down onto the table (about half its pixels) still gives the centre
    within 3 mm; the message counts the table points dropped."""
    scene = make_scene(1.0, 0.9)
    vs, us = np.nonzero(scene.labels == sc.LABEL_CAN_SIDE)
    v, u = vs.max(), int(np.median(us))
    patch_labels = scene.labels[v - 8:v + 9, u - 6:u + 7]
    assert (patch_labels == sc.LABEL_TABLE).mean() > 0.3
    _, results = run(scene, patch=scene.xyz[v - 8:v + 9, u - 6:u + 7])
    assert centre_error(scene, 0, results[3].can) < 3e-3
    dropped = int(results[2].message.split("(")[2].split(" table points dropped")[0])
    assert dropped > 20


def test_clicked_point_selects_points_within_the_radius():
    """points_near returns exactly the finite scene points within the radius of the click."""
    scene = make_scene(1.0, 0.9)
    f = CanFinder(scene.xyz)
    centre = table_point(scene, 0.1, -0.1)
    near = f.points_near(centre, 0.03)
    flat = scene.xyz.reshape(-1, 3).astype(float)
    with np.errstate(invalid="ignore"):
        expected = np.sum(np.linalg.norm(flat - centre, axis=1) <= 0.03)
    assert len(near) == expected > 100
    assert np.linalg.norm(near - centre, axis=1).max() <= 0.03 + 1e-6


def test_clicked_walkthrough():
    """Clicks on the table and on the can's side (3 cm patches, some table points in the can's)
    take the walkthrough to the centre within 3 mm."""
    scene = make_scene(1.0, 0.9)
    f = CanFinder(scene.xyz)
    f.select_near(table_point(scene, 0.15, -0.1), 0.03)
    f.process(0)
    f.process(1)
    click = can_patch(scene, half=0)[0, 0]
    f.select_near(click, 0.03)
    f.process(2)
    assert centre_error(scene, 0, f.process(3).can) < 3e-3


def test_latest_selection_wins():
    """A can patch selected before mode 1 is replaced by a new selection after mode 1."""
    scene = make_scene(1.0, 0.9)
    f = CanFinder(scene.xyz)
    f.select(table_patch(scene))
    f.process(0)
    f.select(table_patch(scene))  # a wrong "can" patch: on the table, all dropped as table
    f.process(1)
    with pytest.raises(PerceptionError, match="above the table band"):
        f.process(2)
    f.select(can_patch(scene))
    f.process(2)
    assert centre_error(scene, 0, f.process(3).can) < 3e-3


def fresh(scene):
    f = CanFinder(scene.xyz)
    return f


@pytest.mark.parametrize("steps, mode, match", [
    ([], 0, "no patch selected; select a patch on the table"),
    ([], 1, "identify the table first: select a table patch and call mode 0"),
    ([], 2, "identify the table first"),
    ([], 3, "identify the table first"),
    (["table", 0], 2, "call mode 1 first"),
    (["table", 0], 3, "call mode 1 first"),
    (["table", 0, 1], 2, "no can patch yet; select a patch on the side of the can"),
    (["table", 0, 1], 3, "no initial can estimate yet; select a can patch and call mode 2"),
    (["table", 0, 1, "can"], 3, "call mode 2 first"),
])
def test_out_of_order_calls(steps, mode, match):
    """A mode called before its prerequisites fails saying what to do next."""
    scene = make_scene(1.0, 0.9)
    f = fresh(scene)
    for s in steps:
        if s == "table":
            f.select(table_patch(scene))
        elif s == "can":
            f.select(can_patch(scene))
        else:
            f.process(s)
    with pytest.raises(PerceptionError, match=match):
        f.process(mode)


@pytest.mark.parametrize("mode", [5, -1, 99, "x"])
def test_unknown_mode(mode):
    """An unknown mode fails listing the modes."""
    with pytest.raises(PerceptionError, match="unknown mode.*0 IDENTIFY_PLANE.*4 FIND_CAN_AUTO"):
        fresh(make_scene(1.0, 0.9)).process(mode)


BAD_SELECTIONS = {  # name: (points about a point p (sensor frame), what the message says)
    "empty": (lambda p: np.zeros((0, 3)), "empty"),
    "all NaN": (lambda p: np.full((20, 3), np.nan), "no finite points"),
    "inf": (lambda p: np.full((5, 3), np.inf), "no finite points"),
    "two points": (lambda p: p + [[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]], "select a larger patch"),
    "collinear": (lambda p: p + np.outer(np.linspace(-0.02, 0.02, 30), [1.0, 0.0, 0.0]), "line"),
}


@pytest.mark.parametrize("name", list(BAD_SELECTIONS))
def test_bad_selection_fails_and_state_is_kept(name):
    """A bad selection fails mode 0 (and mode 2) with a reason; the plane, the points above and the
    can estimate found before are kept and the walkthrough continues."""
    make_points, match = BAD_SELECTIONS[name]
    scene = make_scene(1.0, 0.9)
    f, _ = run(scene)
    plane, above, can = f.plane, f.above_indices, f.can
    for mode, p in ((0, table_point(scene, 0.2, -0.1)), (2, table_point(scene, 0.0, -0.033, 0.06))):
        f.select(make_points(p))
        with pytest.raises(PerceptionError, match=match):
            f.process(mode)
        assert f.plane is plane and f.above_indices is above and f.can is can
    f.select(can_patch(scene))
    f.process(2)
    assert centre_error(scene, 0, f.process(3).can) < 3e-3


def test_rejected_selection_is_not_replaced_by_an_older_one():
    """After a rejected selection (e.g. in an unknown frame) mode 0 fails with its reason rather
    than using the previous patch."""
    scene = make_scene(1.0, 0.9)
    f = fresh(scene)
    f.select(table_patch(scene))
    f.reject_selection("frame 'map' unknown")
    with pytest.raises(PerceptionError, match="frame 'map' unknown"):
        f.process(0)


def test_new_plane_resets_the_can():
    """Mode 0 again forgets the points above, the can patch and the can estimate."""
    scene = make_scene(1.0, 0.9)
    f, _ = run(scene)
    f.select(table_patch(scene))
    f.process(0)
    assert f.above_indices is None and f.can is None and not f.has_can_patch


def test_mode_3_again_starts_from_the_fit():
    """Calling mode 3 twice keeps the centre (to 0.1 mm) and takes few iterations the second time."""
    scene = make_scene(1.0, 0.9)
    f, results = run(scene)
    again = f.process(3)
    assert np.linalg.norm(again.can.base_center - results[3].can.base_center) < 1e-4
    assert again.can.iterations <= 2


@pytest.mark.parametrize("field, value", [("z_eps", 0), ("can_radius", -1), ("r_eps", 0), ("max_iterations", 0),
                                          ("z_threshold", -0.1), ("viewpoint", (0, 0))])
def test_config_is_validated(field, value):
    """A FinderConfig value that cannot work is refused when the finder is made."""
    with pytest.raises(PerceptionError, match=field):
        CanFinder(np.zeros((10, 3), np.float32), FinderConfig(**{field: value}))


def test_mode_4_finds_every_can_without_a_selection():
    """Mode 4 finds both cans with no selection; the best becomes the estimate and the table the plane."""
    scene = make_scene(1.0, 0.9, second_can=(0.12, 0.08))
    f = CanFinder(scene.xyz, FinderConfig())
    result = f.process(4)
    assert result.mode == Mode.FIND_CAN_AUTO and len(result.cans) == 2
    errors = sorted(min(np.linalg.norm(c.base_center - np.asarray(t["base_center"])) for c in result.cans)
                    for t in scene.truth["cans"])
    assert errors[-1] < 0.003, errors
    assert f.can is not None and f.plane is not None
    assert np.allclose(f.can.T_sensor_from_can, result.cans[0].T_sensor_from_can)
    assert abs(f.plane.normal @ np.asarray(scene.truth["table"]["normal"])) > np.cos(np.radians(0.5))
    assert "found 2 can(s)" in result.message
    assert "best: base centre" in result.message and "image's edge" not in result.message


def test_mode_4_says_when_the_best_can_lies_and_the_image_cuts_it():
    """A lying can cut by the image's edge at column 330 (development seed 5 of "lying can"): mode 4's
    answer gives it from the end seen, its length, and says its far end is beyond the image's edge."""
    from example_pcl import scene_objects

    xyz = np.ascontiguousarray(sc.generate_scene(scene_objects.case_spec("lying can", 5)).xyz[:, :330])
    result = CanFinder(xyz, FinderConfig()).process(4)
    assert len(result.cans) == 1 and result.cans[0].lying and not result.cans[0].end_seen
    assert "best: lying, end centre" in result.message and ", length " in result.message
    assert "its far end beyond the image's edge" in result.message


def test_mode_4_with_no_can_fails_with_the_reason():
    """Mode 4 on a table without cans fails saying nothing was found, and keeps the previous state."""
    empty = sc.generate_scene(sc.SceneSpec(cans=[], boxes=[(0.0, 0.0, 0.1, 0.06, 0.12)], seed=2))
    f = CanFinder(empty.xyz, FinderConfig())
    with pytest.raises(PerceptionError, match="no can found"):
        f.process(4)
    assert f.can is None


def test_modes_1_to_3_continue_from_mode_4():
    """After mode 4, mode 1 finds the points above its table, an earlier selection is not taken as
    the can patch, and a can patch selected after mode 4 gives the same centre (0.1 mm) as modes 0-3
    fitting a can of the size mode 4 found."""
    scene = make_scene(1.0, 0.9)
    f = CanFinder(scene.xyz, FinderConfig())
    f.select(table_patch(scene))
    found = f.process(4).can
    _, reference = run(scene, config=FinderConfig(can_radius=found.radius, can_height=found.height))
    above = f.process(1)
    assert abs(len(above.model) - len(reference[1].model)) <= 0.005 * len(reference[1].model)
    with pytest.raises(PerceptionError, match="no can patch yet"):
        f.process(2)
    f.select(can_patch(scene))
    f.process(2)
    fit = f.process(3)
    assert np.linalg.norm(fit.can.base_center - reference[3].can.base_center) < 1e-4


def test_modes_2_3_after_mode_4_fit_the_size_it_found():
    """After mode 4 found a 45 mm can (the configured size is 33 mm), modes 2 and 3 fit a can of
    mode 4's radius and height: the centre within 3 mm of the truth, the model on the can's side;
    a new mode 0 brings the configured size back."""
    spec = sc.SceneSpec(camera_distance=1.0, tilt=0.9, cans=[(0.0, 0.0, 0.045, 0.15)], seed=5)
    scene = sc.generate_scene(spec)
    f = CanFinder(scene.xyz, FinderConfig())
    found = f.process(4).can
    assert found.radius == pytest.approx(0.045, abs=1e-3)
    f.process(1)
    f.select(can_patch(scene))
    initial = f.process(2).can
    fit = f.process(3)
    for can in (initial, fit.can):
        assert (can.radius, can.height) == (found.radius, found.height)
    assert centre_error(scene, 0, fit.can) < 3e-3
    model = fit.model.astype(float) - fit.can.base_center
    along = model @ fit.can.axis
    assert along.max() == pytest.approx(found.height, abs=1e-5)
    side = np.linalg.norm(model - along[:, None] * fit.can.axis, axis=1).max()
    assert side == pytest.approx(found.radius, abs=1e-5)
    f.select(table_patch(scene))
    f.process(0)
    f.process(1)
    f.select(can_patch(scene))
    assert f.process(2).can.radius == 0.033 and f.can.height == 0.122


def test_mode_2_3_can_reports_its_fit():
    """Modes 2 and 3 return a Can with the configured size, the fit's points (n_fit_points of
    n_points within r_eps), its arc (about the visible half) and the plane-frame centre of its pose."""
    scene = make_scene(1.0, 0.9)
    f, results = run(scene)
    for result in results[2:]:
        can = result.can
        assert (can.radius, can.height) == (0.033, 0.122)
        assert 0 < can.n_fit_points <= can.n_points
        assert 2.0 < can.arc_coverage < 2 * np.pi
        assert can.shape_error is None and can.indices is None
        in_plane = np.linalg.inv(f.T_sensor_from_plane) @ np.append(can.base_center, 1.0)
        np.testing.assert_allclose(in_plane[:2], can.center_plane, atol=1e-9)
        assert set(can.to_dict()) >= {"base_center", "axis", "radius", "height", "rms_error", "arc_coverage",
                                      "n_points", "n_fit_points", "iterations", "converged"}
    assert results[2].can.iterations == 0 and results[3].can.iterations > 0


def test_mode_4_up_prior_replaces_the_configured_one():
    """process(4, up=...) searches only planes near that up: the table's normal (any length) gives
    the cans; the camera's x axis, parallel to the table (the camera does not roll), leaves no
    plane to find, whether it comes from the call or from config.auto.up."""
    scene = make_scene(1.0, 0.6, second_can=(0.12, 0.08))
    normal = np.asarray(scene.truth["table"]["normal"])
    sideways = (1.0, 0.0, 0.0)
    f = CanFinder(scene.xyz, FinderConfig(auto=AutoConfig(up=sideways)))
    with pytest.raises(PerceptionError, match="no plane within"):
        f.process(4)
    result = f.process(4, up=3.0 * normal)
    assert len(result.cans) == 2
    assert abs(f.plane.normal @ normal) > np.cos(np.radians(0.5))
    with pytest.raises(PerceptionError, match="no plane within"):
        CanFinder(scene.xyz).process(4, up=sideways)
    with pytest.raises(PerceptionError, match="up must be a non-zero vector"):
        CanFinder(scene.xyz).process(4, up=(0.0, 0.0, 0.0))


def test_mode_4_no_can_names_what_each_object_failed():
    """Mode 4 on a table with only a box says there is no can and why the box is not one."""
    empty = sc.generate_scene(sc.SceneSpec(cans=[], boxes=[(0.0, 0.0, 0.1, 0.06, 0.12)], seed=2))
    with pytest.raises(PerceptionError, match=r"none a can; object 1 \(\d+ points at \(.*\) m\): \w"):
        CanFinder(empty.xyz).process(4)
