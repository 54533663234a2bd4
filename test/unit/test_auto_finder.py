"""Unit tests of example_pcl.auto_finder: the automatic, selection-free search for cans (issue 5).

Needs the compiled extension (source build/ws/devel/setup.bash). Scenes come from
example_pcl.scene, so every claim is checked against ground truth: all cans found, none invented,
centres within 3 mm and radii within 2 mm.
"""
import json
import pathlib

import numpy as np
import pytest
from numpy.testing import assert_allclose

from example_pcl import auto_finder as af
from example_pcl import scene as sc
from example_pcl.errors import PerceptionError

REAL_KINECT = pathlib.Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / \
    "frame_20121214T142256.332395.pcd"

CENTRE_TOLERANCE = 0.003  # m
RADIUS_TOLERANCE = 0.002  # m

# Cans are (x, y, radius, height) and boxes (x, y, size_x, size_y, size_z) in the table frame (m).
SCENES = {
    "one soda can, 1 m": sc.SceneSpec(),
    "three radii and a box, 0.8 m": sc.SceneSpec(
        camera_distance=0.8, tilt=0.9, seed=1,
        cans=[(0.0, 0.0, 0.04, 0.12), (0.17, 0.05, 0.025, 0.1), (-0.16, 0.08, 0.06, 0.15)],
        boxes=[(0.05, 0.2, 0.08, 0.06, 0.12)]),
    "two cans and two boxes, 1.7 m": sc.SceneSpec(
        camera_distance=1.7, tilt=0.7, yaw=0.3, seed=2,
        cans=[(0.0, 0.0, 0.05, 0.14), (0.3, 0.1, 0.03, 0.11)],
        boxes=[(-0.25, 0.05, 0.12, 0.08, 0.15), (0.15, 0.25, 0.06, 0.06, 0.08)]),
    "four cans seen steeply, 1.2 m": sc.SceneSpec(
        camera_distance=1.2, tilt=1.25, yaw=-0.4, seed=3,
        cans=[(0.0, 0.0, 0.033, 0.122), (0.15, 0.12, 0.055, 0.1), (-0.18, 0.1, 0.028, 0.18),
              (0.1, -0.15, 0.045, 0.09)]),
}
BOXES_ONLY = sc.SceneSpec(camera_distance=1.0, cans=[], seed=4, boxes=[
    (0.0, 0.0, 0.1, 0.07, 0.15), (0.2, 0.1, 0.05, 0.05, 0.1), (-0.2, 0.05, 0.15, 0.1, 0.06)])


@pytest.fixture(scope="module", params=list(SCENES), ids=list(SCENES))
def found(request):
    """(scene, AutoResult) for each scene of SCENES, generated and searched once."""
    scene = sc.generate_scene(SCENES[request.param])
    return scene, af.find_cans(scene.xyz)


@pytest.fixture(scope="module")
def boxes_only():
    scene = sc.generate_scene(BOXES_ONLY)
    return scene, af.find_cans(scene.xyz)


def axis_on_true_table(truth, can):
    """Where the found can's axis meets the true table plane (camera frame, m)."""
    n, d = np.asarray(truth["table"]["normal"]), truth["table"]["d"]
    return can.base_center - (n @ can.base_center + d) / (n @ can.axis) * can.axis


def pairs(truth, cans):
    """(true can, found can, centre error m) for each true can and the found can nearest to it."""
    out = []
    for true in truth["cans"]:
        errors = [np.linalg.norm(axis_on_true_table(truth, c) - true["base_center"]) for c in cans]
        k = int(np.argmin(errors)) if errors else None
        out.append((true, None if k is None else cans[k], None if k is None else errors[k]))
    return out


# --- generated scenes -----------------------------------------------------------------------------


def test_every_can_found_once_and_no_false_can(found):
    """As many cans are reported as there are, each nearest to a different true can."""
    scene, result = found
    assert len(result.cans) == len(scene.truth["cans"]), result.message
    matched = {id(c) for _, c, _ in pairs(scene.truth, result.cans)}
    assert len(matched) == len(result.cans)


