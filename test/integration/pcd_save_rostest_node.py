#!/usr/bin/python3
"""rostest node for pcd_save and pcd_publisher, run by pcd_save.test (argument ``stream``) and
pcd_save_rosbag.test (argument ``rosbag``).

Both nodes under test run as subprocesses of this node (so their exit codes and output are
checked), with the Python that runs this node (ROS's), whether or not the devel-space relays exist.
"""
import glob
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest

import numpy as np
import roslib.packages
import rosgraph
import rospy
import rostest
from sensor_msgs.msg import PointCloud2

from example_pcl import pcd
from example_pcl.conversions import cloud_to_array, fields_to_dtype, pack_rgb

PKG = "example_pcl"
TOPIC = "/kinect/depth/points"


def node_command(node_type):
    """The command running a node of this package with this interpreter (ROS's /usr/bin/python3)."""
    matches = roslib.packages.find_node(PKG, node_type)
    if not matches:
        raise RuntimeError(f"cannot find node {node_type} of {PKG}")
    return [sys.executable, matches[0]]


def rich_points(seed, height=96, width=128):
    """An organized cloud with NaN points, rgb and two more fields (float intensity, uint16 ring)."""
    rng = np.random.default_rng(seed)
    dtype = fields_to_dtype([("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 7, 1),
                             ("intensity", 16, 7, 1), ("ring", 20, 4, 1)], 24)
    points = np.zeros((height, width), dtype)
    for c in "xyz":
        points[c] = rng.normal(0, 2, size=(height, width)).astype(np.float32)
    holes = rng.random((height, width)) < 0.15
    for c in "xyz":
        points[c][holes] = np.nan
    points["rgb"] = pack_rgb(rng.integers(0, 256, size=(height, width, 3), dtype=np.uint8)).view(np.float32)
    points["intensity"] = rng.random((height, width)).astype(np.float32) * 1000
    points["ring"] = rng.integers(0, 64, size=(height, width), dtype=np.uint16)
    return points


class Run:
    """A node under test running as a subprocess; output collected for the assertion messages."""

    counter = 0

    def __init__(self, node_type, *args, cwd=None):
        Run.counter += 1
        self.name = f"{node_type}_{os.getpid()}_{Run.counter}"
        self.proc = subprocess.Popen(node_command(node_type) + list(args) + [f"__name:={self.name}"], cwd=cwd,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.output = ""
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.proc.stdout:
            self.output += line

    def wait(self, timeout):
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.stop()
            raise AssertionError(f"{self.name} still running after {timeout} s:\n{self.output}")
        self._reader.join(5)
        return code

    def stop(self, sig=signal.SIGINT):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._reader.join(5)
        return self.proc.returncode


def wait_for(condition, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def subscribed(node_name, topic):
    """True once the master lists ``node_name`` among the subscribers of ``topic``."""
    state = rosgraph.Master("/pcd_save_rostest").getSystemState()
    return any(t == topic and ("/" + node_name) in subs for t, subs in state[1])


class SavedCloudChecks(unittest.TestCase):
    """Assertions shared by both suites."""

    def assert_file_equals_message(self, path, msg, fmt):
        """The PCD file read back equals the message field by field: bits for binary formats, printed precision for ascii."""
        saved = pcd.read_pcd(path)
        sent = cloud_to_array(msg)
        self.assertEqual(saved.format, fmt)
        self.assertEqual(saved.points.shape, sent.shape, "organized shape")
        self.assertEqual(saved.is_dense, msg.is_dense)
        self.assertEqual(set(saved.points.dtype.names), set(sent.dtype.names))
        for name in sent.dtype.names:
            a, b = np.ascontiguousarray(saved.points[name]), np.ascontiguousarray(sent[name])
            if fmt == "ascii" and name != "rgb":
                np.testing.assert_allclose(a.astype(np.float64), b.astype(np.float64), rtol=1e-8, equal_nan=True,
                                           err_msg=f"{path}: field {name} differs beyond print precision")
            # binary formats must be bit-exact; ascii at 9 digits is too (and rgb is its bit pattern in ascii)
            np.testing.assert_array_equal(a.view(np.uint8), b.view(np.uint8), err_msg=f"{path}: field {name}")

    def assert_sidecar_matches(self, path, msg, topic):
        meta = json.load(open(path + ".json"))
        self.assertEqual(meta["frame_id"], msg.header.frame_id)
        self.assertEqual((meta["stamp"]["secs"], meta["stamp"]["nsecs"]), (msg.header.stamp.secs, msg.header.stamp.nsecs))
        self.assertEqual(meta["topic"], topic)
        self.assertEqual((meta["width"], meta["height"]), (msg.width, msg.height))
        return meta


class StreamTests(SavedCloudChecks):
    """pcd_publisher streams a PCD file; pcd_save's snapshots, timeout, unwritable destination, Ctrl-C."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="pcd_save_rostest_")
        cls.source = os.path.join(cls.tmp, "source.pcd")
        pcd.write_pcd(cls.source, rich_points(seed=11), fmt="binary", is_dense=False)
        cls.received = {}
        cls.lock = threading.Lock()
        cls.sub = rospy.Subscriber(TOPIC, PointCloud2, cls.on_cloud, queue_size=10, buff_size=1 << 24)
        cls.publisher = Run("pcd_publisher", f"_file:={cls.source}", "_rate:=10",
                            "_frame_id:=camera_depth_optical_frame")
        wait_for(lambda: len(cls.received) >= 2, 30, "pcd_publisher's clouds")

    @classmethod
    def tearDownClass(cls):
        cls.publisher.stop()
        cls.sub.unregister()
        shutil.rmtree(cls.tmp, ignore_errors=True)

    @classmethod
    def on_cloud(cls, msg):
        with cls.lock:
            cls.received[(msg.header.stamp.secs, msg.header.stamp.nsecs)] = msg

    def published(self, meta):
        """The message pcd_publisher published with the stamp a sidecar records."""
        wait_for(lambda: (meta["stamp"]["secs"], meta["stamp"]["nsecs"]) in self.received, 5, "the saved stamp")
        return self.received[(meta["stamp"]["secs"], meta["stamp"]["nsecs"])]

    def test_publisher_streams_the_file(self):
        """pcd_publisher publishes the file's cloud (every field, organized, NaNs) in the requested frame at ~rate."""
        with self.lock:
            msgs = sorted(self.received.values(), key=lambda m: m.header.stamp.to_sec())
        self.assertEqual(msgs[-1].header.frame_id, "camera_depth_optical_frame")
        self.assertFalse(msgs[-1].is_dense)
        self.assert_file_equals_message(self.source, msgs[-1], "binary")
        count = len(self.received)
        time.sleep(2.0)
        self.assertGreaterEqual(len(self.received) - count, 14, "expected about 10 Hz")

    def check_snapshot(self, fmt):
        out_dir = tempfile.mkdtemp(dir=self.tmp, prefix=fmt + "_")
        run = Run("pcd_save", f"_format:={fmt}", "_timeout:=30", cwd=out_dir)  # default ~file: ./test_pcd.pcd
        code = run.wait(60)
        self.assertEqual(code, 0, run.output)
        path = os.path.join(out_dir, "test_pcd.pcd")
        self.assertIn(path, run.output, "pcd_save says where it wrote")
        self.assertEqual(sorted(os.listdir(out_dir)), ["test_pcd.pcd", "test_pcd.pcd.json"])
        meta = json.load(open(path + ".json"))
        msg = self.published(meta)
        self.assert_sidecar_matches(path, msg, TOPIC)
        self.assert_file_equals_message(path, msg, fmt)

    def test_snapshot_ascii(self):
        """Default run: the next cloud to ./test_pcd.pcd in ascii, equal to the published one to print precision; exit 0."""
        self.check_snapshot("ascii")

    def test_snapshot_binary(self):
        """binary: the saved file equals the published cloud bit for bit, frame_id and stamp in the sidecar."""
        self.check_snapshot("binary")

    def test_snapshot_binary_compressed(self):
        """binary_compressed: the saved file equals the published cloud bit for bit."""
        self.check_snapshot("binary_compressed")

    def test_count_writes_numbered_files(self):
        """~count 3: three numbered files with sidecars, consecutive published clouds, then exit 0."""
        out = os.path.join(tempfile.mkdtemp(dir=self.tmp), "snap.pcd")
        run = Run("pcd_save", f"_file:={out}", "_format:=binary", "_count:=3", "_timeout:=30")
        self.assertEqual(run.wait(60), 0, run.output)
        paths = sorted(glob.glob(out[:-4] + "_*.pcd"))
        self.assertEqual([os.path.basename(p) for p in paths], ["snap_000000.pcd", "snap_000001.pcd", "snap_000002.pcd"])
        for path in paths:
            meta = json.load(open(path + ".json"))
            self.assert_file_equals_message(path, self.published(meta), "binary")
        self.assertIn("dropped 0", run.output)

    def test_timeout(self):
        """No cloud within ~timeout: a clear message naming the topic, exit 2, no file."""
        out_dir = tempfile.mkdtemp(dir=self.tmp)
        start = time.monotonic()
        run = Run("pcd_save", "_timeout:=1.5", "kinect/depth/points:=/no/such/points", cwd=out_dir)
        code = run.wait(30)
        self.assertEqual(code, 2, run.output)
        self.assertIn("no cloud on /no/such/points within 1.5 s", run.output)
        self.assertLess(time.monotonic() - start, 20)
        self.assertEqual(os.listdir(out_dir), [])

    def test_unwritable_destination(self):
        """An unwritable ~file is reported at start-up, without waiting for a cloud (no timeout set), exit 1."""
        blocker = os.path.join(self.tmp, "a_regular_file")
        open(blocker, "w").close()
        for bad in (os.path.join(blocker, "out.pcd"), os.path.join(self.tmp, "no", "such", "dir", "out.pcd")):
            run = Run("pcd_save", f"_file:={bad}", "kinect/depth/points:=/no/such/points")
            self.assertEqual(run.wait(30), 1, run.output)
            self.assertIn(f"cannot save to '{bad}'", run.output)

    def test_sigint_in_continuous_mode(self):
        """Ctrl-C in ~count 0 mode: exit 0 promptly; every file complete with its sidecar, no temporary file left."""
        out_dir = tempfile.mkdtemp(dir=self.tmp)
        run = Run("pcd_save", f"_file:={out_dir}/c.pcd", "_format:=binary_compressed", "_count:=0")
        wait_for(lambda: len(glob.glob(os.path.join(out_dir, "*.json"))) >= 3, 30, "three snapshots")
        start = time.monotonic()
        self.assertEqual(run.stop(signal.SIGINT), 0, run.output)
        self.assertLess(time.monotonic() - start, 10)
        self.assertIn("pcd_save done: saved", run.output)
        names = os.listdir(out_dir)
        self.assertEqual([n for n in names if n.startswith(".")], [], "temporary files left")
        pcds = sorted(n for n in names if n.endswith(".pcd"))
        self.assertEqual(sorted(n for n in names if n.endswith(".json")), [n + ".json" for n in pcds])
        for name in pcds:
            path = os.path.join(out_dir, name)
            self.assert_file_equals_message(path, self.published(json.load(open(path + ".json"))), "binary_compressed")


class RosbagTests(SavedCloudChecks):
    """A recorded stream replayed with `rosbag play` feeds pcd_save like a sensor."""

    def test_rosbag_replay(self):
        """Four clouds recorded with the rosbag API and replayed: four numbered files equal to them, in order."""
        import rosbag
        from example_pcl.conversions import array_to_cloud

        tmp = tempfile.mkdtemp(prefix="pcd_save_rosbag_")
        try:
            bag_path = os.path.join(tmp, "kinect.bag")
            msgs = []
            with rosbag.Bag(bag_path, "w") as bag:
                for i in range(4):
                    msg = array_to_cloud(rich_points(seed=100 + i, height=48, width=64), frame_id="kinect_rgb_optical",
                                         stamp=rospy.Time(1355496176, 332395000 + i * 33000000), is_dense=False)
                    msg.header.seq = 7 + i
                    bag.write(TOPIC, msg, t=msg.header.stamp)
                    msgs.append(msg)
            out = os.path.join(tmp, "bag.pcd")
            run = Run("pcd_save", f"_file:={out}", "_format:=binary", "_count:=4", "_timeout:=60")
            wait_for(lambda: subscribed(run.name, TOPIC), 30, "pcd_save's subscription")
            play = subprocess.run(["rosbag", "play", "--quiet", "-d", "1", bag_path], stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True, timeout=120)
            self.assertEqual(play.returncode, 0, play.stdout)
            code = run.wait(60)
            self.assertEqual(code, 0, run.output)
            self.assertIn("dropped 0", run.output)
            for i, msg in enumerate(msgs):
                path = f"{out[:-4]}_{i:06d}.pcd"
                meta = self.assert_sidecar_matches(path, msg, TOPIC)
                self.assertEqual(meta["seq"], 7 + i)
                self.assert_file_equals_message(path, msg, "binary")
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    suite = sys.argv[1] if len(sys.argv) > 1 and not sys.argv[1].startswith("__") else "stream"
    rospy.init_node("pcd_save_rostest", anonymous=True)
    cases = {"stream": ("pcd_save_stream", StreamTests), "rosbag": ("pcd_save_rosbag", RosbagTests)}
    rostest.rosrun(PKG, *cases[suite], sys.argv)
