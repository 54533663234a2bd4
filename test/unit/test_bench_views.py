"""bench/bench_views.py: the views of a scene and what the cans found get wrong against its labels."""
import pathlib
import sys
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "bench"))
import bench_views  # noqa: E402


def test_sixteen_views_keep_each_point_with_its_label():
    """Four turns at four grid offsets; in each, a pixel keeps its label, and x and y are negated as
    the turn says (mirrored: x; upside down: x and y; columns reversed: neither)."""
    xyz = np.random.default_rng(1).normal(size=(4, 6, 3)).astype(np.float32)
    labels = np.arange(24).reshape(4, 6) * 10
    cloud = SimpleNamespace(xyz=xyz, points={"label": labels})
    seen = list(bench_views.views(cloud))
    assert len(seen) == 16 and len({name for name, _, _ in seen}) == 16
    for name, view, lab in seen:
        sign = np.array(next(s for turn, (_, s) in bench_views.TURNS.items() if name.startswith(turn + "offset")))
        np.testing.assert_array_equal(view / sign, xyz.reshape(-1, 3)[lab.reshape(-1)].reshape(view.shape))
    assert seen[0][1].shape == (4, 6, 3) and seen[3][1].shape == (3, 5, 3)


def test_wrong_names_the_cans_that_differ_from_the_labels():
    labels = np.array([2, 2, 2, 3, 3, 4])
    objects = [{"label": 2, "kind": "can"}, {"label": 3, "kind": "lying_can"}, {"label": 4, "kind": "box"}]

    def can(indices, lying=False):
        return SimpleNamespace(indices=np.array(indices), lying=lying)

    assert bench_views.wrong(SimpleNamespace(cans=[can([0, 1, 3]), can([3, 4], True)]), labels, objects) == ""
    assert bench_views.wrong(SimpleNamespace(cans=[can([0, 1]), can([5])]), labels, objects) == \
        "cans [2, 4] for [2]; lying cans none for [3]"


def test_degraded_scenes_drop_pixels_or_move_them_along_their_rays():
    """5 % or 20 % of the pixels dropped (NaN), the rest untouched; or every pixel moved along its ray
    by noise of about the asked multiple of sigma (noise_coefficient x z^2)."""
    xyz = np.zeros((200, 300, 3), np.float32)
    xyz[..., 0], xyz[..., 2] = 0.1, 1.0
    cloud = SimpleNamespace(xyz=xyz)
    out = dict(bench_views.degraded(cloud, 1, 0.002))
    assert list(out) == [f"{name}, draw 0" for name in bench_views.DEGRADED]
    for name, fraction in (("5 % dropped", 0.05), ("20 % dropped", 0.2)):
        lost = np.isnan(out[f"{name}, draw 0"][..., 2])
        assert abs(lost.mean() - fraction) < 0.01
        np.testing.assert_array_equal(out[f"{name}, draw 0"][~lost], xyz[~lost])
    for name, sigmas in (("noise +0.5 sigma", 0.5), ("noise +1 sigma", 1.0)):
        moved = out[f"{name}, draw 0"]
        assert abs(np.std(moved[..., 2] - 1.0) - sigmas * 0.002) < 0.05 * sigmas * 0.002
        np.testing.assert_allclose(moved[..., 0] / moved[..., 2], 0.1, rtol=1e-5)  # along the ray
