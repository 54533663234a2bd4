#!/usr/bin/python3
"""Can pcd_save keep up with a Kinect? 640x480 XYZRGB at 30 Hz, continuous mode, binary and binary_compressed.

    source build/ws/devel/setup.bash && /usr/bin/python3 bench/pcd_save_rate.py [--seconds 10] [--rate 30]

Starts a roscore on a free port, pcd_publisher streaming a 640x480 XYZRGB cloud (the real Kinect
frame ../shared/data/frame_20121214T142256.332395.pcd when present, else a synthetic organized
cloud with NaN holes), and pcd_save with ~count 0 into a temporary directory, for each format;
after a warm-up it measures for --seconds, then stops pcd_save with SIGINT. Prints a markdown
table: offered and saved rate, drops (sequence gaps / queue discards), CPU% of pcd_save (and per
saved frame), of the publisher and of everything else on the machine (100% = one core), and the
machine it ran on. A benchmark, not a test: nothing fails.
"""
import argparse
import os
import platform
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from common import cpu_seconds, machine_busy_seconds, own_roscore, stop  # noqa: E402
KINECT_FRAME = os.path.join(ROOT, "..", "shared", "data", "frame_20121214T142256.332395.pcd")
SUMMARY = re.compile(r"pcd_save done: saved (\d+) of (\d+) clouds received .*?\(([\d.]+) Hz\), dropped (\d+) "
                     r"\(sequence gaps (\d+), queue discards (\d+)\)")


def make_input(path):
    """A 640x480 XYZRGB PCD file (x y z rgb float32, 16-byte points); returns its description."""
    from example_pcl.conversions import make_points, unpack_rgb
    from example_pcl.pcd import read_pcd, write_pcd

    if os.path.exists(KINECT_FRAME):
        frame = read_pcd(KINECT_FRAME)
        points = make_points(np.array(frame.xyz), unpack_rgb(frame.points))
        what = "real Kinect frame (PCL test data), 12% NaN"
    else:
        rng = np.random.default_rng(0)
        v, u = np.mgrid[0:480, 0:640].astype(np.float32)
        z = 1.0 + 0.5 * (v / 480) + rng.normal(0, 0.002, (480, 640)).astype(np.float32)
        xyz = np.stack([(u - 320) / 525 * z, (v - 240) / 525 * z, z], axis=-1).astype(np.float32)
        xyz[rng.random((480, 640)) < 0.12] = np.nan
        rgb = np.stack([u % 256, v % 256, (u + v) % 256], axis=-1).astype(np.uint8)
        points = make_points(xyz, rgb)
        what = "synthetic ramp, 12% NaN (../shared/data absent)"
    write_pcd(path, points, fmt="binary", is_dense=False)
    return what, points.nbytes


def node(name, *args, env):
    """A node of this checkout's scripts/ run with this interpreter (ROS's), no devel relay needed."""
    return subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", name)] + list(args), env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def run_format(fmt, source, seconds, rate, env, tmp):
    out_dir = tempfile.mkdtemp(dir=tmp, prefix=fmt + "_")
    publisher = node("pcd_publisher", f"_file:={source}", f"_rate:={rate}", "__name:=bench_pcd_publisher", env=env)
    saver = node("pcd_save", f"_file:={out_dir}/frame.pcd", f"_format:={fmt}", "_count:=0",
                 "__name:=bench_pcd_save", env=env)
    try:
        deadline = time.monotonic() + 30
        while not any(n.endswith(".json") for n in os.listdir(out_dir)):
            if time.monotonic() > deadline or saver.poll() is not None:
                raise RuntimeError(f"pcd_save wrote nothing for {fmt}")
            time.sleep(0.1)
        time.sleep(1.0)  # warm-up
        t0, c0, p0, m0 = time.monotonic(), cpu_seconds(saver.pid), cpu_seconds(publisher.pid), machine_busy_seconds()
        time.sleep(seconds)
        t1, c1, p1, m1 = time.monotonic(), cpu_seconds(saver.pid), cpu_seconds(publisher.pid), machine_busy_seconds()
        saver.send_signal(signal.SIGINT)
        output = saver.communicate(timeout=60)[0]
    finally:
        stop(saver, publisher)
    match = SUMMARY.search(output)
    if not match:
        raise RuntimeError(f"no summary from pcd_save:\n{output[-2000:]}")
    saved, received, hz, dropped, gaps, discards = match.groups()
    files = [n for n in os.listdir(out_dir) if n.endswith(".pcd")]
    size = np.mean([os.path.getsize(os.path.join(out_dir, n)) for n in files[:20]]) if files else 0
    shutil.rmtree(out_dir, ignore_errors=True)
    span = t1 - t0
    return dict(fmt=fmt, saved=int(saved), received=int(received), hz=float(hz), dropped=int(dropped),
                gaps=int(gaps), discards=int(discards), cpu=100 * (c1 - c0) / span, pub_cpu=100 * (p1 - p0) / span,
                other_cpu=100 * ((m1 - m0) - (c1 - c0) - (p1 - p0)) / span, file_mb=size / 1e6)


def machine():
    model = "?"
    try:
        with open("/proc/cpuinfo") as f:
            model = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{model}, {os.cpu_count()} CPUs, Python {platform.python_version()}, {platform.platform()}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measurement window per format")
    parser.add_argument("--rate", type=float, default=30.0, help="publishing rate, Hz")
    parser.add_argument("--formats", nargs="+", default=["binary", "binary_compressed"])
    args = parser.parse_args()

    tmp = tempfile.mkdtemp(prefix="pcd_save_bench_")
    try:
        with own_roscore(tmp) as env:
            source = os.path.join(tmp, "kinect_xyzrgb.pcd")
            what, nbytes = make_input(source)
            rows = [run_format(fmt, source, args.seconds, args.rate, env, tmp) for fmt in args.formats]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    print(f"pcd_save continuous mode, 640x480 XYZRGB ({nbytes / 1e6:.1f} MB per message, {what}) "
          f"published at {args.rate:g} Hz = {nbytes * args.rate / 1e6:.0f} MB/s, {args.seconds:g} s per format")
    print(f"machine: {machine()}; output directory on {tempfile.gettempdir()}\n")
    print("| format | saved Hz | saved / received | dropped (seq gaps + queue discards) | file MB | "
          "CPU% pcd_save | CPU ms per saved frame | CPU% pcd_publisher | CPU% everything else |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in rows:
        print(f"| {r['fmt']} | {r['hz']:.1f} | {r['saved']} / {r['received']} | {r['dropped']} "
              f"({r['gaps']} + {r['discards']}) | {r['file_mb']:.1f} | {r['cpu']:.0f} | "
              f"{10 * r['cpu'] / r['hz'] if r['hz'] else float('nan'):.0f} | {r['pub_cpu']:.0f} | "
              f"{r['other_cpu']:.0f} |")
    print("\nCPU% is per core (100 = one core busy; the machine has", os.cpu_count(), "cores); drops are frames "
          "the publisher sent that pcd_save never saw (sequence gaps) plus frames its bounded queue discarded. "
          "Everything else: the CPU all other processes on the machine used meanwhile (roscore, other users' "
          "work), from /proc/stat; with it near the machine's capacity, pcd_save's rate is bounded by its share "
          "of the cores, not by its own speed.")


if __name__ == "__main__":
    main()