def test_centres_within_3_mm(found):
    """Each can's axis meets the true table within 3 mm of the true base centre."""
    scene, result = found
    for true, can, error in pairs(scene.truth, result.cans):
        assert error < CENTRE_TOLERANCE, f"can of radius {true['radius']}: centre off by {1e3 * error:.2f} mm"


def test_radii_within_2_mm(found):
    """Each can's fitted radius is within 2 mm of the true radius."""
    scene, result = found
    for true, can, _ in pairs(scene.truth, result.cans):
        assert abs(can.radius - true["radius"]) < RADIUS_TOLERANCE


def test_heights_and_axes(found):
    """Heights are within 1.5 cm of the truth and the axes within 0.5 degree of the table normal."""
    scene, result = found
    for true, can, _ in pairs(scene.truth, result.cans):
        assert abs(can.height - true["height"]) < 0.015
        assert np.degrees(np.arccos(min(1.0, can.axis @ np.asarray(true["axis"])))) < 0.5


def test_table_is_the_table_not_the_floor(found):
    """The support plane is the table top (within 2 mm and 0.3 degree), though the floor shows too."""
    scene, result = found
    truth = scene.truth["table"]
    assert (scene.labels == sc.LABEL_FLOOR).any()
    assert abs(result.table.d - truth["d"]) < 0.002
    assert np.degrees(np.arccos(min(1.0, result.table.normal @ np.asarray(truth["normal"])))) < 0.3


def test_pose_frames_are_consistent(found):
    """T_sensor_from_can is rigid, has its origin at base_center and its z along the axis."""
    _, result = found
    for can in result.cans:
        T = can.T_sensor_from_can
        assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
        assert_allclose(T[:3, 3], can.base_center)
        assert_allclose(T[:3, 2], can.axis)
        assert_allclose(can.axis, result.table.normal, atol=1e-12)


def test_cans_sorted_best_first(found):
    """Cans come with the most side points in their fit first."""
    _, result = found
    counts = [c.n_fit_points for c in result.cans]
    assert counts == sorted(counts, reverse=True)


def test_boxes_only_gives_no_can(boxes_only):
    """A table with boxes and no can: no can, and every box rejected with a reason."""
    scene, result = boxes_only
    assert result.cans == []
    assert len(result.rejected) == len(scene.truth["boxes"])
    assert all(r.reason for r in result.rejected)
    assert "none a can" in result.message


def test_floor_larger_than_table_is_not_taken():
    """From far away the floor has more points than the table; the table is still chosen."""
    scene = sc.generate_scene(sc.SceneSpec(camera_distance=1.8, tilt=0.8, seed=5,
                                           cans=[(0.0, 0.0, 0.03, 0.1)]))
    assert (scene.labels == sc.LABEL_FLOOR).sum() > (scene.labels == sc.LABEL_TABLE).sum()
    result = af.find_cans(scene.xyz)
    assert abs(result.table.d - scene.truth["table"]["d"]) < 0.002
    assert len(result.cans) == 1


def test_up_prior_restricts_the_table():
    """With `up` given, the table found is a plane whose normal is within max_tilt of it."""
    scene = sc.generate_scene(SCENES["one soda can, 1 m"])
    up = np.asarray(scene.truth["table"]["normal"])
    result = af.find_cans(scene.xyz, config=af.AutoConfig(up=tuple(up)))
    assert len(result.cans) == 1
    sideways = np.cross(up, [1.0, 0.0, 0.0])
    try:
        result = af.find_cans(scene.xyz, config=af.AutoConfig(up=tuple(sideways), max_tilt=0.1))
    except PerceptionError as e:  # no such plane at all: also a correct answer
        assert "no plane within" in str(e)
        return
    assert abs(result.table.normal @ sideways) > np.cos(0.1)
    assert result.cans == []


# A grazing view (the camera 0.2 m above the table, 0.2 rad down) of two cans in front of a "wall":
# a box 0.5 m wide and 0.4 m tall whose face, square to the camera, is the largest plane in view.
WALL_SCENE = sc.SceneSpec(camera_distance=1.0, tilt=0.2, cans=[(0.0, 0.0, 0.033, 0.122), (0.12, -0.05, 0.04, 0.1)],
                          boxes=[(0.0, 0.25, 0.5, 0.05, 0.4)], seed=7)


