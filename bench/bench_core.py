#!/usr/bin/python3
"""The native core side by side with sensor_msgs, NumPy, memcpy, PCL's C++ and (when installed) Open3D.

On a 640x480 organized XYZRGB cloud with ~30% NaN points, laid out as PCL's PointXYZRGB
(32 bytes a point) in a sensor_msgs/PointCloud2. Run with `make bench` (writes the figures in
docs/benchmarks.md) or `bench/bench_core.py --print-only`.
"""
import argparse
import json
import os
import statistics
import time
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from common import machine_line, median_time, ms, table, write_figures  # noqa: E402

from example_pcl import _native, conversions, pcd  # noqa: E402


def kinect_like_message(nan_fraction=0.3, seed=0):
    """A PointCloud2 of 640x480 PCL-style XYZRGB points (x y z pad rgb pad pad pad) with NaN holes."""
    from sensor_msgs.msg import PointCloud2, PointField
    from std_msgs.msg import Header

    rng = np.random.default_rng(seed)
    h, w = 480, 640
    v, u = np.mgrid[0:h, 0:w]
    z = 1.0 + 0.5 * rng.random((h, w))
    xyz = np.stack([(u - 319.5) / 525 * z, (v - 239.5) / 525 * z, z], axis=-1).astype(np.float32)
    xyz[rng.random((h, w)) < nan_fraction] = np.nan
    buf = np.zeros((h, w, 32), np.uint8)
    buf[..., :12] = xyz.view(np.uint8).reshape(h, w, 12)
    buf[..., 16:20] = rng.integers(0, 2**24, (h, w), dtype=np.uint32).view(np.uint8).reshape(h, w, 4)
    fields = [PointField("x", 0, 7, 1), PointField("y", 4, 7, 1), PointField("z", 8, 7, 1),
              PointField("rgb", 16, 7, 1)]
    return PointCloud2(header=Header(frame_id="camera"), height=h, width=w, fields=fields, is_bigendian=False,
                       point_step=32, row_step=32 * w, data=buf.tobytes(), is_dense=False)


def rigid_transform():
    c, s = np.cos(0.3), np.sin(0.3)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = [0.1, -0.2, 0.3]
    return T


def try_open3d():
    try:
        import open3d  # noqa: F401

        return open3d
    except Exception:  # not installed, or no libGL
        return None


def bench_message(msg, o3d):
    from sensor_msgs import point_cloud2

    read_points = median_time(lambda: list(point_cloud2.read_points(msg, ("x", "y", "z"))), repeats=3)
    view = median_time(lambda: conversions.cloud_to_xyz(msg), repeats=50)
    copy = median_time(lambda: conversions.cloud_to_xyz(msg, copy=True), repeats=20)
    rows = [["sensor_msgs.point_cloud2.read_points (list)", ms(read_points), "1x"],
            ["ours: cloud_to_xyz (zero-copy view)", ms(view), f"{read_points / view:,.0f}x faster"],
            ["ours: cloud_to_xyz(copy=True)", ms(copy), f"{read_points / copy:,.0f}x faster"]]
    return rows, {"read_points": read_points, "view": view, "copy": copy}


