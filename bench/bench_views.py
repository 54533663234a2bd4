#!/usr/bin/python3
"""The real mOSD scenes in sixteen views and with several search seeds (issue 13): where the cans
found differ from the labels.

A view is the scene at one of the four offsets of the search's every-2nd-pixel grid, as it is,
mirrored (x negated, columns reversed: the same table seen in a mirror), upside down (x and y
negated, rows and columns reversed: the camera turned about its axis) or with its columns in reverse
order (the same points; the order the search draws them in changes). Which pixels the search sees and
which hypotheses it draws first change what it finds at the margins. A view is right when every
labelled can is found upright and every lying one lying, each on that object's points (the label
most of its points carry), and nothing else. Prints a markdown table (the views and seeds that are
not right, per scene) and writes it into docs/can_search.md between <!-- bench:views --> markers.
"""
import argparse
import json
import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_cans import DOC, OBJECTS, OSD  # noqa: E402
from common import machine_line, table, write_section  # noqa: E402

from example_pcl import auto_finder as af  # noqa: E402
from example_pcl import can_search as cs  # noqa: E402

# name: (the pixels' order, the sign of x, y, z)
TURNS = {"": (np.s_[:, :], (1, 1, 1)), "mirrored, ": (np.s_[:, ::-1], (-1, 1, 1)),
         "upside down, ": (np.s_[::-1, ::-1], (-1, -1, 1)), "columns reversed, ": (np.s_[:, ::-1], (1, 1, 1))}


def views(cloud, turns=tuple(TURNS)):
    """(name, xyz (H, W, 3) float32, object labels (H, W)) of the scene (a pcd.PointCloud with labels)
    in each of `turns` (TURNS' names) at each of the grid's four offsets."""
    labels = cloud.points["label"].astype(int) // 10
    for name in turns:
        order, sign = TURNS[name]
        xyz, lab = cloud.xyz[order] * np.array(sign, np.float32), labels[order]
        for dy, dx in ((0, 0), (0, 1), (1, 0), (1, 1)):
            yield f"{name}offset {dy},{dx}", np.ascontiguousarray(xyz[dy:, dx:]), lab[dy:, dx:]


def wrong(result, labels, objects):
    """What the cans found (an auto_finder result) get wrong against the labelled objects, or "":
    the labels of the upright and lying cans found (most of each one's points) against the truth's."""
    why = []
    for on_side, kind in ((False, "can"), (True, "lying_can")):
        owners = sorted(int(np.bincount(labels.reshape(-1)[c.indices]).argmax()) for c in result.cans
                        if c.lying == on_side)
        truth = sorted(o["label"] for o in objects if o["kind"] == kind)
        if owners != truth:
            why.append(f"{kind.replace('_', ' ')}s {owners or 'none'} for {truth or 'none'}")
    return "; ".join(why)


def main(argv=None):
    from example_pcl.pcd import read_pcd

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, nargs="+", default=list(range(6)), help="the search's seeds")
    p.add_argument("--print-only", action="store_true", help="print only, do not write docs/can_search.md")
    args = p.parse_args(argv)
    if not OSD.is_dir():
        raise SystemExit(f"the real mOSD scenes are absent ({OSD})")
    scenes = json.loads(OBJECTS.read_text())["scenes"]
    rows, runs, right = [], 0, 0
    for name in sorted(scenes, key=lambda n: int(n[5:])):
        cloud = read_pcd(str(OSD / f"{name}.pcd"))
        bad = {}
        for seed in args.seeds:
            config = af.AutoConfig(cylinders=cs.CylinderSearchConfig(seed=seed))
            for view, xyz, labels in views(cloud):
                why = wrong(af.find_cans(xyz, viewpoint=cloud.origin, config=config), labels, scenes[name])
                runs += 1
                right += not why
                if why:
                    bad.setdefault(why, []).append(f"{view} seed {seed}")
        for why, where in bad.items():
            shown = ", ".join(where[:3]) + (f" and {len(where) - 3} more" if len(where) > 3 else "")
            rows.append([name, len(where), why, shown])
    text = (f"`bench/bench_views.py` (seeds {', '.join(map(str, args.seeds))}), {machine_line()}\n\n"
            f"{right} of {runs} views and seeds right ({len(scenes)} scenes, {len(TURNS) * 4} views, "
            f"{len(args.seeds)} seeds); those that are not:\n\n"
            + table(["scene", "views and seeds", "found", "where"], rows or [["-", 0, "-", "-"]]))
    print(text)
    if not args.print_only:
        write_section(DOC, "views", text)


if __name__ == "__main__":
    main()
