"""Unit tests of example_pcl.scene_sequence: moving sequences with per-frame truth, and their cache
(pure NumPy, no ROS, no extension)."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from example_pcl import scene as sc
from example_pcl import scene_sequence as ss
from example_pcl.errors import PerceptionError


def test_can_path_eases_between_keyframes():
    """A can rests at each keyframe, is halfway at the midpoint, and holds the ends outside."""
    can = ss.SequenceCan(7, 0.03, 0.1, ((10, 0.0, 0.0), (20, 0.1, -0.02)))
    assert can.position(0) == (0.0, 0.0) and can.position(10) == (0.0, 0.0)
    assert_allclose(can.position(15), (0.05, -0.01))
    assert can.position(20) == pytest.approx((0.1, -0.02)) and can.position(99) == (0.1, -0.02)
    step = np.diff([can.position(f)[0] for f in (10, 10.01, 19.99, 20)])
    assert step[0] < 1e-6 and step[2] < 1e-6


def test_default_sequence_adds_moves_and_removes_a_can():
    """The default: can 0 all along, can 1 gone after frame 19, can 2 from frame 6; the camera drifts."""
    spec = ss.SequenceSpec()
    assert spec.truth_ids(0) == [0, 1] and spec.truth_ids(6) == [0, 1, 2] and spec.truth_ids(20) == [0, 2]
    first, last = spec.scene_spec(0), spec.scene_spec(spec.n_frames - 1)
    assert last.camera_distance > first.camera_distance and last.yaw > first.yaw and last.tilt > first.tilt
    assert last.cans[1][:2] != spec.scene_spec(12).cans[2][:2]
    assert spec.scene_spec(1).seed == spec.seed + 1


@pytest.mark.parametrize("kwargs,match", [
    ({"cans": [ss.SequenceCan(0, 0.03, 0.1, ((0, 0, 0),), first=2)]}, "aim"),
    ({"cans": [ss.SequenceCan(0, 0.03, 0.1, ((0, 0, 0),)), ss.SequenceCan(0, 0.03, 0.1, ((0, 0.2, 0),))]},
     "unique"),
    ({"cans": [ss.SequenceCan(0, 0.03, 0.1, ((5, 0, 0), (5, 0.1, 0)))]}, "increasing"),
    ({"rate": 0.0}, "rate")])
def test_bad_spec_raises(kwargs, match):
    with pytest.raises(PerceptionError, match=match):
        ss.SequenceSpec(**kwargs).validate()


TWO_FRAMES = ss.SequenceSpec(n_frames=2, yaw_step=0.05, cans=[
    ss.SequenceCan(4, 0.033, 0.122, ((0, 0.0, 0.0),)),
    ss.SequenceCan(9, 0.04, 0.1, ((0, 0.15, 0.05), (1, 0.17, 0.05)))])


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    cache = tmp_path_factory.mktemp("sequences")
    return cache, ss.render_sequence(TWO_FRAMES, cache_dir=cache, with_rgb=True)


def test_frames_carry_truth_with_stable_ids(rendered):
    """Each frame's truth names its cans by truth id, in the camera frame of that frame: the
    can's side points lie at its radius from its axis."""
    _, frames = rendered
    assert [f.stamp for f in frames] == [0.0, 1 / 30]
    for f in frames:
        assert f.xyz.shape == (sc.HEIGHT, sc.WIDTH, 3) and f.xyz.dtype == np.float32
        assert f.rgb.shape == (sc.HEIGHT, sc.WIDTH, 3)
        assert [c["id"] for c in f.truth["cans"]] == [4, 9]
        scene = sc.generate_scene(TWO_FRAMES.scene_spec(f.index))
        for k, truth in enumerate(f.truth["cans"]):
            side = f.xyz[scene.labels == sc.LABEL_CAN_SIDE + k]
            side = side[np.isfinite(side).all(axis=1)]
            r = np.linalg.norm(np.cross(side - truth["base_center"], truth["axis"]), axis=1)
            assert abs(np.median(r) - truth["radius"]) < 0.002
    moved = [np.asarray(f.truth["cans"][1]["base_center"]) for f in frames]
    assert np.linalg.norm(moved[1] - moved[0]) > 0.01, "the camera and can 9 moved"


def test_cache_round_trip(rendered, monkeypatch):
    """A second render of the same spec loads the cached frames (nothing rendered) unchanged."""
    cache, frames = rendered
    assert len(list(cache.glob("sequence_*.npz"))) == 1

    def no_render(*args, **kwargs):
        raise AssertionError("rendered although cached")

    monkeypatch.setattr(sc, "generate_scene", no_render)
    again = ss.render_sequence(TWO_FRAMES, cache_dir=cache, with_rgb=True)
    for a, b in zip(frames, again):
        np.testing.assert_array_equal(a.xyz, b.xyz)
        np.testing.assert_array_equal(a.rgb, b.rgb)
        assert a.truth == b.truth and a.stamp == b.stamp and a.index == b.index
