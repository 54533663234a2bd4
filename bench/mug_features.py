#!/usr/bin/python3
"""Upside-down mugs against cans (issue 13): does the depth data show the mug's foot?

An upside-down mug whose handle the sensor does not see is a closed cylinder of a can's size
(learn38's two, labels 2 and 3). A mug's foot has a rounded edge where the side meets the (now top)
bottom and a foot ring around a recessed middle; a can's top meets its side at a rim or a lid. This
measures, per object, from its points as the finder sees them (every `--step`-th pixel, each of the
step x step pixel offsets of that grid: min..max over them), against its circle (fitted to its
side points 2 cm above its base to 3 cm below its top) and its top (the 99th percentile of the
points on the outer ring, beyond 0.7 r, as the finder takes a lid), in mm:

* edge 3-6, 6-10, 10-15: how far the side lies inside the circle that far below the top (median of
  d - r of the points within 60 degrees of the direction to the sensor, within 15 mm inside and
  6 mm outside the circle) minus the same 20-50 mm below the top: < 0 where the edge is rounded;
* centre - ring: the top's height within 0.4 r of the axis minus at 0.6-0.85 r (< 0: recessed);
* ring - rim: the top's height at 0.6-0.85 r minus at 0.9-0.97 r (> 0: it falls toward the edge).

Real objects: the upright cans and upside-down mugs of bench/osd_objects.json in ../shared/data/osd
(their labelled points); generated: every upright can of example_pcl.scene_objects' cases on the
development seeds given (the generator's per-pixel labels). Prints a markdown table; the figures and
what was concluded are in docs/can_search.md (Limits).
"""
import argparse
import itertools
import json
import sys

import numpy as np

from bench_cans import OBJECTS, OSD, real_truth
from common import table

from example_pcl import geometry as g
from example_pcl import scene as sc
from example_pcl import scene_objects as so
from example_pcl import transforms
from example_pcl.errors import PerceptionError

FEATURES = ("edge 3-6", "edge 6-10", "edge 10-15", "centre - ring", "ring - rim")


def _median(values):
    return float(np.median(values)) if len(values) >= 3 else np.nan


def features(points, sensor, base):
    """The features (module docstring) of one object's points (float64 (N, 3), plane frame, m) seen
    from `sensor` (plane frame, m) on a support at height `base` (m): (radius, range to the sensor
    (m), dict of feature -> mm)."""
    z = points[:, 2]
    side = points[(z > base + 0.02) & (z < np.percentile(z, 99) - 0.03)]
    cx, cy, r = g.fit_circle_algebraic(side)
    fit = g.fit_cylinder(side, (cx, cy), r, 0.006, max_iterations=50)
    (cx, cy), r = fit.center, fit.radius
    d = np.hypot(points[:, 0] - cx, points[:, 1] - cy)
    front = (sensor[:2] - (cx, cy)) / np.linalg.norm(sensor[:2] - (cx, cy))
    facing = ((points[:, 0] - cx) * front[0] + (points[:, 1] - cy) * front[1]) / np.maximum(d, 1e-9) > 0.5
    top = np.percentile(z[(d >= 0.7 * r) & (d <= r + 0.005)], 99)
    near = facing & (d > r - 0.015) & (d < r + 0.006)

    def edge(lo, hi):  # mm below the top
        return _median(d[near & (z > top - 1e-3 * hi) & (z <= top - 1e-3 * lo)] - r)

    below = edge(20, 50)
    up = z > top - 0.02
    centre, ring = _median(z[up & (d < 0.4 * r)]), _median(z[up & (d >= 0.6 * r) & (d < 0.85 * r)])
    rim = _median(z[up & (d >= 0.9 * r) & (d < 0.97 * r)])
    values = (edge(3, 6) - below, edge(6, 10) - below, edge(10, 15) - below, centre - ring, ring - rim)
    return r, float(np.linalg.norm(np.r_[cx, cy, top] - sensor)), {k: 1e3 * v for k, v in zip(FEATURES, values)}


