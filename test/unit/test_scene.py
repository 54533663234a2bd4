"""Unit tests of example_pcl.scene, the simulated Kinect (pure NumPy, no ROS, no extension)."""
import dataclasses
import json
import os
import pathlib
import sys
import types

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from example_pcl import geometry
from example_pcl import scene as sc
from example_pcl.errors import PerceptionError

REPO = pathlib.Path(__file__).resolve().parents[2]


def exact(**kw):
    """A spec without noise or random dropout: every returned point lies exactly on its surface."""
    return sc.SceneSpec(noise=False, dropout=0.0, **kw)


@pytest.fixture(scope="module")
def default_scene():
    return sc.generate_scene(sc.SceneSpec())


@pytest.fixture(scope="module")
def exact_scene():
    return sc.generate_scene(exact())


def plane_of(truth):
    return np.array(truth["table"]["normal"]), truth["table"]["d"]


def distance_from_axis(points, can):
    """Distance (m) of each point from the can's axis line."""
    rel = points - np.array(can["base_center"])
    axis = np.array(can["axis"])
    return np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)


def test_shape_and_dtype(default_scene):
    """xyz is float32 (480, 640, 3), rgb uint8 (480, 640, 3), labels (480, 640)."""
    assert default_scene.xyz.shape == (480, 640, 3) and default_scene.xyz.dtype == np.float32
    assert default_scene.rgb.shape == (480, 640, 3) and default_scene.rgb.dtype == np.uint8
    assert default_scene.labels.shape == (480, 640)


def test_no_return_is_nan_in_all_three_coordinates(default_scene):
    """A pixel without depth is NaN in x, y and z alike, never partly."""
    nan = np.isnan(default_scene.xyz)
    assert_array_equal(nan[..., 0], nan[..., 2])
    assert_array_equal(nan[..., 1], nan[..., 2])


def test_default_scene_shows_can_table_and_floor(default_scene):
    """The default scene has the can near the image centre, table all around it, floor beyond."""
    labels = default_scene.labels
    rows, cols = np.nonzero(labels == sc.LABEL_CAN_SIDE)
    assert len(rows) > 500
    assert abs(cols.mean() - sc.CX) < 40 and abs(rows.mean() - sc.CY) < 60
    r0, r1, c0, c1 = rows.min(), rows.max(), cols.min(), cols.max()
    # table on all four sides of the can's bounding box
    assert (labels[r0 - 20, c0:c1] == sc.LABEL_TABLE).all() and (labels[r1 + 20, c0:c1] == sc.LABEL_TABLE).all()
    assert (labels[r0:r1, c0 - 30] == sc.LABEL_TABLE).mean() > 0.9
    assert (labels[r0:r1, c1 + 30] == sc.LABEL_TABLE).all()
    assert (labels[0] == sc.LABEL_FLOOR).all()  # floor beyond the far edge of the table
    assert default_scene.truth["table"]["height"] == pytest.approx(0.75)


def test_truth_plane_normal_is_unit_and_faces_camera(default_scene):
    """The truth table normal is a unit vector pointing toward the camera (d > 0 for the origin)."""
    n, d = plane_of(default_scene.truth)
    assert np.linalg.norm(n) == pytest.approx(1.0)
    assert d > 0  # the camera (origin) is on the side the normal points to


def test_can_base_lies_on_truth_plane(default_scene):
    """Each can's truth base centre lies on the truth table plane and its axis is the normal."""
    n, d = plane_of(default_scene.truth)
    for can in default_scene.truth["cans"]:
        assert n @ np.array(can["base_center"]) + d == pytest.approx(0.0, abs=1e-12)
        assert_allclose(can["axis"], n, atol=1e-12)
        assert can["radius"] == 0.033 and can["height"] == 0.122


def test_can_side_points_at_radius_from_axis(exact_scene):
    """Noise-free, every can-side point is one radius from the truth axis, between base and top."""
    can = exact_scene.truth["cans"][0]
    pts = exact_scene.xyz[exact_scene.labels == sc.LABEL_CAN_SIDE].astype(float)
    pts = pts[np.isfinite(pts[:, 2])]
    assert len(pts) > 500
    assert_allclose(distance_from_axis(pts, can), can["radius"], atol=2e-6)
    along = (pts - np.array(can["base_center"])) @ np.array(can["axis"])
    assert along.min() >= -1e-6 and along.max() <= can["height"] + 1e-6


