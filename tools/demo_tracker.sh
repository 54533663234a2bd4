#!/usr/bin/env bash
# make demo-tracker: can_tracker on a generated moving stream, headless unless RVIZ=true.
# Starts its own ROS master (on a free port) and can_tracker.launch (target_frame:=table), streams a
# generated sequence at 30 Hz (tools/stream_sequence.py: the camera drifting, a can added, one moved,
# one removed) and prints the tracks per frame; stops everything it started, also on error or Ctrl-C.
# Needs the devel space sourced (make demo-tracker does it). Usage: tools/demo_tracker.sh [rviz] [args...]
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=/usr/bin/python3
OUT=build/demo_tracker
mkdir -p "$OUT"
RVIZ=false
if [ "${1:-}" = "rviz" ]; then RVIZ=true; shift; fi

PORT=$($PYTHON -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI="http://127.0.0.1:$PORT"
export ROS_HOME="$PWD/$OUT/ros_home"   # logs stay in build/demo_tracker
LAUNCH_LOG="$OUT/roslaunch.log"

LAUNCH_PID=""
stop() {
  if [ -n "$LAUNCH_PID" ] && kill -0 "$LAUNCH_PID" 2>/dev/null; then
    kill -INT "$LAUNCH_PID" 2>/dev/null || true
    for _ in $(seq 50); do kill -0 "$LAUNCH_PID" 2>/dev/null || break; sleep 0.1; done
    kill -TERM "$LAUNCH_PID" 2>/dev/null || true
    wait "$LAUNCH_PID" 2>/dev/null || true
  fi
}
trap stop EXIT
trap 'exit 130' INT TERM

echo "demo-tracker: roslaunch example_pcl can_tracker.launch cloud:=/camera/depth/points target_frame:=table" \
  "rviz:=$RVIZ (master on port $PORT, log $LAUNCH_LOG)"
roslaunch -p "$PORT" example_pcl can_tracker.launch cloud:=/camera/depth/points target_frame:=table \
  rviz:="$RVIZ" >"$LAUNCH_LOG" 2>&1 &
LAUNCH_PID=$!

for _ in $(seq 100); do
  $PYTHON -c 'import rosgraph, sys; sys.exit(not rosgraph.is_master_online())' 2>/dev/null && break
  if ! kill -0 "$LAUNCH_PID" 2>/dev/null; then
    echo "demo-tracker: roslaunch exited; see $LAUNCH_LOG" >&2; tail -n 20 "$LAUNCH_LOG" >&2; exit 1
  fi
  sleep 0.2
done

if ! $PYTHON tools/stream_sequence.py "$@"; then
  echo "demo-tracker: failed; the node's log: $LAUNCH_LOG" >&2
  tail -n 20 "$LAUNCH_LOG" >&2
  exit 1
fi
grep -h "can_tracker:" "$LAUNCH_LOG" | grep -v "^\s*\*" | tail -n 8 || true
