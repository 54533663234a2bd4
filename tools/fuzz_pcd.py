#!/usr/bin/python3
"""The long fuzzing run of the PCD reader: test/unit/test_pcd_fuzz.py with many more examples.

    source build/ws/devel/setup.bash && tools/fuzz_pcd.py [--examples 50000]

Runs in a child process, so a crash in PCL is reported (with the damaged file that caused it,
left in the fuzzer's temporary directory) instead of taking this script down. A hang is caught
by --timeout.
"""
import argparse
import os
import pathlib
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", type=int, default=50000, help="damaged files to try")
    parser.add_argument("--timeout", type=float, default=3600, help="seconds before the run counts as hung")
    args = parser.parse_args()
    env = dict(os.environ, PCD_FUZZ_EXAMPLES=str(args.examples))
    start = time.monotonic()
    try:
        proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                               str(ROOT / "test/unit/test_pcd_fuzz.py::test_damaged_files_never_crash")],
                              env=env, timeout=args.timeout)
    except subprocess.TimeoutExpired:
        print(f"fuzz_pcd: HUNG after {args.timeout:.0f} s (the input is the newest /tmp/pcd_fuzz_*/fuzz.pcd)")
        return 1
    elapsed = time.monotonic() - start
    if proc.returncode < 0:
        print(f"fuzz_pcd: the reader CRASHED (signal {-proc.returncode}); reproducer: newest /tmp/pcd_fuzz_*/fuzz.pcd")
        return 1
    verdict = "no crash, no hang, every rejected file a PerceptionError" if proc.returncode == 0 else "FAILURES above"
    print(f"fuzz_pcd: {args.examples} damaged files in {elapsed:.0f} s: {verdict}")
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