def test_can_top_points_on_top_disc(exact_scene):
    """Noise-free, can-top points are one height above the table and within the radius."""
    can = exact_scene.truth["cans"][0]
    n, d = plane_of(exact_scene.truth)
    pts = exact_scene.xyz[exact_scene.labels == sc.LABEL_CAN_TOP].astype(float)
    pts = pts[np.isfinite(pts[:, 2])]
    assert len(pts) > 100
    assert_allclose(pts @ n + d, can["height"], atol=2e-6)
    assert (distance_from_axis(pts, can) <= can["radius"] + 1e-6).all()


def test_table_points_satisfy_plane_equation(exact_scene):
    """Noise-free, table-top points satisfy normal . p + d = 0 and lie inside the table rectangle."""
    n, d = plane_of(exact_scene.truth)
    pts = exact_scene.xyz[exact_scene.labels == sc.LABEL_TABLE].astype(float)
    pts = pts[np.isfinite(pts[:, 2])]
    assert len(pts) > 100000
    assert_allclose(pts @ n + d, 0.0, atol=2e-6)
    T = np.array(exact_scene.truth["camera_from_table"])
    in_table = (pts - T[:3, 3]) @ T[:3, :3]  # back into the table frame
    assert (np.abs(in_table[:, 0]) <= 0.6 + 1e-5).all() and (np.abs(in_table[:, 1]) <= 0.4 + 1e-5).all()


def test_floor_points_satisfy_floor_plane(exact_scene):
    """Noise-free, floor points lie on the truth floor plane, table_height below the table."""
    floor = exact_scene.truth["floor"]
    pts = exact_scene.xyz[exact_scene.labels == sc.LABEL_FLOOR].astype(float)
    pts = pts[np.isfinite(pts[:, 2])]
    assert len(pts) > 1000
    assert_allclose(pts @ np.array(floor["normal"]) + floor["d"], 0.0, atol=1e-5)
    assert floor["d"] - exact_scene.truth["table"]["d"] == pytest.approx(0.75)


def test_projector_shadow_beside_can(exact_scene):
    """Noise-free, table pixels just left of the can (away from the +x projector) have no depth."""
    labels, z = exact_scene.labels, exact_scene.xyz[..., 2]
    rows, cols = np.nonzero(labels >= sc.LABEL_CAN_SIDE)  # side and top: the can's silhouette
    shadow = (labels == sc.LABEL_TABLE) & np.isnan(z)
    assert shadow.sum() > 50
    left, right = np.zeros_like(shadow), np.zeros_like(shadow)
    for r in np.unique(rows):
        c = cols[rows == r]
        left[r, max(c.min() - 15, 0):c.min()] = True
        right[r, c.max() + 1:c.max() + 16] = True
    assert (shadow & left).sum() == shadow.sum()  # all of it hugs the can's left side
    assert not (shadow & right).any()


def test_no_shadow_without_projector_offset():
    """With the projector at the camera (offset 0) and no dropout, every table pixel has depth."""
    s = sc.generate_scene(exact(projector_offset=0.0))
    assert np.isfinite(s.xyz[s.labels == sc.LABEL_TABLE]).all()


def test_same_seed_same_scene():
    """Two scenes from the same spec and seed are identical; another seed differs."""
    a = sc.generate_scene(sc.SceneSpec(seed=7))
    b = sc.generate_scene(sc.SceneSpec(seed=7))
    c = sc.generate_scene(sc.SceneSpec(seed=8))
    assert_array_equal(a.xyz, b.xyz)
    assert_array_equal(a.rgb, b.rgb)
    assert a.truth == b.truth
    assert not np.array_equal(a.xyz, c.xyz, equal_nan=True)


def test_generator_passed_in_is_used():
    """A Generator passed to generate_scene decides the noise, whatever spec.seed says."""
    a = sc.generate_scene(sc.SceneSpec(seed=1), rng=np.random.default_rng(42))
    b = sc.generate_scene(sc.SceneSpec(seed=2), rng=np.random.default_rng(42))
    assert_array_equal(a.xyz, b.xyz)


def test_depth_noise_follows_kinect_model():
    """Depth noise on the table has zero mean and sigma = 1.425e-3 z^2 (within 3 %)."""
    noisy = sc.generate_scene(sc.SceneSpec(dropout=0.0, seed=3))
    clean = sc.generate_scene(exact(seed=3))
    mask = (noisy.labels == sc.LABEL_TABLE) & np.isfinite(clean.xyz[..., 2])
    z = clean.xyz[..., 2][mask].astype(float)
    normalised = (noisy.xyz[..., 2][mask] - z) / (1.425e-3 * z ** 2)
    assert abs(normalised.mean()) < 0.02
    assert normalised.std() == pytest.approx(1.0, rel=0.03)


