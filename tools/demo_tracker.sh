#!/usr/bin/env bash
# make demo-tracker: can_tracker on a generated moving stream, headless unless RVIZ=true.
# Starts its own ROS master (on a free port) and can_tracker.launch (target_frame:=table), streams a
# generated sequence at 30 Hz (tools/stream_sequence.py: the camera drifting, a can added, one moved,
# one removed) and prints the tracks per frame; stops everything it started, also on error or Ctrl-C.
# Needs the devel space sourced (make demo-tracker does it). Usage: tools/demo_tracker.sh [rviz] [args...]
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/roslaunch_bg.sh
OUT=build/demo_tracker
RVIZ=false
if [ "${1:-}" = "rviz" ]; then RVIZ=true; shift; fi

start_roslaunch demo-tracker "$OUT" example_pcl can_tracker.launch cloud:=/camera/depth/points \
  target_frame:=table rviz:="$RVIZ"
$PYTHON tools/stream_sequence.py "$@" || fail demo-tracker
grep -h "can_tracker:" "$LAUNCH_LOG" | grep -v "^\s*\*" | tail -n 8 || true