def _plane_error_deg(result, truth):
    return float(np.degrees(np.arccos(min(1.0, abs(result.table.normal @ np.asarray(truth["table"]["normal"]))))))


def test_up_prior_keeps_a_wall_from_being_the_table():
    """Without a prior the wall's face wins the table search on this scene; with the table's up it
    is the table, and both cans come out within 1 mm."""
    scene = sc.generate_scene(WALL_SCENE)
    up = tuple(scene.truth["table"]["normal"])
    unguided = af.find_cans(scene.xyz)
    assert _plane_error_deg(unguided, scene.truth) > 45 and unguided.cans == []
    guided = af.find_cans(scene.xyz, config=af.AutoConfig(up=up))
    assert _plane_error_deg(guided, scene.truth) < 0.25
    assert len(guided.cans) == 2
    for can in guided.cans:
        assert min(np.linalg.norm(can.base_center - np.asarray(t["base_center"])) for t in scene.truth["cans"]) < 1e-3


def test_table_refinement_runs_until_the_plane_stops_moving():
    """On the grazing view one least-squares pass leaves the RANSAC plane's tilt partly in; the
    default passes take it out (0.29 -> 0.19 deg measured)."""
    scene = sc.generate_scene(WALL_SCENE)
    up = tuple(scene.truth["table"]["normal"])
    one = af.find_cans(scene.xyz, config=af.AutoConfig(up=up, refine_iterations=1))
    default = af.find_cans(scene.xyz, config=af.AutoConfig(up=up))
    assert _plane_error_deg(default, scene.truth) < _plane_error_deg(one, scene.truth) - 0.05


def test_unorganized_cloud_uses_euclidean_clusters():
    """An (N, 3) cloud (NaN dropped) gives the same can as the organized one, by PCL's clusters."""
    scene = sc.generate_scene(SCENES["one soda can, 1 m"])
    flat = scene.xyz.reshape(-1, 3)
    flat = flat[np.isfinite(flat).all(axis=1)]
    organized = af.find_cans(scene.xyz).cans[0]
    unorganized = af.find_cans(flat).cans[0]
    assert_allclose(unorganized.base_center, organized.base_center, atol=5e-4)
    assert abs(unorganized.radius - organized.radius) < 5e-4


# --- real data and degenerate input ---------------------------------------------------------------


@pytest.mark.skipif(not REAL_KINECT.exists(), reason=f"the real Kinect frame is not there ({REAL_KINECT})")
def test_real_kinect_frame_has_no_can():
    """PCL's real Kinect frame (boxes on a floor, no cans): no can found, and it says so."""
    from example_pcl.pcd import read_pcd

    result = af.find_cans(read_pcd(str(REAL_KINECT)).xyz)
    assert result.cans == []
    assert result.message.startswith("no can found")


def test_message_counts_the_lying_cans():
    """A lying can touching an upright one (development seed 3): "found 2 can(s), 1 lying, radii ..."."""
    from example_pcl import scene_objects

    result = af.find_cans(sc.generate_scene(scene_objects.case_spec("lying can touching can", 3)).xyz)
    assert sorted(c.lying for c in result.cans) == [False, True]
    assert result.message.startswith("found 2 can(s), 1 lying, radii "), result.message


def _lying_can_seed_5():
    """A "lying can" scene (development seed 5: a lying can across columns 282-360 beside an upright
    can) and its lying can's ends (plane frame, m) and T_plane_from_sensor."""
    from example_pcl import scene_objects, transforms

    spec = scene_objects.case_spec("lying can", 5)
    scene = sc.generate_scene(spec)
    truth = next(t for t in scene.truth["objects"] if t["lying"])
    to_plane = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    start = transforms.apply(to_plane, truth["base_center"])
    end = transforms.apply(to_plane, np.asarray(truth["base_center"]) + truth["height"] * np.asarray(truth["axis"]))
    return scene, (start, end), to_plane


