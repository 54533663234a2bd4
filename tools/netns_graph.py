#!/usr/bin/python3
"""A ROS graph spread over separate hosts made with Linux network namespaces (ip netns + veth).

    sudo bash -c 'source build/ws/devel/setup.bash && tools/netns_graph.py'

Three hosts on one private link (a bridge in a fourth namespace): `master` (10.231.0.1) runs
roscore, `sensor` (10.231.0.2) runs pcd_publisher, `perception` (10.231.0.3) runs pcd_save and
find_can. Every process gets ROS_MASTER_URI=http://10.231.0.1:11311 and its own host's ROS_IP, as
on real machines. The scenario: a snapshot crosses from sensor to perception intact; the
publisher is killed and restarted and pcd_save, in continuous mode, picks the stream up again; a
service call from the sensor host reaches find_can on the perception host. Everything the script
creates (namespaces, links, processes) is removed on exit. Needs root (CAP_NET_ADMIN).
"""
import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time

SUBNET = "10.231.0"
HOSTS = {"master": 1, "sensor": 2, "perception": 3}


def sh(*args, check=True):
    return subprocess.run(args, check=check, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def stop_process(proc, sig=signal.SIGINT, timeout=20):
    """Signals the process group of proc (started with start_new_session=True) and waits; SIGKILL
    if it does not end within timeout s. Returns its exit status."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, sig)
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        except ProcessLookupError:
            pass
    return proc.returncode


def wait_for(predicate, timeout, step=0.1):
    """True as soon as predicate() is, False once timeout s have passed."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(step)
    return False


class NetnsGraph:
    """Network namespaces as hosts on one bridged link; a context manager that cleans up after itself."""

    def __init__(self, tag=None):
        self.tag = tag or str(os.getpid())
        self.switch = f"epcl{self.tag}sw"
        self.namespaces = {host: f"epcl{self.tag}{host[:4]}" for host in HOSTS}
        self.processes = []
        self.master_uri = f"http://{self.ip('master')}:11311"

    @staticmethod
    def ip(host):
        return f"{SUBNET}.{HOSTS[host]}"

    def __enter__(self):
        try:
            sh("ip", "netns", "add", self.switch)
            sh("ip", "netns", "exec", self.switch, "ip", "link", "add", "br0", "type", "bridge")
            sh("ip", "netns", "exec", self.switch, "ip", "link", "set", "br0", "up")
            for i, (host, ns) in enumerate(self.namespaces.items()):
                sh("ip", "netns", "add", ns)
                # veth pair made inside the switch namespace, one end moved to the host as eth0
                sh("ip", "netns", "exec", self.switch, "ip", "link", "add", f"p{i}", "type", "veth", "peer", "name",
                   f"h{i}")
                sh("ip", "netns", "exec", self.switch, "ip", "link", "set", f"h{i}", "netns", ns, "name", "eth0")
                sh("ip", "netns", "exec", self.switch, "ip", "link", "set", f"p{i}", "master", "br0", "up")
                sh("ip", "netns", "exec", ns, "ip", "addr", "add", f"{self.ip(host)}/24", "dev", "eth0")
                sh("ip", "netns", "exec", ns, "ip", "link", "set", "eth0", "up")
                sh("ip", "netns", "exec", ns, "ip", "link", "set", "lo", "up")
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc):
        # SIGINT, not SIGKILL: roscore starts rosmaster and rosout in sessions of their own, which
        # only it stops; killed, it would leave them running.
        for proc in reversed(self.processes):
            self.stop(proc, signal.SIGINT, timeout=15)
        for ns in [*self.namespaces.values(), self.switch]:
            sh("ip", "netns", "del", ns, check=False)

    def env(self, host, **extra):
        env = dict(os.environ, ROS_MASTER_URI=self.master_uri, ROS_IP=self.ip(host), **extra)
        env.pop("ROS_HOSTNAME", None)
        return env

    def start(self, host, cmd, log_path, cwd=None, **env):
        """Starts cmd on host (in its namespace), output to log_path; returns the Popen."""
        log = open(log_path, "w")
        proc = subprocess.Popen(["ip", "netns", "exec", self.namespaces[host], *cmd], env=self.env(host, **env),
                                stdout=log, stderr=subprocess.STDOUT, cwd=cwd, start_new_session=True)
        proc.log_path = log_path
        self.processes.append(proc)
        return proc

    def run(self, host, cmd, timeout=60, **env):
        return subprocess.run(["ip", "netns", "exec", self.namespaces[host], *cmd], env=self.env(host, **env),
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=timeout)

    stop = staticmethod(stop_process)

    def wait_for_master(self, timeout=30):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.run("perception", ["rostopic", "list"], timeout=10).returncode == 0:
                return
            time.sleep(0.5)
        raise RuntimeError(f"no ROS master at {self.master_uri} after {timeout} s")