def test_noisy_points_stay_on_their_pixel_ray():
    """Noise moves points along the pixel's ray only: x/z and y/z are those of the pixel."""
    s = sc.generate_scene(sc.SceneSpec(seed=4))
    rays = sc.pixel_rays()
    ok = np.isfinite(s.xyz[..., 2])
    xyz = s.xyz[ok].astype(float)
    assert_allclose(xyz[:, :2] / xyz[:, 2:], rays[ok][:, :2], atol=1e-6)


def test_quantized_depth_takes_disparity_steps():
    """With quantize, every depth is fx * 0.075 / (k / 8) for an integer k (1/8 px disparity)."""
    s = sc.generate_scene(sc.SceneSpec(quantize=True, seed=5))
    z = s.xyz[..., 2][np.isfinite(s.xyz[..., 2])].astype(float)
    k = 8 * sc.FX * 0.075 / z
    assert_allclose(k, np.round(k), atol=1e-2)


def test_dropout_fraction():
    """A 5 % dropout removes about 5 % of the otherwise returned pixels."""
    base = sc.generate_scene(exact(seed=6))
    dropped = sc.generate_scene(sc.SceneSpec(noise=False, dropout=0.05, seed=6))
    had = np.isfinite(base.xyz[..., 2])
    lost = had & np.isnan(dropped.xyz[..., 2])
    assert lost.sum() / had.sum() == pytest.approx(0.05, abs=0.005)


def test_no_depth_beyond_max_range():
    """Looking nearly level, no returned depth exceeds max_range, and far floor is NaN."""
    s = sc.generate_scene(exact(camera_distance=1.0, tilt=0.3, max_range=2.5))
    z = s.xyz[..., 2]
    assert np.nanmax(z) <= 2.5
    assert np.isnan(z[s.labels == sc.LABEL_FLOOR]).any()


@pytest.mark.parametrize("distance, tilt, yaw", [
    (0.6, 0.5, 0.0), (0.8, 1.2, 0.0), (1.0, 0.9, 0.4), (1.4, 0.7, -0.3), (1.8, 1.0, 0.0), (1.8, 0.5, 1.0),
])
def test_geometry_holds_for_distances_and_tilts(distance, tilt, yaw):
    """For distances 0.6-1.8 m and tilts 0.5-1.2 rad the can is seen, near the centre, on the plane."""
    s = sc.generate_scene(exact(camera_distance=distance, tilt=tilt, yaw=yaw))
    truth = s.truth
    can = truth["cans"][0]
    base = np.array(can["base_center"])
    assert np.linalg.norm(base) == pytest.approx(distance)
    assert_allclose(base[:2] / base[2], 0.0, atol=1e-9)  # the optical axis passes through the base
    n, d = plane_of(truth)
    assert np.arcsin(-n[1]) == pytest.approx(np.pi / 2 - tilt)  # normal's elevation from tilt
    side = s.xyz[s.labels == sc.LABEL_CAN_SIDE].astype(float)
    side = side[np.isfinite(side[:, 2])]
    assert len(side) > 50
    assert_allclose(distance_from_axis(side, can), can["radius"], atol=5e-6)
    table = s.xyz[s.labels == sc.LABEL_TABLE].astype(float)
    table = table[np.isfinite(table[:, 2])]
    assert_allclose(table @ n + d, 0.0, atol=5e-6)


def test_camera_pose_is_rigid_and_consistent(default_scene):
    """camera_from_table is a rigid transform mapping the table origin to the truth table centre."""
    T = np.array(default_scene.truth["camera_from_table"])
    assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    assert_allclose(T[3], [0, 0, 0, 1])
    assert_allclose(T[:3, 3], default_scene.truth["table"]["center"])
    assert_allclose(T[:3, 2], default_scene.truth["table"]["normal"])