@pytest.mark.parametrize("how", ["cropped", "holes"])
def test_a_lying_can_cut_by_the_image_edge_starts_from_the_end_seen(how):
    """The image ends at column 330, across a lying can (cropped, or NaN beyond as a Kinect's
    border): end_seen False, its origin the end seen (within 4 mm of the truth's), its axis toward
    the end cut off, its height shorter than the can; in full view, end_seen True."""
    from example_pcl import transforms

    scene, ends, to_plane = _lying_can_seed_5()
    full = af.find_cans(scene.xyz)
    assert len(full.cans) == 2 and all(c.end_seen and c.base_seen for c in full.cans)
    if how == "cropped":
        xyz = np.ascontiguousarray(scene.xyz[:, :330])
    else:
        xyz = scene.xyz.copy()
        xyz[:, 330:] = np.nan
    cans = af.find_cans(xyz).cans
    assert len(cans) == 1 and cans[0].lying  # the upright can stands beyond column 394
    can = cans[0]
    assert not can.end_seen and can.base_seen
    origin = transforms.apply(to_plane, can.base_center)
    seen, cut = sorted(ends, key=lambda e: np.linalg.norm(e[:2] - origin[:2]))
    assert np.linalg.norm(origin[:2] - seen[:2]) < 0.004
    assert (transforms.apply(to_plane, can.base_center + can.axis) - origin) @ (cut - seen) > 0
    assert can.height < np.linalg.norm(cut - seen) - 0.02
    assert can.to_dict()["end_seen"] is False


def test_a_lying_can_the_bottom_edge_cuts_lengthwise_says_so():
    """The image ends at row 215, along the lying can (its pixels on the edge from end to end, the
    axis leaving the image beyond one end): end_seen False, shorter than the can; the upright can
    whose base is below the edge stands on the table (base_seen False), its whole height seen."""
    scene, ends, _ = _lying_can_seed_5()
    cans = af.find_cans(np.ascontiguousarray(scene.xyz[:215])).cans
    assert sorted(c.lying for c in cans) == [False, True]
    lying, upright = (next(c for c in cans if c.lying is flag) for flag in (True, False))
    assert not lying.end_seen and lying.height < np.linalg.norm(ends[1] - ends[0]) - 0.05
    assert upright.end_seen and not upright.base_seen and abs(upright.height - 0.15) < 0.003


def test_an_upright_can_whose_top_is_cut_by_the_image_edge_says_so():
    """The image begins at row 180, across the upright can's upper part: end_seen False, its height
    what is seen (less than its 150 mm), from can_search and from the issue 5 finder alike."""
    scene, _, _ = _lying_can_seed_5()
    for config in (af.AutoConfig(), af.AutoConfig(search="clusters")):  # either search marks it
        upright = [c for c in af.find_cans(np.ascontiguousarray(scene.xyz[180:]), config=config).cans if not c.lying]
        assert len(upright) == 1 and not upright[0].end_seen and upright[0].base_seen, config.search
        assert upright[0].height < 0.145


@pytest.mark.parametrize("xyz", [np.full((48, 64, 3), np.nan, np.float32), np.zeros((0, 3), np.float32)],
                         ids=["all NaN", "empty"])
def test_no_points_is_a_clear_error(xyz):
    """A cloud without finite points raises PerceptionError saying there is no table to find."""
    with pytest.raises(PerceptionError, match="finite point"):
        af.find_cans(xyz)


def test_wrong_shape_is_a_clear_error():
    """A cloud that is not (N, 3) or (H, W, 3) raises PerceptionError naming its shape."""
    with pytest.raises(PerceptionError, match=r"\(10, 2\)"):
        af.find_cans(np.zeros((10, 2), np.float32))


def test_random_points_give_no_plane():
    """A cloud of scattered points (no plane) raises PerceptionError asking for a table."""
    xyz = np.random.default_rng(0).uniform(-1, 1, (2000, 3)).astype(np.float32)
    with pytest.raises(PerceptionError, match="table"):
        af.find_cans(xyz, config=af.AutoConfig(min_plane_fraction=0.3))


@pytest.mark.parametrize("change", [{"min_radius": 0.1}, {"max_height": 0.0}, {"clustering": "kd"},
                                    {"ransac_step": 0}, {"up": (0.0, 0.0, 0.0)}])
def test_bad_config_rejected(change):
    """A config that makes no sense is refused with PerceptionError before any work."""
    with pytest.raises(PerceptionError, match="AutoConfig"):
        af.find_cans(np.zeros((4, 4, 3), np.float32), config=af.AutoConfig(**change))


