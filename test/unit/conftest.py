"""Lets the pure-Python unit tests import example_pcl from this checkout without a catkin workspace.

The source tree is appended (not prepended) to sys.path, so a sourced devel space, whose
example_pcl package also holds the compiled _native extension, still comes first.
"""
import pathlib
import sys
from concurrent.futures import Future

import pytest

_SRC = str(pathlib.Path(__file__).resolve().parents[2] / "src")
if _SRC not in sys.path:
    sys.path.append(_SRC)


class ManualExecutor:
    """An executor whose submitted calls run only when the test says (run): a search "in the
    background" finishes exactly where the test wants it to."""

    def __init__(self):
        self.calls = []  # (future, function, args) not run yet

    def submit(self, function, *args):
        future = Future()
        self.calls.append((future, function, args))
        return future

    def run(self):
        for future, function, args in self.calls:
            try:
                future.set_result(function(*args))
            except Exception as e:  # noqa: BLE001 - handed over, as an executor does
                future.set_exception(e)
        self.calls = []


@pytest.fixture
def manual_executor():
    return ManualExecutor()
