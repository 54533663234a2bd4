#!/usr/bin/python3
"""A finder in its own process, for bench_filed.py: loads the real scenes named in argv[1] (a JSON list,
read from argv[2], the osd directory), searches each once untimed, prints "ready", then for each scene
number read from stdin prints the seconds one find_cans took and the cans it found. Uses only what
every version of example_pcl since issue 5 has (auto_finder.find_cans, pcd.read_pcd), so that it runs
against an older build too."""
import json
import pathlib
import sys
import time

from example_pcl import auto_finder as af
from example_pcl.pcd import read_pcd


def main():
    names = json.loads(sys.argv[1])
    clouds = [read_pcd(str(pathlib.Path(sys.argv[2]) / f"{name}.pcd")) for name in names]
    config = af.AutoConfig()
    for cloud in clouds:
        af.find_cans(cloud.xyz, viewpoint=cloud.origin, config=config)
    print("ready", flush=True)
    for line in sys.stdin:
        cloud = clouds[int(line)]
        start = time.perf_counter()
        result = af.find_cans(cloud.xyz, viewpoint=cloud.origin, config=config)
        print(f"{time.perf_counter() - start} {len(result.cans)}", flush=True)


if __name__ == "__main__":
    main()
