"""bench/bench_cans.py's scoring: how found cans are matched with the truth."""
import pathlib
import sys
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "bench"))
import bench_cans  # noqa: E402


def upright(x, y, base_height, height):
    return SimpleNamespace(base_center=np.array([x, y, base_height]), axis=np.array([0.0, 0.0, 1.0]),
                           height=height, lying=False)


def test_stacked_cans_on_one_axis_are_matched_by_their_base_heights():
    """A can on a can: both found on nearly one axis. The upper one, scored first, lies horizontally
    nearer the lower truth; matched by the base's height too, each found can is its own truth's."""
    truth = [{"center": np.array([0.0, 0.0]), "radius": 0.04, "support_height": 0.0, "top": 0.09},
             {"center": np.array([0.001, 0.0]), "radius": 0.03, "support_height": 0.09, "top": 0.2}]
    tally = bench_cans.Tally()
    bench_cans.score(tally, [upright(0.0002, 0.0, 0.089, 0.11), upright(0.0, 0.0, 0.0, 0.09)], truth, [],
                     np.eye(4), 0.015)
    assert (tally.found, tally.missed, tally.false) == (2, 0, 0)
    np.testing.assert_allclose(sorted(tally.top_errors), [0.0, 0.001], atol=1e-9)


def test_a_can_reported_twice_counts_once_and_once_false():
    truth = [{"center": np.array([0.0, 0.0]), "radius": 0.04, "support_height": 0.0, "top": 0.1}]
    tally = bench_cans.Tally()
    bench_cans.score(tally, [upright(0.0, 0.0, 0.0, 0.1), upright(0.001, 0.0, 0.0, 0.1)], truth, [], np.eye(4), 0.015)
    assert (tally.found, tally.missed, tally.false) == (1, 0, 1)
