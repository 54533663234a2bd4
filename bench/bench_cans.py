#!/usr/bin/python3
"""Every can on a real table (issue 13): can_search (find_cans' default) beside the issue 5 finder
(search="clusters"), in one run, on generated cases and on the real mOSD scenes.

* Generated: every case of example_pcl.scene_objects.CASES for held-out seeds (default 1900-1909;
  development used 0-99 and 400-499, and 100-104, 200-209, 300-309, 600-609, 700-709, 800-809,
  900-909, 1000-1009, 1100-1109, 1200-1209, 1300-1309, 1400-1409, 1500-1509, 1600-1609,
  1700-1709 and 1800-1809 were held out before), truth from the generator.
* Real: ../shared/data/osd, truth from the human labels: each object's points (label // 10), the
  table from the table's labels (1-9); what each object is comes from bench/osd_objects.json
  (looked up in the colour images). A can's centre is the circle fitted to its labelled side points.

Per case: cans found / missed / false (an upright can reported where there is none, also an
upright report of a lying can; a generated can less than a quarter in view - fewer of its pixels
return depth than a quarter of those it shows alone - is neither found nor missed: reported apart,
"hidden found"), lying cans reported as lying (axis within 10 degrees of the truth's
and the middle of the axis within the match distance horizontally: 15 mm generated, 20 mm real; one
whose far end the image's edge cuts, end_seen False, by the end it reports seen; with the median of both
errors; a real lying can's truth is the horizontal cylinder fitted to its labelled
side points: lying_truth), median centre error (mm, horizontal,
against the truth's axis), median top error (mm, generated upright cans: the found top's height
against the truth's, where a gripper closes on a can from above), base off (generated upright cans
found whose base height is more than 1 cm off their support's: a can reported on the wrong support,
or with its base inferred on the table while it stands on an object; found by its axis all the
same) and time per frame (median / p90 ms, real scenes; each scene searched `--repeats` times, the
two finders alternately). Prints a markdown table and writes it into docs/can_search.md between
<!-- bench:cans --> markers.
"""
import argparse
import dataclasses
import json
import pathlib
import statistics
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from common import machine_line, table, write_section  # noqa: E402

from example_pcl import auto_finder as af  # noqa: E402
from example_pcl import geometry as g  # noqa: E402
from example_pcl import scene as sc  # noqa: E402
from example_pcl import scene_objects as so  # noqa: E402
from example_pcl import transforms  # noqa: E402

PROJECT = HERE.parent
OSD = PROJECT / ".." / "shared" / "data" / "osd"
OBJECTS = HERE / "osd_objects.json"
DOC = PROJECT / "docs" / "can_search.md"
LYING_ANGLE = np.radians(10)  # a lying can's axis within this of the truth's
MIN_IN_VIEW = 0.25  # a generated can counts when at least this fraction of it is in view
BASE_OFF = 0.01  # m: a found can's base further than this from its support's height is counted "base off"
FINDERS = {"can_search": af.AutoConfig(), "issue 5 finder": af.AutoConfig(search="clusters")}


class Tally:
    def __init__(self):
        self.found = self.missed = self.false = self.lying = self.lying_total = 0
        self.hidden_found = self.hidden_total = 0  # cans (upright or lying) less than MIN_IN_VIEW in view
        self.errors, self.times = [], []  # centre errors (m); real frames' search times (s)
        self.top_errors = []  # generated upright cans found: |found top - true top| (m)
        self.base_errors = []  # the same cans: |found base height - true support height| (m)
        self.lying_errors, self.lying_angles = [], []

    def add(self, other):
        """Adds another Tally's counts and errors to this one (a total over cases)."""
        for a in ("found", "missed", "false", "lying", "lying_total", "hidden_found", "hidden_total"):
            setattr(self, a, getattr(self, a) + getattr(other, a))
        for a in ("errors", "times", "top_errors", "base_errors", "lying_errors", "lying_angles"):
            getattr(self, a).extend(getattr(other, a))

    def row(self, name, finder, timed):
        err = f"{1e3 * statistics.median(self.errors):.2f}" if self.errors else "-"
        top = f"{1e3 * statistics.median(self.top_errors):.1f}" if self.top_errors else "-"
        t = (f"{1e3 * statistics.median(self.times):.1f} / {1e3 * np.percentile(self.times, 90):.1f}"
             if timed and self.times else "-")
        lying = f"{self.lying}/{self.lying_total}" if self.lying_total else "-"
        if self.lying_errors:
            lying += (f" ({1e3 * statistics.median(self.lying_errors):.1f} mm, "
                      f"{np.degrees(statistics.median(self.lying_angles)):.1f} deg)")
        hidden = f"{self.hidden_found}/{self.hidden_total}" if self.hidden_total else "-"
        base_off = sum(e > BASE_OFF for e in self.base_errors) if self.base_errors else "-"
        return [name, finder, self.found, self.missed, self.false, lying, hidden, err, top, base_off, t]


