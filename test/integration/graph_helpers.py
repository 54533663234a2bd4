"""Helpers of the integration tests: a private ROS master, node processes, waiting for a condition."""
import os
import pathlib
import signal
import socket
import subprocess
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tools"))
from netns_graph import stop_process, wait_for  # noqa: E402, F401  (wait_for: for the tests)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class RosGraph:
    """A roscore on a free port and the processes started against it; all stopped at teardown."""

    def __init__(self, tmp_path):
        self.env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}", ROS_HOME=str(tmp_path / "ros"),
                        ROS_IP="127.0.0.1")
        self.env.pop("ROS_HOSTNAME", None)
        self.tmp_path = tmp_path
        self.processes = []
        self.start("roscore", ["roscore", "-p", self.env["ROS_MASTER_URI"].rsplit(":", 1)[1]])
        deadline = time.monotonic() + 30
        while subprocess.run(["rostopic", "list"], env=self.env, capture_output=True).returncode != 0:
            if time.monotonic() > deadline:
                raise RuntimeError("roscore did not come up")
            time.sleep(0.3)

    def start(self, name, cmd, cwd=None):
        log = open(self.tmp_path / f"{name}.log", "w")
        proc = subprocess.Popen(cmd, env=self.env, stdout=log, stderr=subprocess.STDOUT, cwd=cwd or self.tmp_path,
                                start_new_session=True)
        proc.name, proc.log_path = name, self.tmp_path / f"{name}.log"
        self.processes.append(proc)
        return proc

    def rosrun(self, name, node, *params, cwd=None):
        return self.start(name, ["rosrun", "example_pcl", node, *params], cwd=cwd)

    stop = staticmethod(stop_process)

    def log(self, proc):
        return proc.log_path.read_text()

    def close(self):
        # SIGINT, not SIGKILL: roscore and roslaunch start their children (rosmaster, rosout, the
        # nodes) in sessions of their own, which only they stop; killed, they would leave them running.
        for proc in reversed(self.processes):
            self.stop(proc, signal.SIGINT, timeout=15)
