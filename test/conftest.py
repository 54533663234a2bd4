"""Fixtures shared by the unit and integration tests."""
import pathlib

import pytest

PROJECT = pathlib.Path(__file__).resolve().parent.parent
SHARED_DATA = PROJECT.parent / "shared" / "data"


@pytest.fixture
def shared_pcd():
    """Path of one of PCL's own test PCD files in ../shared/data, or a skip saying why."""

    def get(name):
        path = SHARED_DATA / name
        if not path.is_file():
            pytest.skip(f"{path} is absent: PCL's real test clouds live in ../shared/data beside the checkout")
        return path

    return get
