"""Fuzzing the PCD reader (a short bounded run; tools/fuzz_pcd.py runs the long one)."""
import os
import pathlib
import sys
import tempfile

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from fuzz.pcd_mutations import apply, mutations, seed_files  # noqa: E402

from example_pcl import pcd  # noqa: E402
from example_pcl.errors import PerceptionError  # noqa: E402

WORK = pathlib.Path(tempfile.mkdtemp(prefix="pcd_fuzz_"))
EXAMPLES = int(os.environ.get("PCD_FUZZ_EXAMPLES", "400"))  # tools/fuzz_pcd.py raises it
SEEDS = seed_files(WORK)


def read_checked(path):
    """Reads a possibly damaged file: either a consistent cloud or a PerceptionError naming the file."""
    try:
        cloud = pcd.read_pcd(path)
    except PerceptionError as e:
        assert path.name in str(e)
        return None
    assert cloud.points.dtype.itemsize > 0
    assert cloud.points.ndim in (1, 2)
    return cloud


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow], database=None)
@given(seed=st.integers(0, len(SEEDS) - 1), steps=mutations)
def test_damaged_files_never_crash(seed, steps):
    """A damaged PCD file (truncated, flipped, forged header or sizes) reads consistently or raises PerceptionError."""
    data = SEEDS[seed]
    for step in steps:
        data = apply(data, step)
    path = WORK / "fuzz.pcd"  # left behind as the reproducer if the reader ever crashes
    path.write_bytes(data)
    read_checked(path)


@pytest.mark.parametrize("index", range(len(SEEDS)))
def test_seeds_are_valid(index):
    """Every seed reads without error, so the mutations start from valid files."""
    path = WORK / f"seed{index}.pcd"
    path.write_bytes(SEEDS[index])
    assert read_checked(path) is not None
