"""Tests of example_pcl.select_patch: selections from pixel rectangles and boxes."""
import numpy as np
import pytest

from example_pcl.errors import PerceptionError
from example_pcl.select_patch import parse_numbers, select_points


def grid():
    """A 4x5 organized cloud whose point (v, u) is (u, v, 1), with one NaN at (1, 1)."""
    v, u = np.mgrid[0:4, 0:5]
    xyz = np.stack([u, v, np.ones_like(u)], axis=-1).astype(np.float32)
    xyz[1, 1] = np.nan
    return xyz


def test_rect_is_inclusive_and_drops_nan():
    """A rectangle selects columns u0..u1 and rows v0..v1 inclusive, without the NaN points."""
    pts = select_points(grid(), rect=[1, 0, 2, 1])
    assert pts.dtype == np.float32 and pts.shape == (3, 3)
    assert {tuple(p[:2]) for p in pts} == {(1, 0), (2, 0), (2, 1)}


def test_rect_is_clipped_and_corners_sorted():
    """A rectangle beyond the image is clipped; its corners may come in any order."""
    assert len(select_points(grid(), rect="[10, 10, 3, 2]")) == 4
    assert len(select_points(grid(), rect=[-5, -5, 100, 100])) == 19


def test_box_selects_inside_points():
    """A box selects the finite points within its bounds (inclusive), any cloud shape."""
    pts = select_points(grid().reshape(-1, 3), box=[0.5, 0.5, 0, 2, 2, 2])
    assert {tuple(p[:2]) for p in pts} == {(2, 1), (1, 2), (2, 2)}


@pytest.mark.parametrize("kwargs", [dict(), dict(rect=[0, 0, 1, 1], box=[0] * 6), dict(rect=[0, 0, 1]),
                                    dict(box="[1, 2, x, 4, 5, 6]")])
def test_bad_requests(kwargs):
    """Neither or both of rect and box, or a wrong count of numbers, is a PerceptionError."""
    with pytest.raises(PerceptionError):
        select_points(grid(), **kwargs)


def test_rect_needs_an_organized_cloud():
    """A pixel rectangle of an unorganized cloud is refused."""
    with pytest.raises(PerceptionError, match="organized"):
        select_points(grid().reshape(-1, 3), rect=[0, 0, 1, 1])


def test_parse_numbers_accepts_lists_and_strings():
    """'[1, 2, 3, 4]', '1 2 3 4' and [1, 2, 3, 4] all parse."""
    for value in ("[1, 2, 3, 4]", "1 2 3 4", [1, 2, 3, 4], (1.0, 2, 3, 4)):
        assert parse_numbers(value, 4, "rect") == [1.0, 2.0, 3.0, 4.0]