def test_several_cans_and_a_box():
    """Every can and box appears with its own label, boxes blue, the box top box-height above the table."""
    spec = exact(cans=[(0.0, 0.0, 0.033, 0.122), (0.2, 0.1, 0.04, 0.15)], boxes=[(-0.2, 0.05, 0.08, 0.06, 0.1)])
    s = sc.generate_scene(spec)
    assert (s.labels == sc.LABEL_CAN_SIDE + 1).sum() > 200
    box = s.labels == sc.LABEL_BOX
    assert box.sum() > 500
    rgb = s.rgb[box].astype(int)
    assert (rgb[:, 2] > rgb[:, 0]).all() and (rgb[:, 2] > rgb[:, 1]).all()
    n, d = plane_of(s.truth)
    heights = s.xyz[box].astype(float) @ n + d
    assert np.nanmax(heights) == pytest.approx(0.1, abs=1e-5)
    assert len(s.truth["cans"]) == 2 and len(s.truth["boxes"]) == 1
    assert s.truth["boxes"][0]["size"] == [0.08, 0.06, 0.1]


def test_colours_by_surface(exact_scene):
    """Cans are red-ish, the table brown (red > green > blue), the floor grey."""
    rgb, labels = exact_scene.rgb.astype(int), exact_scene.labels
    can = rgb[labels == sc.LABEL_CAN_SIDE]
    assert (can[:, 0] > 2 * can[:, 1]).all()
    table = rgb[labels == sc.LABEL_TABLE]
    assert ((table[:, 0] > table[:, 1]) & (table[:, 1] > table[:, 2])).all()
    floor = rgb[labels == sc.LABEL_FLOOR]
    assert (floor[:, 0] == floor[:, 1]).all() and (floor[:, 1] == floor[:, 2]).all()


@pytest.mark.parametrize("kw, message", [
    (dict(cans=[(0.7, 0.0, 0.033, 0.122)]), "overhangs the table"),
    (dict(cans=[(0.0, 0.0, -0.03, 0.122)]), "must be > 0"),
    (dict(tilt=0.0), "tilt"),
    (dict(tilt=2.0), "tilt"),
    (dict(camera_distance=0.0), "camera_distance"),
    (dict(dropout=1.0), "dropout"),
    (dict(boxes=[(0.0, 0.0, 0.1, 0.1)]), "box 0"),
])
def test_invalid_spec_raises_perception_error(kw, message):
    """A spec that cannot make a scene raises PerceptionError naming the bad value."""
    with pytest.raises(PerceptionError, match=message):
        sc.generate_scene(sc.SceneSpec(**kw))


def test_truth_json_round_trips(default_scene):
    """The truth dict survives json.dumps/json.loads unchanged (plain lists, floats, ints)."""
    assert json.loads(json.dumps(default_scene.truth)) == default_scene.truth


@pytest.fixture
def fake_pcd(monkeypatch):
    """Stands in for example_pcl.pcd (compiled extension) and records the write_cloud calls."""
    calls = []

    def write_cloud(path, xyz, rgb=None, fmt="binary_compressed"):
        calls.append(dict(path=path, xyz=xyz, rgb=rgb, fmt=fmt))
        pathlib.Path(path).write_bytes(b"fake")

    module = types.ModuleType("example_pcl.pcd")
    module.write_cloud = write_cloud
    monkeypatch.setitem(sys.modules, "example_pcl.pcd", module)
    return calls


def test_cli_writes_cloud_and_truth(tmp_path, fake_pcd, capsys):
    """make_scene writes OUT.pcd through pcd.write_cloud and the truth beside it as OUT.json."""
    out = tmp_path / "two_cans.pcd"
    status = sc.main([str(out), "--distance", "1.2", "--tilt", "0.8", "--can", "0", "0", "0.033", "0.122",
                      "--can", "0.15", "0.05", "0.04", "0.15", "--box", "-0.2", "0", "0.1", "0.1", "0.1",
                      "--seed", "3", "--format", "binary"])
    assert status == 0
    (call,) = fake_pcd
    assert call["path"] == str(out) and call["fmt"] == "binary"
    expected = sc.generate_scene(sc.SceneSpec(camera_distance=1.2, tilt=0.8, seed=3,
                                              cans=[(0, 0, 0.033, 0.122), (0.15, 0.05, 0.04, 0.15)],
                                              boxes=[(-0.2, 0, 0.1, 0.1, 0.1)]))
    assert_array_equal(call["xyz"], expected.xyz)
    assert_array_equal(call["rgb"], expected.rgb)
    truth = json.loads((tmp_path / "two_cans.json").read_text())
    assert truth == expected.truth
    assert sorted(p.name for p in tmp_path.iterdir()) == ["two_cans.json", "two_cans.pcd"]
    assert "two_cans.json" in capsys.readouterr().out


