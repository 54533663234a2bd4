"""Tests of example_pcl.find_can_client's pure part: the walkthrough's patches on the bundled scene."""
import json
import pathlib

from example_pcl.find_can_client import CAN_RECT, TABLE_RECT

DATA = pathlib.Path(__file__).resolve().parents[2] / "data"


def test_rects_select_table_and_can_in_the_bundled_scene():
    """The walkthrough's table rectangle sees only the table and its can rectangle only the can's side
    (the bundled scene, regenerated from its spec)."""
    from example_pcl import scene as sc

    spec = json.loads((DATA / "test_pcd.json").read_text())["spec"]
    spec = sc.SceneSpec(**{**spec, "cans": [tuple(c) for c in spec["cans"]], "boxes": [],
                           "table_size": tuple(spec["table_size"])})
    labels = sc.generate_scene(spec).labels
    u0, v0, u1, v1 = TABLE_RECT
    assert (labels[v0:v1 + 1, u0:u1 + 1] == sc.LABEL_TABLE).all()
    u0, v0, u1, v1 = CAN_RECT
    assert (labels[v0:v1 + 1, u0:u1 + 1] == sc.LABEL_CAN_SIDE).all()
