#!/usr/bin/python3
"""The real mOSD scenes in sixteen views and with several search seeds (issue 13): where the cans
found differ from the labels.

A view is the scene at one of the four offsets of the search's every-2nd-pixel grid, as it is,
mirrored (x negated, columns reversed: the same table seen in a mirror), upside down (x and y
negated, rows and columns reversed: the camera turned about its axis) or with its columns in reverse
order (the same points; the order the search draws them in changes). Which pixels the search sees and
which hypotheses it draws first change what it finds at the margins. A view is right when every
labelled can is found upright and every lying one lying, each on that object's points (the label
most of its points carry), and nothing else. The scenes degraded too (search seed 0): a fraction
of the pixels dropped at random (no return), or depth noise added along each pixel's ray (a multiple
of the sensor's sigma, noise_coefficient x range^2), each in `--draws` random draws. Prints a
markdown table (the views, seeds and degraded draws that are not right, per scene) and writes it
into docs/can_search.md between <!-- bench:views --> markers.
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


def object_labels(cloud):
    """Each pixel's object (int (H, W)) from a labelled scene's labels (pcd.PointCloud): label // 10."""
    return cloud.points["label"].astype(int) // 10


def views(cloud, turns=tuple(TURNS)):
    """(name, xyz (H, W, 3) float32, object labels (H, W)) of the scene (a pcd.PointCloud with labels)
    in each of `turns` (TURNS' names) at each of the grid's four offsets."""
    labels = object_labels(cloud)
    for name in turns:
        order, sign = TURNS[name]
        xyz, lab = cloud.xyz[order] * np.array(sign, np.float32), labels[order]
        for dy, dx in ((0, 0), (0, 1), (1, 0), (1, 1)):
            yield f"{name}offset {dy},{dx}", np.ascontiguousarray(xyz[dy:, dx:]), lab[dy:, dx:]


# name: (fraction of the pixels dropped, depth noise added in the sensor's sigmas)
DEGRADED = {"5 % dropped": (0.05, 0.0), "20 % dropped": (0.2, 0.0), "noise +0.5 sigma": (0.0, 0.5),
            "noise +1 sigma": (0.0, 1.0)}


def degraded(cloud, draws, noise_coefficient):
    """(name, xyz (H, W, 3) float32) of the scene with each of DEGRADED's degradations, `draws` random
    draws of each; noise_coefficient: the sensor's sigma over the squared range (1/m)."""
    for name, (dropped, sigmas) in DEGRADED.items():
        for draw in range(draws):
            rng = np.random.default_rng(draw)
            xyz = cloud.xyz.astype(np.float64)
            # Along the ray: the depth error is the range's, sigma = noise_coefficient x z^2.
            xyz *= 1.0 + sigmas * noise_coefficient * xyz[..., 2:] * rng.standard_normal(xyz.shape[:2] + (1,))
            xyz[rng.random(xyz.shape[:2]) < dropped] = np.nan
            yield f"{name}, draw {draw}", xyz.astype(np.float32)


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
    p.add_argument("--draws", type=int, default=3, help="random draws of each degradation")
    p.add_argument("--print-only", action="store_true", help="print only, do not write docs/can_search.md")
    args = p.parse_args(argv)
    if not OSD.is_dir():
        raise SystemExit(f"the real mOSD scenes are absent ({OSD})")
    scenes = json.loads(OBJECTS.read_text())["scenes"]
    rows, counts = [], {"views": [0, 0], "degraded": [0, 0]}  # runs, right
    for name in sorted(scenes, key=lambda n: int(n[5:])):
        cloud = read_pcd(str(OSD / f"{name}.pcd"))
        bad = {}

        def judge(kind, where, result, labels):
            why = wrong(result, labels, scenes[name])
            counts[kind][0] += 1
            counts[kind][1] += not why
            if why:
                bad.setdefault(why, []).append(where)

        for seed in args.seeds:
            config = af.AutoConfig(cylinders=cs.CylinderSearchConfig(seed=seed))
            for view, xyz, labels in views(cloud):
                judge("views", f"{view} seed {seed}", af.find_cans(xyz, viewpoint=cloud.origin, config=config), labels)
        labels = object_labels(cloud)
        for what, xyz in degraded(cloud, args.draws, af.AutoConfig().noise_coefficient):
            judge("degraded", what, af.find_cans(xyz, viewpoint=cloud.origin), labels)
        for why, where in bad.items():
            shown = ", ".join(where[:3]) + (f" and {len(where) - 3} more" if len(where) > 3 else "")
            rows.append([name, len(where), why, shown])
    (views_run, views_right), (degraded_run, degraded_right) = counts["views"], counts["degraded"]
    text = (f"`bench/bench_views.py` (seeds {', '.join(map(str, args.seeds))}; {args.draws} draws), "
            f"{machine_line()}\n\n"
            f"{views_right} of {views_run} views and seeds right ({len(scenes)} scenes, {len(TURNS) * 4} views, "
            f"{len(args.seeds)} seeds); {degraded_right} of {degraded_run} degraded scenes right "
            f"({', '.join(DEGRADED)}); those that are not:\n\n"
            + table(["scene", "runs", "found", "where"], rows or [["-", 0, "-", "-"]]))
    print(text)
    if not args.print_only:
        write_section(DOC, "views", text)


if __name__ == "__main__":
    main()
