"""Lets the pure-Python unit tests import example_pcl from this checkout without a catkin workspace.

The source tree is appended (not prepended) to sys.path, so a sourced devel space, whose
example_pcl package also holds the compiled _native extension, still comes first.
"""
import pathlib
import sys

_SRC = str(pathlib.Path(__file__).resolve().parents[2] / "src")
if _SRC not in sys.path:
    sys.path.append(_SRC)
