"""Runs each rostest launch file of test/integration (its test nodes beside it) as one pytest test."""
import os
import pathlib
import shutil
import subprocess

import pytest

HERE = pathlib.Path(__file__).resolve().parent
LAUNCH_FILES = sorted(HERE.glob("*.test"))


@pytest.mark.skipif(shutil.which("rostest") is None, reason="rostest not on PATH: source the devel space (make test does)")
@pytest.mark.parametrize("launch", LAUNCH_FILES, ids=[p.stem for p in LAUNCH_FILES])
def test_rostest(launch, tmp_path):
    """Every test node in the rostest launch file reports success."""
    env = dict(os.environ, ROS_HOME=str(tmp_path / "ros_home"), ROS_LOG_DIR=str(tmp_path / "log"))
    proc = subprocess.run(["rostest", "--text", str(launch)], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=900)
    # rostest exits 0 when a test node dies before reporting; only its summary line is proof.
    passed = proc.returncode == 0 and "* RESULT: SUCCESS" in proc.stdout
    assert passed, f"rostest {launch.name} failed:\n{proc.stdout[-6000:]}"