def _span(rows, median=False):
    """'min..max' of each feature over rows (dicts), and its median when asked."""
    return [f"{min(f[k] for f in rows):+.1f}..{max(f[k] for f in rows):+.1f}"
            + (f" (median {np.median([f[k] for f in rows]):+.1f})" if median else "") for k in FEATURES]


def real(step):
    from example_pcl.pcd import read_pcd

    rows = []
    for name, objects in sorted(json.loads(OBJECTS.read_text())["scenes"].items()):
        chosen = [o for o in objects if o["kind"] in ("can", "mug_upside_down")]
        if not chosen:
            continue
        cloud = read_pcd(str(OSD / f"{name}.pcd"))
        to_plane = real_truth(cloud, objects)[0]
        sensor = transforms.apply(to_plane, np.asarray(cloud.origin, float))
        for obj in chosen:
            measured, radii = [], []
            for oy, ox in itertools.product(range(step), repeat=2):
                labels = cloud.points["label"].reshape(cloud.xyz.shape[:2])[oy::step, ox::step].reshape(-1)
                xyz = cloud.xyz[oy::step, ox::step].reshape(-1, 3).astype(float)
                ok = np.isfinite(xyz).all(axis=1)
                pts = transforms.apply(to_plane, xyz[ok & (labels.astype(int) // 10 == obj["label"])])
                r, distance, f = features(pts, sensor, np.percentile(pts[:, 2], 1))
                measured.append(f)
                radii.append(r)
            what = obj["kind"] + (f" ({obj['note']})" if "note" in obj else "")
            rows.append([f"{name}/{obj['label']}", what, f"{1e3 * np.median(radii):.1f}", f"{distance:.2f}",
                         *_span(measured)])
    return rows


def generated(seeds, step):
    """One row: min..max of each feature over the upright cans of every case and seed."""
    measured = []
    for case, seed in itertools.product(so.CASES, seeds):
        scene = sc.generate_scene(so.case_spec(case, seed))
        to_plane = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
        sensor = transforms.apply(to_plane, np.zeros(3))
        labels = scene.labels[::step, ::step].reshape(-1)
        xyz = scene.xyz[::step, ::step].reshape(-1, 3).astype(float)
        ok = np.isfinite(xyz).all(axis=1)
        for i, obj in enumerate(scene.spec.objects):
            pts = transforms.apply(to_plane, xyz[ok & (labels == sc.LABEL_OBJECT + i)])
            # A can mostly hidden shows no edge to measure; one with a cup or can on it no top.
            covered = any(o is not obj and abs(o.z - obj.top) < 1e-6 for o in scene.spec.objects)
            if obj.kind != "can" or covered or len(pts) < 200:
                continue
            try:
                f = features(pts, sensor, obj.z)[2]
            except PerceptionError:  # too little side for a circle (a cup on it, a box in front)
                continue
            if all(np.isfinite(v) for v in f.values()):
                measured.append(f)
    return [f"generated (seeds {seeds[0]}-{seeds[-1]})", f"{len(measured)} upright cans", "28-50",
            "0.7-1.3 to the table's centre",
            *_span(measured, median=True)]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--step", type=int, default=2, help="every step-th pixel, as the finder's grid_step")
    p.add_argument("--seeds", type=int, nargs=2, default=(0, 20), metavar=("FIRST", "END"),
                   help="generated development seeds FIRST..END-1 (never the held-out 300-309)")
    args = p.parse_args(argv)
    if not 0 <= args.seeds[0] < args.seeds[1] <= 100:
        p.error("development seeds lie within 0-99")
    rows = real(args.step) if OSD.is_dir() else []
    if not rows:
        print(f"real scenes skipped: {OSD} is absent", file=sys.stderr)
    rows.append(generated(list(range(*args.seeds)), args.step))
    header = ["object", "what", "r (mm)", "range (m)", *(f"{k} (mm)" for k in FEATURES)]
    print(f"`bench/mug_features.py --step {args.step} --seeds {args.seeds[0]} {args.seeds[1]}`\n")
    print(table(header, rows))


if __name__ == "__main__":
    main()
