#!/usr/bin/python3
"""Per-frame cost of tracking (issue 12): the local refit (example_pcl.local_fit) beside the full
search (auto_finder.find_cans) on the same frames, and the tracker's smoothing.

Frames: the default generated moving sequence (example_pcl.scene_sequence: 30 frames of 640x480,
camera drifting, 2-3 cans, one added, one moved, one removed), rendered once and cached. Each
frame is processed by LocalFinder (refit where it holds, full search where it does not, with
search_period as given) and, separately, by find_cans alone; every figure is the median over the
frames of the stage's wall time (ms). Jitter: per-axis std (mm) of the static can's base centre
in the table frame, raw detections vs. CanTracker's output; error: max distance (mm) of any
tracked can from the truth. Run `bench/bench_tracking.py [--repeats N] [--search-period P]`.
"""
import argparse
import statistics
import time

import numpy as np

from common import machine_line

from example_pcl import auto_finder as af
from example_pcl import local_fit as lf
from example_pcl import scene_sequence as ss
from example_pcl import tracking as tr


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--repeats", type=int, default=3, help="passes over the sequence (default %(default)s)")
    p.add_argument("--search-period", type=int, default=30, help="frames (default %(default)s)")
    args = p.parse_args()
    spec = ss.SequenceSpec()
    frames = ss.render_sequence(spec)
    stages = {}
    full = []
    raw, tracked, errors = [], [], []
    for repeat in range(args.repeats):
        finder = lf.LocalFinder(lf.LocalFitConfig(search_period=args.search_period))
        tracker = tr.CanTracker()
        for f in frames:
            result = finder.process(f.xyz)
            t = time.perf_counter()
            update = tracker.update(result.cans, f.stamp)
            track_time = time.perf_counter() - t
            key = "search frames" if result.searched else "local frames"
            for stage, seconds in result.timings.items():
                stages.setdefault((key, stage), []).append(1e3 * seconds)
            stages.setdefault((key, "tracker"), []).append(1e3 * track_time)
            t = time.perf_counter()
            af.find_cans(f.xyz)
            full.append(1e3 * (time.perf_counter() - t))
            if repeat == 0:
                T = np.linalg.inv(np.asarray(f.truth["camera_from_table"]))
                static = np.asarray(f.truth["cans"][0]["base_center"])
                det = min(result.cans, key=lambda c: np.linalg.norm(c.base_center - static))
                track = min(update.tracks, key=lambda c: np.linalg.norm(c.base_center - static))
                raw.append(T[:3, :3] @ det.base_center + T[:3, 3])
                tracked.append(T[:3, :3] @ track.base_center + T[:3, 3])
                for truth in f.truth["cans"]:
                    seen = [c for c in update.tracks if c.seen]
                    errors.append(min(np.linalg.norm(c.base_center - truth["base_center"]) for c in seen))
    print(f"# tracking bench: {len(frames)} frames x {args.repeats}, search_period {args.search_period}")
    print(f"# {machine_line()}")
    print(f"{'frames':<14} {'stage':<8} {'median ms':>10} {'p90 ms':>8} {'n':>4}")
    for (key, stage), values in sorted(stages.items()):
        print(f"{key:<14} {stage:<8} {statistics.median(values):>10.2f} {np.percentile(values, 90):>8.2f} "
              f"{len(values):>4}")
    print(f"{'find_cans':<14} {'total':<8} {statistics.median(full):>10.2f} {np.percentile(full, 90):>8.2f} "
          f"{len(full):>4}")
    print(f"static can jitter (per-axis std, table frame): detections "
          f"{1e3 * np.array(raw).std(axis=0).max():.3f} mm, tracked {1e3 * np.array(tracked).std(axis=0).max():.3f} mm")
    print(f"max tracked error against the truth: {1e3 * max(errors):.2f} mm")


if __name__ == "__main__":
    main()