def netns_available():
    """None when network namespaces can be made here, else the reason they cannot."""
    if os.geteuid() != 0:
        return "network namespaces need root (CAP_NET_ADMIN)"
    probe = f"epclprobe{os.getpid()}"
    result = sh("ip", "netns", "add", probe, check=False)
    if result.returncode != 0:
        return f"'ip netns add' is not permitted here: {result.stdout.strip()}"
    sh("ip", "netns", "del", probe, check=False)
    return None


def run_scenario(scene, workdir, log=print):
    """The multi-host scenario; returns a dict of what was observed. Raises on a broken step."""
    from example_pcl import pcd

    ros_home = os.path.join(workdir, "ros_home")
    results = {}
    with NetnsGraph() as graph:
        graph.start("master", ["roscore", "-p", "11311"], os.path.join(workdir, "roscore.log"), ROS_HOME=ros_home)
        graph.wait_for_master()
        log(f"master up at {graph.master_uri}")

        publisher_cmd = ["rosrun", "example_pcl", "pcd_publisher", f"_file:={scene}", "_rate:=5",
                         "_frame_id:=camera_depth_optical_frame"]
        publisher = graph.start("sensor", publisher_cmd, os.path.join(workdir, "publisher1.log"), ROS_HOME=ros_home)

        snapshot = os.path.join(workdir, "snapshot.pcd")
        saved = graph.run("perception", ["rosrun", "example_pcl", "pcd_save", f"_file:={snapshot}",
                                         "_format:=binary", "_timeout:=30"], timeout=60, ROS_HOME=ros_home)
        if saved.returncode != 0:
            raise RuntimeError(f"pcd_save across hosts failed:\n{saved.stdout}")
        sent, got = pcd.read_pcd(scene).points, pcd.read_pcd(snapshot).points
        results["snapshot_intact"] = all(
            sent[n].tobytes() == got[n].tobytes() for n in sent.dtype.names) and sent.shape == got.shape
        log(f"snapshot across hosts intact: {results['snapshot_intact']}")

        stream_dir = os.path.join(workdir, "stream")
        os.makedirs(stream_dir)
        saver = graph.start("perception", ["rosrun", "example_pcl", "pcd_save", f"_file:={stream_dir}/s.pcd",
                                           "_format:=binary", "_count:=0"], os.path.join(workdir, "saver.log"),
                            ROS_HOME=ros_home)

        def saved_count():
            return len([f for f in os.listdir(stream_dir) if f.endswith(".pcd")])

        if not wait_for(lambda: saved_count() >= 2, 30):
            raise RuntimeError("continuous pcd_save received nothing across hosts")
        graph.stop(publisher, signal.SIGKILL)
        time.sleep(2.0)
        before = saved_count()
        time.sleep(1.0)
        results["silent_while_publisher_dead"] = saved_count() == before
        graph.start("sensor", publisher_cmd, os.path.join(workdir, "publisher2.log"), ROS_HOME=ros_home)
        results["resumed_after_restart"] = wait_for(lambda: saved_count() >= before + 2, 30)
        log(f"publisher killed at {before} files; stream picked up again after restart: "
            f"{results['resumed_after_restart']} ({saved_count()} files)")
        graph.stop(saver, signal.SIGINT)
        last = sorted(f for f in os.listdir(stream_dir) if f.endswith(".pcd"))[-1]
        got = pcd.read_pcd(os.path.join(stream_dir, last)).points
        results["resumed_snapshot_intact"] = all(sent[n].tobytes() == got[n].tobytes() for n in sent.dtype.names)

        finder = graph.start("perception", ["rosrun", "example_pcl", "find_can", f"_pcd_file:={scene}"],
                             os.path.join(workdir, "find_can.log"), ROS_HOME=ros_home)
        wait = graph.run("sensor", ["rosservice", "call", "--wait", "/process_mode", "1"], timeout=60,
                         ROS_HOME=ros_home)
        results["service_across_hosts"] = wait.returncode == 0 and "success: False" in wait.stdout
        log(f"service call sensor -> find_can on perception: {wait.stdout.strip()!r}")
        graph.stop(finder, signal.SIGINT)
    return results


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", help="PCD file the sensor host streams (default: the bundled scene)")
    args = parser.parse_args()
    reason = netns_available()
    if reason:
        print(f"netns_graph: cannot run: {reason}")
        return 2
    if args.scene:
        scene = os.path.abspath(args.scene)
    else:
        import rospkg

        scene = os.path.join(rospkg.RosPack().get_path("example_pcl"), "data", "test_pcd.pcd")
    with tempfile.TemporaryDirectory(prefix="netns_graph_") as workdir:
        results = run_scenario(scene, workdir)
    print(results)
    return 0 if all(results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
