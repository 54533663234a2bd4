"""bench/bench_filed.py: its finder process answers with one search's time and cans."""
import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "bench"))
import bench_filed  # noqa: E402

SETUP = bench_filed.PROJECT / "build" / "ws" / "devel" / "setup.bash"


@pytest.mark.skipif(not bench_filed.OSD.is_dir(), reason="../shared/data/osd (the real scenes) is absent")
@pytest.mark.skipif(not SETUP.exists(), reason="this checkout is not built in build/ws (make build)")
def test_a_finder_process_times_the_scene_it_is_asked_for():
    """learn43 holds one upright and one lying can: its time is a search's and it reports both."""
    proc = bench_filed.start(SETUP, ["learn9", "learn43"])
    try:
        proc.stdin.write("1\n")
        proc.stdin.flush()
        seconds, cans = proc.stdout.readline().split()
    finally:
        proc.stdin.close()
        proc.wait(timeout=30)
    assert 0.0 < float(seconds) < 10.0 and int(cans) == 2
    assert proc.returncode == 0
