#!/usr/bin/env bash
# make demo: the find_can walkthrough, headless, on the bundled scene.
# Starts its own ROS master (on a free port) and find_can.launch rviz:=false, runs the scripted
# operator (python3 -m example_pcl.demo), and stops everything it started, also on error or Ctrl-C.
# Needs the devel space sourced (make demo does it). Picture: build/demo/find_can.png.
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/roslaunch_bg.sh
OUT=build/demo

start_roslaunch demo "$OUT" example_pcl find_can.launch rviz:=false
$PYTHON -m example_pcl.demo --out "$OUT/find_can.png" "$@" || fail demo