def score(tally, found_cans, true_cans, true_lying, to_plane, match):
    """Matches found cans (sensor frame) with the truth (plane-frame dicts: center (x, y), radius,
    support_height, base_seen, top (generated: the top's height, m); lying: center (x, y, z) the middle of its
    axis, axis (unit, horizontal), length; either: hidden (optional, less than MIN_IN_VIEW in view))."""
    used, used_lying = set(), set()
    for can in found_cans:
        base = transforms.apply(to_plane, can.base_center)
        if can.lying:
            # A lying can is found when its axis is within LYING_ANGLE of the truth's and the middle
            # of its axis within `match` of the truth's (horizontally); one whose far end the image's
            # edge cuts (end_seen False), when its origin, the end seen, is within `match` of the
            # truth's nearer end (both ends cut: its middle within `match` of the truth's axis).
            axis = transforms.apply(to_plane, can.base_center + can.axis) - base
            mid = transforms.apply(to_plane, can.base_center + 0.5 * can.height * can.axis)
            hits = [(_lying_error(can, base, mid, t), k) for k, t in enumerate(true_lying)
                    if k not in used_lying and abs(axis @ t["axis"]) >= np.cos(LYING_ANGLE)]
            error, k = min(hits) if hits else (np.inf, -1)
            if error >= match:
                tally.false += 1
                continue
            used_lying.add(k)
            if true_lying[k].get("hidden"):
                tally.hidden_found += 1
                continue
            tally.lying += 1
            tally.lying_errors.append(error)
            tally.lying_angles.append(np.arccos(min(1.0, abs(axis @ true_lying[k]["axis"]))))
            continue
        axis = transforms.apply(to_plane, can.base_center + can.axis) - base
        # where the found axis meets the truth's base height; of the cans not matched yet, the one
        # nearest counting the base's height too (cans stacked on one axis differ only there)
        errors, costs = [], []
        for k, t in enumerate(true_cans):
            s = (t["support_height"] - base[2]) / axis[2] if abs(axis[2]) > 1e-6 else 0.0
            p = base + s * axis
            errors.append(np.linalg.norm(p[:2] - t["center"]))
            costs.append(np.inf if k in used else errors[-1] + abs(t["support_height"] - base[2]))
        k = int(np.argmin(costs)) if costs and np.isfinite(min(costs)) else -1
        if k >= 0 and errors[k] < max(match, 0.5 * true_cans[k]["radius"]):
            used.add(k)
            if true_cans[k].get("hidden"):
                tally.hidden_found += 1
                continue
            tally.found += 1
            tally.errors.append(errors[k])
            if "top" in true_cans[k]:
                tally.top_errors.append(abs(base[2] + can.height * axis[2] - true_cans[k]["top"]))
                tally.base_errors.append(abs(base[2] - true_cans[k]["support_height"]))
        else:
            tally.false += 1
    tally.missed += sum(not t.get("hidden", False) for k, t in enumerate(true_cans) if k not in used)
    tally.lying_total += sum(not t.get("hidden", False) for t in true_lying)
    tally.hidden_total += sum(t.get("hidden", False) for t in true_cans + true_lying)


