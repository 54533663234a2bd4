#!/usr/bin/python3
"""Time per real frame of find_cans beside the finder as it was when issue 13 was filed, in one run.

The issue's time targets (median <= 20 ms, p90 <= 33 ms per 640x480 frame) were set against that
finder's 16.5 / 29 ms on the day it was filed; this machine's speed varies by up to twice from day
to day, so the targets are judged as ratios to that finder measured beside it: 20 / 16.5 = 1.21 at the
median, 33 / 29 = 1.14 at the p90. The filed revision (FILED, the commit before can_search landed) is
exported with `git archive` into build/filed-REV and built there by its own Makefile, unless
--filed-setup names the setup.bash of a build of it. Each finder runs in its own process
(finder_worker.py); they search the real scenes of ../shared/data/osd in turn, one at a time,
alternating which goes first, `--repeats` times. Prints a markdown table and writes it into
docs/can_search.md between <!-- bench:filed --> markers.
"""
import argparse
import json
import pathlib
import statistics
import subprocess
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_cans import DOC, OBJECTS, OSD  # noqa: E402
from common import PROJECT, machine_line, table, write_section  # noqa: E402

FILED = "c258b07"  # main when issue 13 was filed: find_cans was the issue 5 finder
TARGET = {"median": (20.0, 16.5), "p90": (33.0, 29.0)}  # ms: the target and the filed finder's time


def build_filed(rev):
    """The setup.bash of a build of revision `rev` in build/filed-REV (exported and built if missing)."""
    where = PROJECT / "build" / f"filed-{rev}"
    setup = where / "build" / "ws" / "devel" / "setup.bash"
    if not setup.exists():
        where.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(["git", "-C", str(PROJECT), "archive", rev], stdout=subprocess.PIPE, check=True)
        subprocess.run(["tar", "-x", "-C", str(where)], input=archive.stdout, check=True)
        print(f"building {rev} in {where} ...", flush=True)
        subprocess.run(["make", "-C", str(where), "build"], check=True)
    return setup


def start(setup, names):
    """A finder_worker.py process on the build whose setup.bash is `setup`, once it is ready."""
    command = f'source "{setup}" && exec /usr/bin/python3 "$0" "$1" "$2"'
    proc = subprocess.Popen(["bash", "-c", command, str(HERE / "finder_worker.py"), json.dumps(names), str(OSD)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    if proc.stdout.readline().strip() != "ready":
        raise SystemExit(f"the finder of {setup} did not start")
    return proc


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5, help="searches per real scene and finder")
    parser.add_argument("--filed-setup", help="setup.bash of a build of the filed revision (default: build it)")
    parser.add_argument("--print-only", action="store_true", help="print only, do not write docs/can_search.md")
    args = parser.parse_args()
    if not OSD.is_dir():
        raise SystemExit(f"no real scenes: {OSD} is absent")
    names = sorted(json.loads(OBJECTS.read_text())["scenes"])
    setups = {f"the finder as issue 13 was filed ({FILED})": pathlib.Path(args.filed_setup or build_filed(FILED)),
              "find_cans (this checkout)": PROJECT / "build" / "ws" / "devel" / "setup.bash"}
    procs = {label: start(setup, names) for label, setup in setups.items()}
    times = {label: [] for label in procs}
    for repeat in range(args.repeats):
        for i in range(len(names)):
            order = list(procs) if (repeat + i) % 2 == 0 else list(procs)[::-1]
            for label in order:
                procs[label].stdin.write(f"{i}\n")
                procs[label].stdin.flush()
                times[label].append(float(procs[label].stdout.readline().split()[0]))
    for proc in procs.values():
        proc.stdin.close()
        proc.wait()
    filed, now = (times[label] for label in procs)
    ratio = {"median": statistics.median(now) / statistics.median(filed),
             "p90": float(np.percentile(now, 90) / np.percentile(filed, 90))}
    rows = [[label, f"{1e3 * statistics.median(t):.1f}", f"{1e3 * np.percentile(t, 90):.1f}"]
            for label, t in times.items()]
    rows.append(["ratio", f"{ratio['median']:.2f}", f"{ratio['p90']:.2f}"])
    rows.append(["ratio the targets allow", *(f"{goal / then:.2f}" for goal, then in TARGET.values())])
    text = (table(["finder", "time per real frame, median (ms)", "p90 (ms)"], rows)
            + f"\n\n{len(names)} real scenes x {args.repeats} searches each; {machine_line()}.")
    print(text)
    if not args.print_only:
        write_section(DOC, "filed", text)


if __name__ == "__main__":
    main()