# --- the shape criterion --------------------------------------------------------------------------


def test_shape_error_small_for_a_noisy_arc_large_for_a_corner():
    """A noisy half circle has a shape error far below the threshold; two faces of a box far above."""
    rng = np.random.default_rng(0)
    a = rng.uniform(0, np.pi, 400)
    r = 0.04 + rng.normal(0, 0.003, 400)
    arc = np.column_stack([r * np.cos(a), r * np.sin(a)])
    assert af.shape_error(arc, 0.0, 0.0, 0.04, 8) < 0.3 * af.AutoConfig().max_shape_error
    t = rng.uniform(0, 0.06, 400)
    corner = np.where(rng.random(400)[:, None] < 0.5, np.column_stack([t, 0 * t]), np.column_stack([0 * t, t]))
    from example_pcl import geometry as g

    cx, cy, r0 = g.fit_circle_algebraic(corner)
    fit = g.fit_cylinder(corner, (cx, cy), r0, 0.02)
    assert af.shape_error(corner, fit.cx, fit.cy, fit.radius, 8) > 2 * af.AutoConfig().max_shape_error


# --- command line ---------------------------------------------------------------------------------


def test_cli_prints_cans_as_json(tmp_path, capsys):
    """find_cans SCENE.pcd prints JSON with the can's pose and radius, exit status 0."""
    from example_pcl.pcd import write_cloud

    scene = sc.generate_scene(SCENES["one soda can, 1 m"])
    path = tmp_path / "scene.pcd"
    write_cloud(str(path), scene.xyz, fmt="binary")
    assert af.main([str(path)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["cans"]) == 1
    can = out["cans"][0]
    assert abs(can["radius"] - scene.truth["cans"][0]["radius"]) < RADIUS_TOLERANCE
    assert np.asarray(can["T_sensor_from_can"]).shape == (4, 4)
    assert out["timings_ms"]["total"] > 0


def test_cli_no_can_exits_0_with_message(tmp_path, capsys):
    """With no can in the scene the CLI still exits 0: "cans": [] and the reason on stderr."""
    from example_pcl.pcd import write_cloud

    scene = sc.generate_scene(sc.SceneSpec(cans=[], seed=6))
    path = tmp_path / "empty.pcd"
    write_cloud(str(path), scene.xyz, fmt="binary")
    assert af.main([str(path)]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["cans"] == []
    assert "no can found" in captured.err


def test_cli_unreadable_file_exits_1(tmp_path, capsys):
    """A missing file is reported on stderr with exit status 1 and no JSON."""
    assert af.main([str(tmp_path / "missing.pcd")]) == 1
    captured = capsys.readouterr()
    assert captured.out == "" and "missing.pcd" in captured.err


def test_cli_honours_the_pcd_viewpoint(tmp_path, capsys):
    """A scene saved in a robot's base frame (on the floor, below the table), its VIEWPOINT the camera's
    pose there: the can is found at its true place (normals turned toward the recorded sensor, not
    toward the frame's origin under the table)."""
    from scipy.spatial.transform import Rotation

    from example_pcl.pcd import write_cloud

    scene = sc.generate_scene(SCENES["one soda can, 1 m"])
    base_from_table = np.array([0.3, -0.2, scene.truth["table"]["height"]])  # the table top in the base frame
    T_table_from_camera = np.linalg.inv(np.asarray(scene.truth["camera_from_table"]))
    R, t = T_table_from_camera[:3, :3], T_table_from_camera[:3, 3] + base_from_table
    xyz_table = (scene.xyz.astype(float) @ R.T + t).astype(np.float32)
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    path = tmp_path / "base_frame.pcd"
    write_cloud(str(path), xyz_table, fmt="binary", origin=tuple(t), orientation=(w, x, y, z))
    assert af.main([str(path)]) == 0
    cans = json.loads(capsys.readouterr().out)["cans"]
    assert len(cans) == 1
    assert_allclose(cans[0]["base_center"], base_from_table, atol=CENTRE_TOLERANCE)
    assert_allclose(cans[0]["axis"], [0.0, 0.0, 1.0], atol=0.01)
