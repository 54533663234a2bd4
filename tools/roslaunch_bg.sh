# Sourced by the demo scripts: start_roslaunch NAME OUT ARGS... starts `roslaunch ARGS` in the background
# with its own ROS master on a free port (ROS_MASTER_URI exported), logs and ROS_HOME under OUT, waits for
# the master, and stops roslaunch on exit, error or Ctrl-C. Sets LAUNCH_LOG; fail NAME prints its tail.
PYTHON=${PYTHON:-/usr/bin/python3}
LAUNCH_PID=""

stop_roslaunch() {
  if [ -n "$LAUNCH_PID" ] && kill -0 "$LAUNCH_PID" 2>/dev/null; then
    kill -INT "$LAUNCH_PID" 2>/dev/null || true
    for _ in $(seq 50); do kill -0 "$LAUNCH_PID" 2>/dev/null || break; sleep 0.1; done
    kill -TERM "$LAUNCH_PID" 2>/dev/null || true
    wait "$LAUNCH_PID" 2>/dev/null || true
  fi
}

fail() {
  echo "$1: failed; the node's log: $LAUNCH_LOG" >&2
  tail -n 20 "$LAUNCH_LOG" >&2
  exit 1
}

start_roslaunch() {
  local name=$1 out=$2
  shift 2
  mkdir -p "$out"
  local port
  port=$($PYTHON -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  export ROS_MASTER_URI="http://127.0.0.1:$port"
  export ROS_HOME="$PWD/$out/ros_home"   # logs stay under $out
  LAUNCH_LOG="$out/roslaunch.log"
  trap stop_roslaunch EXIT
  trap 'exit 130' INT TERM
  echo "$name: roslaunch $* (master on port $port, log $LAUNCH_LOG)"
  roslaunch -p "$port" "$@" >"$LAUNCH_LOG" 2>&1 &
  LAUNCH_PID=$!
  # Wait for the master roslaunch starts, so the client does not race it.
  for _ in $(seq 100); do
    $PYTHON -c 'import rosgraph, sys; sys.exit(not rosgraph.is_master_online())' 2>/dev/null && return 0
    kill -0 "$LAUNCH_PID" 2>/dev/null || fail "$name"
    sleep 0.2
  done
  fail "$name"
}