def _lying_error(can, start, mid, truth):
    """Horizontal error (m) of a lying can found (start: its origin, mid: its axis' middle, plane
    frame) against a true lying can (score's dict), as score matches them."""
    if can.end_seen:
        return float(np.linalg.norm(mid[:2] - truth["center"][:2]))
    if can.base_seen:
        ends = [truth["center"] + s * 0.5 * truth["length"] * truth["axis"] for s in (-1.0, 1.0)]
        return float(min(np.linalg.norm(start[:2] - e[:2]) for e in ends))
    rel = mid[:2] - truth["center"][:2]
    return float(abs(rel @ np.array([-truth["axis"][1], truth["axis"][0]])))


def generated_truth(spec, scene):
    """(T_plane_from_sensor, true cans, true lying cans) of a generated scene (score's dicts); a can
    is hidden when fewer of its pixels return depth than MIN_IN_VIEW of those it shows alone."""
    to_plane = transforms.invert(np.asarray(scene.truth["camera_from_table"]))
    cans, lying = [], []
    for obj, t in zip(spec.objects, scene.truth["objects"]):
        if not (t["is_can"] or t["lying"]):
            continue
        alone = sc.generate_scene(dataclasses.replace(spec, objects=[obj])).truth["objects"][0]["visible_points"]
        hidden = t["visible_points"] < MIN_IN_VIEW * alone
        p = transforms.apply(to_plane, t["base_center"])
        if t["is_can"]:
            cans.append({"center": p[:2], "radius": t["radius"], "support_height": p[2], "top": p[2] + t["height"],
                         "hidden": hidden})
        else:
            a = transforms.apply(to_plane, np.asarray(t["base_center"]) + t["height"] * np.asarray(t["axis"]))
            lying.append({"center": 0.5 * (p + a), "axis": (a - p) / np.linalg.norm(a - p),
                          "length": float(np.linalg.norm(a - p)), "hidden": hidden})
    return to_plane, cans, lying


def generated(seeds, tallies):
    for case in so.CASES:
        for seed in seeds:
            spec = so.case_spec(case, seed)
            scene = sc.generate_scene(spec)
            to_plane, cans, lying = generated_truth(spec, scene)
            for name, config in FINDERS.items():
                result = af.find_cans(scene.xyz, config=config)
                score(tallies.setdefault((case, name), Tally()), result.cans, cans, lying, to_plane, 0.015)


