#!/usr/bin/env bash
# make demo: the find_can walkthrough, headless, on the bundled scene.
# Starts its own ROS master (on a free port) and find_can.launch rviz:=false, runs the scripted
# operator (python3 -m example_pcl.demo), and stops everything it started, also on error or Ctrl-C.
# Needs the devel space sourced (make demo does it). Picture: build/demo/find_can.png.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=/usr/bin/python3
OUT=build/demo
mkdir -p "$OUT"

PORT=$($PYTHON -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI="http://127.0.0.1:$PORT"
export ROS_HOME="$PWD/$OUT/ros_home"   # logs stay in build/demo
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

echo "demo: roslaunch example_pcl find_can.launch rviz:=false (master on port $PORT, log $LAUNCH_LOG)"
roslaunch -p "$PORT" example_pcl find_can.launch rviz:=false >"$LAUNCH_LOG" 2>&1 &
LAUNCH_PID=$!

# Wait for the master roslaunch starts, so the client does not race it.
for _ in $(seq 100); do
  $PYTHON -c 'import rosgraph, sys; sys.exit(not rosgraph.is_master_online())' 2>/dev/null && break
  kill -0 "$LAUNCH_PID" 2>/dev/null || { echo "demo: roslaunch exited; see $LAUNCH_LOG" >&2; tail -n 20 "$LAUNCH_LOG" >&2; exit 1; }
  sleep 0.2
done

if ! $PYTHON -m example_pcl.demo --out "$OUT/find_can.png" "$@"; then
  echo "demo: failed; the node's log: $LAUNCH_LOG" >&2
  tail -n 20 "$LAUNCH_LOG" >&2
  exit 1
fi
