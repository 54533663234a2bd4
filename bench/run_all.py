#!/usr/bin/python3
"""Every benchmark in one run; each one's table goes into docs/benchmarks.md (`make bench`)."""
import os
import pathlib
import subprocess
import sys

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from common import write_figures  # noqa: E402


def run(script, *args):
    """Runs a benchmark script on this interpreter, echoing and returning its output."""
    proc = subprocess.run([sys.executable, str(HERE / script), *args], stdout=subprocess.PIPE, text=True)
    print(proc.stdout)
    if proc.returncode != 0:
        raise SystemExit(f"{script} failed with exit code {proc.returncode}")
    return proc.stdout.strip()


def main():
    pcl_program = os.environ.get("PCD_IO_PCL", "")
    run("bench_core.py", *(["--pcl-program", pcl_program] if pcl_program else []))
    write_figures("pcd_save", run("pcd_save_rate.py"))
    if (HERE / "bench_find_can.py").exists():
        run("bench_find_can.py")
    run("bench_auto.py")  # writes its own section of docs/benchmarks.md (auto)
    run("bench_cans.py")  # writes its figures into docs/can_search.md
    run("bench_filed.py")  # builds the finder as issue 13 was filed; writes into docs/can_search.md
    run("bench_views.py")  # writes its figures into docs/can_search.md
    run("bench_range.py")  # writes its figures into docs/can_search.md
    run("bench_tracking.py")
    run("bench_tracker_stream.py")  # writes its figures into docs/can_tracker.md


if __name__ == "__main__":
    main()
