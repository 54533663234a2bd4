#!/usr/bin/python3
"""How far from the camera can_search holds: every case of example_pcl.scene_objects.CASES with its
camera moved to each of several distances, on held-out seeds (default 3000-3009).

A case's camera stands 0.7-1.3 m from its first object's base (scene_objects.case_spec); here only
that distance is replaced (pitch, heading and objects stay the case's). Scored as bench_cans scores
generated scenes (found / missed / false upright cans, lying cans reported lying), with the depth
noise sigma at that distance (the generator's, 1.425e-3 z^2). Prints a markdown table and writes it
into docs/can_search.md between <!-- bench:range --> markers.
"""
import argparse
import dataclasses
import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_cans  # noqa: E402
from common import machine_line, table, write_section  # noqa: E402

from example_pcl import auto_finder as af  # noqa: E402
from example_pcl import scene as sc  # noqa: E402
from example_pcl import scene_objects as so  # noqa: E402

DOC = HERE.parent / "docs" / "can_search.md"
NOISE = 1.425e-3  # the generator's depth noise: sigma = NOISE z^2 (m)


def spec_at(case, seed, distance):
    """The case's scene (scene_objects.case_spec) with its camera `distance` (m) from its aim point."""
    return dataclasses.replace(so.case_spec(case, seed), camera_distance=float(distance))


def tally_at(distance, seeds, cases=so.CASES):
    """A bench_cans.Tally of can_search on every case and seed with the camera at `distance` (m), and
    the (case, seed) of each scene not found right."""
    total, wrong = bench_cans.Tally(), []
    for case in cases:
        for seed in seeds:
            spec = spec_at(case, seed, distance)
            scene = sc.generate_scene(spec)
            to_plane, cans, lying = bench_cans.generated_truth(spec, scene)
            tally = bench_cans.Tally()
            bench_cans.score(tally, af.find_cans(scene.xyz).cans, cans, lying, to_plane, 0.015)
            total.add(tally)
            if tally.missed or tally.false or tally.lying < tally.lying_total:
                wrong.append((case, seed))
    return total, wrong


def row(distance, total, wrong):
    """The table's row for one camera distance (m): its tally and the scenes not right (tally_at)."""
    error = f"{1e3 * np.median(total.errors):.2f}" if total.errors else "-"
    where = ", ".join(f"{case} {seed}" for case, seed in wrong[:4]) + (f" and {len(wrong) - 4} more"
                                                                        if len(wrong) > 4 else "")
    return [f"{distance:.2f}", f"{1e3 * NOISE * distance ** 2:.1f}", str(total.found), str(total.missed),
            str(total.false), f"{total.lying}/{total.lying_total}", error, where or "-"]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--distances", type=float, nargs="+", default=[0.5, 0.7, 1.0, 1.3, 1.45, 1.6],
                   help="camera to the case's first object, m")
    p.add_argument("--seeds", type=int, nargs="+", default=list(range(3000, 3010)),
                   help="generator seeds (held out: development used 0-99 and 400-499)")
    p.add_argument("--print-only", action="store_true", help="print only, do not write docs/can_search.md")
    args = p.parse_args(argv)
    rows = [row(d, *tally_at(d, args.seeds)) for d in args.distances]
    header = ["camera distance (m)", "depth noise sigma there (mm)", "found", "missed", "false",
              "lying reported lying", "median centre error (mm)", "scenes not right (case seed)"]
    text = (f"`bench/bench_range.py` (seeds {args.seeds[0]}-{args.seeds[-1]}, every case), {machine_line()}\n\n"
            + table(header, rows))
    print(text)
    if not args.print_only:
        write_section(DOC, "range", text)


if __name__ == "__main__":
    main()
