"""Fixtures of the integration tests."""
import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from graph_helpers import RosGraph  # noqa: E402


@pytest.fixture
def ros_graph(tmp_path):
    """A private roscore (free port) with helpers to start nodes against it."""
    graph = RosGraph(tmp_path)
    yield graph
    graph.close()