def bench_transform_filter(msg, o3d):
    xyz = conversions.cloud_to_xyz(msg)
    T = rigid_transform()
    raw = np.frombuffer(msg.data, np.uint8)
    dst_raw = np.empty_like(raw)
    out = np.empty(xyz.shape, np.float32)
    R, t = T[:3, :3].astype(np.float32), T[:3, 3].astype(np.float32)
    f = {
        "memcpy of the message buffer (9.8 MB)": lambda: np.copyto(dst_raw, raw),
        "ours: transform_cloud (strided view in, new array out)": lambda: _native.transform_cloud(xyz, T),
        "ours: transform_cloud(out=preallocated)": lambda: _native.transform_cloud(xyz, T, out=out),
        "NumPy: xyz @ R.T + t": lambda: xyz @ R.T + t,
    }
    if o3d is not None:
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz.reshape(-1, 3).astype(np.float64)))
        f["Open3D: PointCloud.transform (float64, in place)"] = lambda: pc.transform(T)
    times = {k: median_time(v, repeats=15) for k, v in f.items()}
    base = times["memcpy of the message buffer (9.8 MB)"]
    rows = [[k, ms(v), f"{v / base:.2f}x memcpy"] for k, v in times.items()]
    z = xyz[..., 2]
    g = {
        "ours: filter_z_band": lambda: _native.filter_z_band(xyz, 1.25, 0.05),
        "NumPy: flatnonzero(abs(z - z0) <= eps)": lambda: np.flatnonzero(np.abs(z - 1.25) <= 0.05),
    }
    with np.errstate(invalid="ignore"):
        ftimes = {k: median_time(v, repeats=15) for k, v in g.items()}
    numpy_t = ftimes["NumPy: flatnonzero(abs(z - z0) <= eps)"]
    rows += [[k, ms(v), f"{v / base:.2f}x memcpy" + (f", {numpy_t / v:.1f}x faster than NumPy" if k.startswith("ours") else "")]
             for k, v in ftimes.items()]
    return rows, {**times, **ftimes}


def bench_normal():
    rng = np.random.default_rng(1)
    rows, figures = [], {}
    for n in (100, 5000, 100000):
        pts = np.c_[rng.uniform(-0.1, 0.1, (n, 2)), rng.normal(1, 0.002, n)].astype(np.float32)
        ours = median_time(lambda: _native.compute_point_normal(pts), repeats=15)

        def numpy_normal():
            good = pts[np.isfinite(pts).all(axis=1)].astype(np.float64)
            w, v = np.linalg.eigh(np.cov(good.T))
            return v[:, 0], w[0] / w.sum()

        ref = median_time(numpy_normal, repeats=15)
        rows.append([f"{n:,} points", ms(ours), ms(ref), f"{ref / ours:.1f}x"])
        figures[n] = {"ours": ours, "numpy": ref}
    return rows, figures


ONE_THREAD = "binary_compressed, 1 thread"


def bench_pcd(msg, o3d, pcl_program, repeats=5):
    """PCD write and read of the cloud in each format: ours and PCL's C++ program, interleaved.

    Runs alternate (PCL's program once, then ours once, `repeats` times) so that a change in the
    machine's load hits both sides alike; medians are compared.
    """
    points = conversions.cloud_to_array(msg)
    times = {}  # (side, op, fmt) -> [seconds]

    def timed(key, f):
        start = time.perf_counter()
        f()
        times.setdefault(key, []).append(time.perf_counter() - start)

    have_pcl = bool(pcl_program) and os.access(pcl_program, os.X_OK)
    with tempfile.TemporaryDirectory() as tmp:
        src = os.path.join(tmp, "in.pcd")
        pcd.write_pcd(src, points, fmt="binary")
        for _ in range(repeats + 1):  # the first round warms the page cache and is dropped below
            if have_pcl:
                out = subprocess.run([pcl_program, src, tmp, "1"], capture_output=True, text=True, check=True).stdout
                for key, value in json.loads(out.strip().splitlines()[-1]).items():
                    if key != "points":
                        op, fmt = key.split("_", 1)
                        times.setdefault(("pcl", op, fmt), []).append(value)
            for fmt in pcd.FORMATS:
                path = os.path.join(tmp, f"ours_{fmt}.pcd")
                timed(("ours", "write", fmt), lambda: pcd.write_pcd(path, points, fmt=fmt))
                timed(("nofsync", "write", fmt), lambda: pcd.write_pcd(path, points, fmt=fmt, fsync=False))
                timed(("ours", "read", fmt), lambda: pcd.read_pcd(path))
                if o3d is not None:
                    t = o3d.t.geometry.PointCloud(o3d.core.Tensor(conversions.xyz_view(points).reshape(-1, 3).copy()))
                    o3path = os.path.join(tmp, f"o3d_{fmt}.pcd")
                    timed(("o3d", "write", fmt), lambda: o3d.t.io.write_point_cloud(
                        o3path, t, write_ascii=fmt == "ascii", compressed=fmt == "binary_compressed"))
                    timed(("o3d", "read", fmt), lambda: o3d.t.io.read_point_cloud(o3path))
            # The compressed writer on one thread, as PCL's writer runs: the per-core speed-up.
            path = os.path.join(tmp, "ours_one_thread.pcd")
            timed(("ours", "write", ONE_THREAD), lambda: pcd.write_pcd(path, points, threads=1))
            timed(("nofsync", "write", ONE_THREAD), lambda: pcd.write_pcd(path, points, threads=1, fsync=False))
    med = {k: statistics.median(v[1:]) for k, v in times.items()}
    rows = []
    for fmt in pcd.FORMATS:
        for op in ("write", "read"):
            rows.append(pcd_row(med, op, fmt, fmt))
            if (op, fmt) == ("write", "binary_compressed"):
                rows.append(pcd_row(med, op, ONE_THREAD, fmt))
    return rows, med


