"""Tests of example_pcl.demo's pure parts: the pose error and the picture."""
import json
import pathlib

import numpy as np
import pytest

from example_pcl import demo, geometry
from example_pcl.messages import pose_message

DATA = pathlib.Path(__file__).resolve().parents[2] / "data"


def test_pose_error_against_truth():
    """pose_error gives the centre distance (m) and the axis angle (deg) from a ground-truth can."""
    truth = {"base_center": [0.0, 0.0, 1.0], "axis": [0.0, -0.6216099682706644, -0.7833269096274834]}
    T = geometry.plane_frame(truth["axis"], np.array(truth["base_center"]) + (0.003, 0.0, 0.004))
    centre, axis = demo.pose_error(pose_message(T, "world"), truth)
    assert centre == pytest.approx(0.005, abs=1e-9) and axis == pytest.approx(0.0, abs=1e-5)
    tilted = geometry.plane_frame((0.0, -0.7, -0.7), truth["base_center"])
    expected = np.degrees(np.arccos(np.dot(np.array([0.0, -0.7, -0.7]) / np.sqrt(0.98), truth["axis"])))
    assert demo.pose_error(pose_message(tilted, "world"), truth)[1] == pytest.approx(expected, abs=1e-6)


def test_rects_select_table_and_can_in_the_bundled_scene():
    """The demo's table rectangle sees only the table and its can rectangle only the can's side
    (the bundled scene, regenerated from its spec)."""
    from example_pcl import scene as sc

    spec = json.loads((DATA / "test_pcd.json").read_text())["spec"]
    spec = sc.SceneSpec(**{**spec, "cans": [tuple(c) for c in spec["cans"]], "boxes": [],
                           "table_size": tuple(spec["table_size"])})
    labels = sc.generate_scene(spec).labels
    u0, v0, u1, v1 = demo.TABLE_RECT
    assert (labels[v0:v1 + 1, u0:u1 + 1] == sc.LABEL_TABLE).all()
    u0, v0, u1, v1 = demo.CAN_RECT
    assert (labels[v0:v1 + 1, u0:u1 + 1] == sc.LABEL_CAN_SIDE).all()


def test_write_picture(tmp_path):
    """write_picture writes a PNG of the scene with the plane and model overlaid."""
    z = np.linspace(0.8, 2.0, 48 * 64).reshape(48, 64)
    v, u = np.mgrid[0:48, 0:64]
    xyz = np.stack([(u - 31.5) * z / 525, (v - 23.5) * z / 525, z], axis=-1).astype(np.float32)
    path = demo.write_picture(tmp_path / "sub" / "out.png", xyz, xyz[30:, :].reshape(-1, 3),
                              xyz[10:12, 10:12].reshape(-1, 3), "title")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
