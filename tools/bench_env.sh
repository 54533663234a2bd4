#!/usr/bin/env bash
# A virtual environment for the benchmarks only: ROS's Python with Debian's packages visible, plus
# Open3D from PyPI (Debian has none), pinned to Debian's NumPy so both sides use the same one.
# Prints the environment's python. Without network or wheel it says so and prints /usr/bin/python3:
# the benchmarks then report Open3D as not installed.
set -uo pipefail
venv=${1:?usage: bench_env.sh VENV_DIR}
if [ -x "$venv/bin/python" ] && "$venv/bin/python" -c 'import open3d' 2>/dev/null; then
  echo "$venv/bin/python"; exit 0
fi
numpy=$(/usr/bin/python3 -c 'import numpy; print(numpy.__version__)')
if /usr/bin/python3 -m venv --system-site-packages "$venv" >&2 &&
   echo "numpy==$numpy" > "$venv/constraints.txt" &&
   "$venv/bin/pip" install -q -c "$venv/constraints.txt" open3d==0.19.0 >&2 &&
   "$venv/bin/python" -c 'import open3d' >&2; then
  echo "$venv/bin/python"
else
  echo "bench_env: Open3D could not be installed; benchmarks run without it" >&2
  echo /usr/bin/python3
fi
