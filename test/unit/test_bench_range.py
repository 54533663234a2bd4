"""bench/bench_range.py: the cases with their camera moved, and how a distance's row reads."""
import dataclasses
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "bench"))
import bench_cans  # noqa: E402
import bench_range  # noqa: E402

from example_pcl import scene as sc  # noqa: E402
from example_pcl import scene_objects as so  # noqa: E402
from example_pcl import transforms  # noqa: E402


def test_spec_at_moves_only_the_camera():
    """The case's objects, pitch and heading stay; the camera stands `distance` from its aim point
    (the first object's base: the table origin)."""
    case = so.case_spec("can on tin", 7)
    moved = bench_range.spec_at("can on tin", 7, 1.6)
    assert moved.camera_distance == 1.6 and case.camera_distance != 1.6
    assert dataclasses.replace(moved, camera_distance=case.camera_distance) == case
    truth = sc.generate_scene(moved).truth
    camera_in_table = transforms.invert(np.asarray(truth["camera_from_table"]))[:3, 3]
    assert abs(np.linalg.norm(camera_in_table) - 1.6) < 1e-9


def test_a_row_gives_the_noise_there_and_names_the_scenes_not_right():
    total = bench_cans.Tally()
    total.found, total.missed, total.false, total.lying, total.lying_total = 9, 2, 1, 3, 4
    total.errors = [0.0001, 0.0002, 0.0009]
    wrong = [("cans touching", 3000), ("cup on can", 3001), ("lying can", 3002), ("can on box", 3003),
             ("can on can", 3004)]
    assert bench_range.row(1.0, total, wrong) == [
        "1.00", "1.4", "9", "2", "1", "3/4", "0.20",
        "cans touching 3000, cup on can 3001, lying can 3002, can on box 3003 and 1 more"]
    assert bench_range.row(0.5, bench_cans.Tally(), [])[1:] == ["0.4", "0", "0", "0", "0/0", "-", "-"]


def test_tally_at_scores_every_scene_of_the_cases_asked():
    """One lying can (development seed 0) at 1 m: found lying, nothing wrong; its upright can too."""
    total, wrong = bench_range.tally_at(1.0, [0], cases=("lying can",))
    assert (total.lying, total.lying_total, total.found, total.missed, total.false) == (1, 1, 1, 0, 0)
    assert wrong == []