def real_truth(cloud, objects):
    """(plane frame T_plane_from_sensor from the labelled table, true cans, true lying cans)."""
    labels = cloud.points["label"].reshape(-1).astype(int)
    xyz = cloud.xyz.reshape(-1, 3).astype(float)
    ok = np.isfinite(xyz).all(axis=1)
    table = xyz[ok & (labels >= 1) & (labels <= 9)]
    centroid = table.mean(axis=0)
    normal = np.linalg.eigh(np.cov((table - centroid).T))[1][:, 0]
    plane = g.Plane.through(normal, centroid, np.asarray(cloud.origin, float))
    to_plane = transforms.invert(g.plane_frame(plane.normal, centroid))
    cans, lying = [], []
    for obj in objects:
        pts = transforms.apply(to_plane, xyz[ok & (labels // 10 == obj["label"])])
        z = pts[:, 2]
        if obj["kind"] == "can":
            base = float(np.percentile(z, 1))
            top = float(np.percentile(z, 99))
            side = pts[(z > base + 0.02) & (z < top - 0.015)]
            cx, cy, r = g.fit_circle_algebraic(side)
            fit = g.fit_cylinder(side, (cx, cy), r, 0.006, max_iterations=50)
            cans.append({"center": fit.center, "radius": fit.radius, "support_height": base if base > 0.02 else 0.0})
        elif obj["kind"] == "lying_can":
            lying.append(lying_truth(pts))
    return to_plane, cans, lying


def lying_truth(pts, turn=np.radians(6), step=np.radians(0.1), end=0.015):
    """A real lying can's truth from its labelled points (plane frame, m): {"center": the middle of
    its axis (3,), "axis": unit, horizontal, "length": the span of its labelled points along it}.
    The horizontal direction within `turn` of the points' principal direction seen from above
    (every `step`) whose cross-section circle, fitted to the side points (without `end` at either end
    of their span) as an upright can's truth is, leaves the least rms residual within 6 mm; the
    middle is the circle's centre at the middle of the span."""
    mean = pts[:, :2].mean(axis=0)
    u = np.linalg.eigh(np.cov((pts[:, :2] - mean).T))[1][:, 1]
    best = None
    for theta in np.arctan2(u[1], u[0]) + np.arange(-turn, turn + step / 2, step):
        u = np.array([np.cos(theta), np.sin(theta)])
        n = np.array([-u[1], u[0]])
        along, across = (pts[:, :2] - mean) @ u, (pts[:, :2] - mean) @ n
        lo, hi = np.percentile(along, [1, 99])
        side = (along > lo + end) & (along < hi - end)
        section = np.column_stack([across[side], pts[side, 2]])
        cl, cz, r = g.fit_circle_algebraic(section)
        fit = g.fit_cylinder(section, (cl, cz), r, 0.006)
        residual = np.abs(np.hypot(*(section - fit.center).T) - fit.radius)
        rms = float(np.sqrt(np.mean(residual[residual <= 0.006] ** 2)))
        if best is None or rms < best[0]:
            middle = mean + 0.5 * (lo + hi) * u + fit.center[0] * n
            best = (rms, {"center": np.array([middle[0], middle[1], fit.center[1]]),
                          "axis": np.array([u[0], u[1], 0.0]), "length": float(hi - lo)})
    return best[1]


def real(repeats, tallies):
    from example_pcl.pcd import read_pcd

    kinds = json.loads(OBJECTS.read_text())["scenes"]
    for name, objects in sorted(kinds.items()):
        path = OSD / f"{name}.pcd"
        cloud = read_pcd(str(path))
        to_plane, cans, lying = real_truth(cloud, objects)
        case = "real: " + ("cans" if cans else "lying cans" if lying else "no can")
        results = {}
        for _ in range(repeats):
            for finder, config in FINDERS.items():
                start = time.perf_counter()
                results[finder] = af.find_cans(cloud.xyz, viewpoint=cloud.origin, config=config)
                elapsed = time.perf_counter() - start
                for key in ((case, finder), ("real: all", finder)):
                    tallies.setdefault(key, Tally()).times.append(elapsed)
        for finder, result in results.items():
            for key in ((case, finder), ("real: all", finder)):
                score(tallies[key], result.cans, cans, lying, to_plane, 0.02)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, nargs="+", default=list(range(1900, 1910)),
                   help="generator seeds (held out: development used 0-99 and 400-499)")
    p.add_argument("--repeats", type=int, default=3, help="searches per real scene and finder")
    p.add_argument("--print-only", action="store_true", help="print only, do not write docs/can_search.md")
    args = p.parse_args(argv)
    tallies = {}
    generated(args.seeds, tallies)
    if OSD.is_dir():
        real(args.repeats, tallies)
    else:
        print(f"real scenes skipped: {OSD} is absent")
    for finder in FINDERS:
        total = Tally()
        for (case, f), t in tallies.items():
            if f == finder and not case.startswith("real"):
                total.add(t)
        tallies[("generated: all", finder)] = total
    rows = [t.row(case, finder, case.startswith("real")) for (case, finder), t in sorted(
        tallies.items(), key=lambda kv: (kv[0][0].startswith("real"), kv[0][0].endswith("all"), kv[0][0], kv[0][1]))]
    header = ["case", "finder", "found", "missed", "false", "lying reported lying", "hidden found",
              "median centre error (mm)",
              "median top error (mm)", "base off > 1 cm", "time per frame median / p90 (ms)"]
    ratio = ""
    if ("real: all", "can_search") in tallies:
        a, b = tallies[("real: all", "can_search")].times, tallies[("real: all", "issue 5 finder")].times
        ratio = (f"\n\nTime ratio can_search / issue 5 finder on the real scenes: median "
                 f"{statistics.median(a) / statistics.median(b):.2f}, "
                 f"p90 {np.percentile(a, 90) / np.percentile(b, 90):.2f}.")
    text = (f"`bench/bench_cans.py` (seeds {', '.join(map(str, args.seeds))}; {args.repeats} searches per real scene "
            f"and finder), {machine_line()}\n\n" + table(header, rows) + ratio)
    print(text)
    if not args.print_only:
        write_section(DOC, "cans", text)


if __name__ == "__main__":
    main()
