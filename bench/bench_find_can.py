#!/usr/bin/python3
"""find_can's modes 0 -> 3 on 640x480 scenes: compute time of the node's classes, and the service round-trip.

Compute: CanFinder (what find_can's service callback runs) called directly on the bundled scene and
two generated ones, per mode and in total (median over repeats; the budget is one Kinect frame
period, 33 ms). Round-trip: a find_can node on the bundled scene (its own roscore on a free port),
each process_mode call timed from the client's rospy.ServiceProxy: compute, publishing the results
and the ROS transport. Run `bench/bench_find_can.py [--repeats N] [--print-only]`; without
--print-only the table goes into docs/benchmarks.md between <!-- bench:find_can --> markers.
"""
import argparse
import os
import pathlib
import signal
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from common import PROJECT, free_port, machine_line, table, write_figures  # noqa: E402

sys.path.insert(0, str(PROJECT / "tools"))
from netns_graph import stop_process  # noqa: E402

from example_pcl import scene as sc  # noqa: E402
from example_pcl.can_finder import CanFinder, Mode  # noqa: E402

STEPS = [m for m in Mode if m != Mode.FIND_CAN_AUTO]  # the operator walkthrough, modes 0-3
from example_pcl.find_can_client import CAN_RECT, TABLE_RECT  # noqa: E402
from example_pcl.pcd import read_pcd  # noqa: E402
from example_pcl.select_patch import select_points  # noqa: E402

BUDGET = 0.033  # s: one frame period of a 30 Hz Kinect


def label_rect(labels, label, qv, qu, half):
    vs, us = np.nonzero(labels == label)
    v, u = int(np.quantile(vs, qv)), int(np.quantile(us, qu))
    return (u - half, v - half, u + half, v + half)


def scenes():
    """(name, xyz, table rect, can rect) of the bundled scene and two generated ones."""
    bundled = np.ascontiguousarray(read_pcd(str(PROJECT / "data" / "test_pcd.pcd")).xyz)
    out = [("bundled (1.0 m, tilt 0.9)", bundled, TABLE_RECT, CAN_RECT)]
    for distance, tilt in ((0.6, 1.2), (1.5, 0.7)):
        s = sc.generate_scene(sc.SceneSpec(camera_distance=distance, tilt=tilt, seed=7))
        out.append((f"generated ({distance} m, tilt {tilt})", s.xyz,
                    label_rect(s.labels, sc.LABEL_TABLE, 0.8, 0.2, 6), label_rect(s.labels, sc.LABEL_CAN_SIDE, 0.5, 0.5, 3)))
    return out


def time_modes(xyz, table_rect, can_rect, repeats):
    """Median seconds of each mode and of their sum over `repeats` walkthroughs (after one warm-up),
    and the last walkthrough's mode 3 message."""
    table_patch = select_points(xyz, rect=table_rect)
    can_patch = select_points(xyz, rect=can_rect)
    per_mode, totals, message = {m: [] for m in STEPS}, [], ""
    for i in range(repeats + 1):
        finder = CanFinder(xyz)
        finder.select(table_patch)
        times = {}
        for mode in STEPS:
            if mode == Mode.COMPUTE_CYLINDRICAL_FIT_ERR_INIT:
                finder.select(can_patch)
            start = time.perf_counter()
            result = finder.process(mode)
            times[mode] = time.perf_counter() - start
        message = result.message
        if i == 0:
            continue  # warm-up
        for mode, t in times.items():
            per_mode[mode].append(t)
        totals.append(sum(times.values()))
    return {m: statistics.median(t) for m, t in per_mode.items()}, statistics.median(totals), message


def service_round_trips(repeats):
    """Median seconds of each process_mode round-trip to a find_can node on the bundled scene."""
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}",
               ROS_HOME=tempfile.mkdtemp(prefix="bench_find_can_"))
    os.environ.update(ROS_MASTER_URI=env["ROS_MASTER_URI"], ROS_HOME=env["ROS_HOME"])
    started = []
    try:
        started.append(subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL,
                                        start_new_session=True,
                                        stderr=subprocess.DEVNULL))
        import rosgraph

        deadline = time.monotonic() + 30
        while not rosgraph.is_master_online():
            if time.monotonic() > deadline:
                raise RuntimeError("roscore did not start")
            time.sleep(0.1)
        import roslib.packages

        node = roslib.packages.find_node("example_pcl", "find_can")[0]
        started.append(subprocess.Popen([sys.executable, node], env=env, stdout=subprocess.DEVNULL,
                                        start_new_session=True,
                                        stderr=subprocess.DEVNULL))
        import rospy

        from example_pcl.find_can_client import FindCanClient

        rospy.init_node("bench_find_can", anonymous=True, disable_signals=True)
        client = FindCanClient(timeout=60)
        xyz = np.ascontiguousarray(read_pcd(str(PROJECT / "data" / "test_pcd.pcd")).xyz)
        table_patch, can_patch = select_points(xyz, rect=TABLE_RECT), select_points(xyz, rect=CAN_RECT)
        per_mode = {m: [] for m in STEPS}
        for i in range(repeats + 1):
            client.select(table_patch)
            for mode in STEPS:
                if mode == Mode.COMPUTE_CYLINDRICAL_FIT_ERR_INIT:
                    client.select(can_patch)
                start = time.perf_counter()
                ok, message = client.call(int(mode))
                elapsed = time.perf_counter() - start
                if not ok:
                    raise RuntimeError(f"mode {int(mode)} failed: {message}")
                if i:
                    per_mode[mode].append(elapsed)
        rospy.signal_shutdown("bench done")
        return {m: statistics.median(t) for m, t in per_mode.items()}
    finally:
        for proc in reversed(started):
            stop_process(proc, signal.SIGINT, timeout=15)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=15, help="walkthroughs timed per scene (default %(default)s)")
    parser.add_argument("--no-service", action="store_true", help="skip the node's service round-trip")
    parser.add_argument("--print-only", action="store_true", help="print only; leave docs/benchmarks.md alone")
    args = parser.parse_args(argv)

    def ms(seconds):
        return f"{seconds * 1e3:.2f}"

    header = ["scene (640x480)", "mode 0 plane", "mode 1 above", "mode 2 init", "mode 3 fit", "total (ms)"]
    rows, slowest = [], 0.0
    for name, xyz, table_rect, can_rect in scenes():
        modes, total, message = time_modes(xyz, table_rect, can_rect, args.repeats)
        slowest = max(slowest, total)
        rows.append([f"{name}: CanFinder compute"] + [ms(modes[m]) for m in STEPS] + [f"**{ms(total)}**"])
        print(f"{name}: {message}", file=sys.stderr)
    if not args.no_service:
        trips = service_round_trips(args.repeats)
        rows.append(["bundled: process_mode service round-trip"] + [ms(trips[m]) for m in STEPS]
                    + [ms(sum(trips.values()))])
    verdict = "within" if slowest <= BUDGET else "OVER"
    text = "\n".join([
        f"find_can, modes 0 -> 3 (median of {args.repeats} walkthroughs; ms). Compute is {verdict} one Kinect "
        f"frame period (33 ms) on every scene. The round-trip adds publishing the results (mode 0 publishes "
        "the table's ~200k inliers) and the ROS transport.",
        "",
        table(header, rows),
        "",
        f"Command: `bench/bench_find_can.py`. Machine: {machine_line()}",
    ])
    print(text)
    if not args.print_only:
        write_figures("find_can", text)
    return 0 if slowest <= BUDGET else 1


if __name__ == "__main__":
    sys.exit(main())