def pcd_row(med, op, variant, fmt):
    """One row of the PCD I/O table: our `variant` of `fmt` against PCL's program and Open3D on `fmt`."""
    pcl_t = med.get(("pcl", op, fmt))
    row = [f"{op} {variant}", ms(med[("ours", op, variant)])]
    row.append(ms(med[("nofsync", op, variant)]) if op == "write" else "(same)")
    row.append(ms(pcl_t) if pcl_t else "n/a")
    fast = med[("nofsync", op, variant)] if op == "write" else med[("ours", op, variant)]
    row.append(f"{fast / pcl_t:.2f}" if pcl_t else "n/a")
    if variant != fmt:
        row.append("")
    else:
        o3_t = med.get(("o3d", op, fmt))
        row.append(ms(o3_t) + " (xyz only)" if o3_t else "not installed")
    return row


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--print-only", action="store_true", help="print only; leave docs/benchmarks.md alone")
    parser.add_argument("--pcl-program", default=os.environ.get("PCD_IO_PCL"),
                        help="the bench/pcd_io_pcl.cpp program (make bench passes it)")
    args = parser.parse_args(argv)
    o3d = try_open3d()
    msg = kinect_like_message()
    nan = np.isnan(conversions.cloud_to_xyz(msg)).any(axis=-1).mean()

    sections = [f"Measured on: {machine_line()}. Cloud: 640x480 organized XYZRGB, 32-byte points, "
                f"{nan:.0%} NaN. Median of repeated runs. Open3D: {o3d.__version__ if o3d else 'not installed'}."]
    rows, _ = bench_message(msg, o3d)
    sections.append("**PointCloud2 -> xyz** (target: at least 100x faster than read_points)\n\n"
                    + table(["method", "time", "ratio"], rows))
    rows, _ = bench_transform_filter(msg, o3d)
    sections.append("**Rigid transform and z-band filter** (target: transform within 3x of memcpy)\n\n"
                    + table(["method", "time", "ratio"], rows))
    rows, _ = bench_normal()
    sections.append("**compute_point_normal (PCL) vs NumPy covariance + eigh**\n\n"
                    + table(["patch", "ours (PCL)", "NumPy", "NumPy / ours"], rows))
    rows, _ = bench_pcd(msg, o3d, args.pcl_program)
    sections.append("**PCD I/O: ours (Python over PCL's reader and writer; binary_compressed in PCL's layout "
                    "with PCL's lzfCompress, compressed by ours on one thread per core; every write atomic: "
                    "temporary name + rename, by default also fsync) vs PCL's C++ loadPCDFile / PCDWriter**, "
                    "runs interleaved (target: within 1.2x)\n\n"
                    + table(["operation", "ours", "ours, fsync=False", "PCL C++", "ours (no fsync) / PCL", "Open3D"],
                            rows))
    text = "\n\n".join(sections)
    print(text)
    if not args.print_only:
        write_figures("core", text)


if __name__ == "__main__":
    main()