def test_cli_defaults_give_default_scene(tmp_path, fake_pcd):
    """make_scene OUT.pcd alone writes the default scene, binary_compressed."""
    sc.main([str(tmp_path / "scene.pcd")])
    assert fake_pcd[0]["fmt"] == "binary_compressed"
    assert_array_equal(fake_pcd[0]["xyz"], sc.generate_scene(sc.SceneSpec()).xyz)


def test_cli_case_writes_that_case(tmp_path, fake_pcd, capsys):
    """make_scene --case NAME --seed N writes scene_objects.case_spec(NAME, N), the scene the benchmark
    scores, with its objects' truth; --distance moves its camera."""
    from example_pcl import scene_objects

    out = tmp_path / "lying.pcd"
    assert sc.main([str(out), "--case", "lying can touching box", "--seed", "5"]) == 0
    expected = sc.generate_scene(scene_objects.case_spec("lying can touching box", 5))
    assert_array_equal(fake_pcd[0]["xyz"], expected.xyz)
    truth = json.loads((tmp_path / "lying.json").read_text())
    assert truth == expected.truth
    assert [(o["kind"], o["lying"]) for o in truth["objects"]] == [("lying_can", True), ("box", False)]
    assert "'lying can touching box' seed 5: lying_can, box" in capsys.readouterr().out

    assert sc.main([str(out), "--case", "cup on can", "--seed", "2", "--distance", "1.1", "--no-noise"]) == 0
    spec = dataclasses.replace(scene_objects.case_spec("cup on can", 2), camera_distance=1.1, noise=False)
    assert_array_equal(fake_pcd[1]["xyz"], sc.generate_scene(spec).xyz)


@pytest.mark.parametrize("argv", [["out.txt"], ["out.pcd", "--can", "0.7", "0", "0.03", "0.1"],
                                  ["out.pcd", "--format", "xml"], ["out.pcd", "--case", "a can"],
                                  ["out.pcd", "--case", "can on can", "--box", "0", "0", "0.1", "0.1", "0.1"]])
def test_cli_rejects_bad_arguments(tmp_path, fake_pcd, argv, capsys):
    """make_scene exits with status 2 and a message for a bad file name, scene, format or case."""
    with pytest.raises(SystemExit) as e:
        sc.main([str(tmp_path / argv[0])] + argv[1:])
    assert e.value.code == 2
    assert "make_scene" in capsys.readouterr().err
    assert not fake_pcd


def test_script_is_executable_and_calls_main():
    """scripts/make_scene is an executable python3 script that runs example_pcl.scene.main()."""
    script = REPO / "scripts" / "make_scene"
    assert os.access(script, os.X_OK)
    text = script.read_text()
    assert text.startswith("#!/usr/bin/python3\n") and "example_pcl.scene.main()" in text


def test_can_pose_error_against_truth():
    """can_pose_error gives the centre distance (m) and the axis angle (deg) from a ground-truth can."""
    truth = {"base_center": [0.0, 0.0, 1.0], "axis": [0.0, -0.6216099682706644, -0.7833269096274834]}
    T = geometry.plane_frame(truth["axis"], np.array(truth["base_center"]) + (0.003, 0.0, 0.004))
    centre, axis = sc.can_pose_error(T, truth)
    assert centre == pytest.approx(0.005, abs=1e-9) and axis == pytest.approx(0.0, abs=1e-5)
    tilted = geometry.plane_frame((0.0, -0.7, -0.7), truth["base_center"])
    expected = np.degrees(np.arccos(np.dot(np.array([0.0, -0.7, -0.7]) / np.sqrt(0.98), truth["axis"])))
    assert sc.can_pose_error(tilted, truth)[1] == pytest.approx(expected, abs=1e-6)


def test_visible_points_count_each_objects_returned_pixels():
    """truth objects' visible_points: the pixels that returned depth on that object; a can behind a
    taller box shows fewer than the same can alone."""
    from example_pcl.scene_objects import Obj

    can = Obj("can", 0.0, 0.1, radius=0.03, height=0.1)
    box = Obj("box", 0.0, 0.05, size=(0.12, 0.03, 0.12))
    scene = sc.generate_scene(exact(cans=[], objects=[can, box]))
    alone = sc.generate_scene(exact(cans=[], objects=[can]))
    returned = np.isfinite(scene.xyz[..., 2])
    counts = [o["visible_points"] for o in scene.truth["objects"]]
    assert counts == [int(np.count_nonzero(returned & (scene.labels == sc.LABEL_OBJECT + i))) for i in range(2)]
    assert 0 < counts[0] < alone.truth["objects"][0]["visible_points"]
