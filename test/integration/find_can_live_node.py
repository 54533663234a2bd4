#!/usr/bin/python3
"""rostest node of find_can_live.test: find_can with ~cloud_topic on a stream this node publishes,
tuned through dynamic_reconfigure while it runs.

The stream (``cloud``, frame live_camera, 3 Hz, each message stamped when sent) shows a generated
scene with one can, then one with two cans. Every output of find_can is recorded in arrival order,
so each call's own messages are checked (another subscription could get an earlier call's). The
tests run in the order of their names, each from the state the previous one left.
"""
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
from find_can_helpers import PKG, pixel_rect, pose_error, table_rect

from example_pcl import scene as sc
from example_pcl.conversions import array_to_cloud, make_points
from example_pcl.find_can_client import FindCanClient
from example_pcl.select_patch import select_points

FRAME = "live_camera"
SCENES = {"one": sc.SceneSpec(seed=3),
          "two": sc.SceneSpec(camera_distance=1.2, tilt=0.8,
                              cans=[(-0.1, 0.0, 0.033, 0.122), (0.12, 0.05, 0.045, 0.15)], seed=11)}
# What each mode publishes when it succeeds (mode 0 also clears the can outputs).
PUBLISHED = {0: ("kinect_pointcloud", "plane_model", "can_marker", "can_poses", "can_markers", "cans"),
             1: ("plane_model",),
             2: ("plane_model", "can_pose", "can_marker", "cans"),
             3: ("plane_model", "can_pose", "can_marker", "cans"),
             4: ("kinect_pointcloud", "plane_model", "can_pose", "can_marker", "can_poses", "can_markers", "cans")}


class Stream:
    """Publishes the shown scene's cloud on `cloud` at 3 Hz, like a camera (not latched), each
    message stamped with the time it is sent; stamps[name]: every stamp sent of a scene."""

    def __init__(self, scenes):
        from sensor_msgs.msg import PointCloud2

        self.clouds = {name: array_to_cloud(make_points(s.xyz, s.rgb), frame_id=FRAME) for name, s in scenes.items()}
        self.stamps = {name: set() for name in scenes}
        self.shown = None
        self.sent = 0
        self.cond = threading.Condition()
        self.pub = rospy.Publisher("cloud", PointCloud2, queue_size=1)
        threading.Thread(target=self.run, daemon=True).start()

    def show(self, name):
        with self.cond:
            self.shown = name

    def wait_for_more(self, count, timeout=30.0):
        """Returns once `count` more clouds were sent."""
        with self.cond:
            target = self.sent + count
            assert self.cond.wait_for(lambda: self.sent >= target, timeout), f"the stream sent no {count} clouds"

    def run(self):
        rate = rospy.Rate(3)
        while not rospy.is_shutdown():
            with self.cond:
                if self.shown is not None:
                    msg = self.clouds[self.shown]
                    msg.header.stamp = rospy.Time.now()
                    self.stamps[self.shown].add(msg.header.stamp)
                    self.pub.publish(msg)
                    self.sent += 1
                    self.cond.notify_all()
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                return


class Outputs:
    """Every message find_can publishes on its outputs, per topic in arrival order."""

    def __init__(self):
        from geometry_msgs.msg import PoseArray, PoseStamped
        from sensor_msgs.msg import PointCloud2
        from visualization_msgs.msg import Marker, MarkerArray

        from example_pcl.msg import CanArray

        kinds = {"kinect_pointcloud": PointCloud2, "plane_model": PointCloud2, "can_pose": PoseStamped,
                 "can_marker": Marker, "can_poses": PoseArray, "can_markers": MarkerArray, "cans": CanArray}
        self.received = {topic: [] for topic in kinds}
        self.cond = threading.Condition()
        self.subscribers = [rospy.Subscriber(topic, kind, self.store, callback_args=topic, queue_size=20)
                            for topic, kind in kinds.items()]

    def store(self, msg, topic):
        with self.cond:
            self.received[topic].append(msg)
            self.cond.notify_all()

    def mark(self):
        """How many messages arrived so far, per topic."""
        with self.cond:
            return {topic: len(messages) for topic, messages in self.received.items()}

    def next_after(self, mark, topics, timeout=10.0):
        """The first message after `mark` on each of `topics`, by topic."""
        with self.cond:
            done = self.cond.wait_for(lambda: all(len(self.received[t]) > mark[t] for t in topics), timeout)
            assert done, f"no message after the call on {[t for t in topics if len(self.received[t]) <= mark[t]]}"
            return {topic: self.received[topic][mark[topic]] for topic in topics}


def headers(msg):
    """(header, True when it must carry the cloud's stamp) of a message, or of each marker of a
    MarkerArray: a DELETE or DELETEALL marker is stamped 0, as rviz takes it (it shows no data)."""
    from visualization_msgs.msg import Marker

    markers = msg.markers if hasattr(msg, "markers") else [msg] if isinstance(msg, Marker) else []
    if not markers:
        return [(msg.header, True)]
    return [(m.header, m.action == Marker.ADD) for m in markers]


class Live(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        from rosgraph_msgs.msg import Log

        cls.logs = []  # (level, text) of find_can's messages on /rosout
        cls.log_cond = threading.Condition()
        cls.rosout = rospy.Subscriber("/rosout", Log, cls.on_rosout, queue_size=100)
        cls.outputs = Outputs()
        cls.scenes = {name: sc.generate_scene(spec) for name, spec in SCENES.items()}
        cls.stream = Stream(cls.scenes)
        cls.client = FindCanClient(frame_id=FRAME, timeout=60.0)
        deadline = time.monotonic() + 60
        while cls.stream.pub.get_num_connections() == 0:
            assert time.monotonic() < deadline, "find_can does not subscribe to cloud"
            time.sleep(0.05)

    @classmethod
    def on_rosout(cls, log):
        if log.name == "/find_can":
            with cls.log_cond:
                cls.logs.append((log.level, log.msg))
                cls.log_cond.notify_all()

    def wait_for_log(self, level, fragment, timeout=10.0):
        with self.log_cond:
            found = self.log_cond.wait_for(lambda: any(lv == level and fragment in t for lv, t in self.logs), timeout)
        self.assertTrue(found, f"find_can logged no '{fragment}' (level {level}): {self.logs[-5:]}")

    def call(self, mode):
        """process_mode(mode): (success, message, {topic: the message the call published})."""
        mark = self.outputs.mark()
        ok, message = self.client.call(mode)
        return ok, message, self.outputs.next_after(mark, PUBLISHED[mode]) if ok else {}

    def call_until_taken(self, mode, name, after=None, timeout=30.0):
        """Calls `mode` (0 or 4) until it took a cloud of scene `name` stamped after `after`: the
        first cloud may be on its way, and the node has the newest cloud only once it arrived."""
        deadline = time.monotonic() + timeout
        while True:
            ok, message, out = self.call(mode)
            if ok:
                stamp = out["kinect_pointcloud"].header.stamp
                if stamp in self.stream.stamps[name] and (after is None or stamp > after):
                    return message, out
            self.assertLess(time.monotonic(), deadline, f"mode {mode} took no cloud of scene {name}: {message}")
            time.sleep(0.2)

    def assert_stamped(self, out, stamp):
        """Each message of a call is in the cloud's frame with the cloud's stamp."""
        for topic, msg in out.items():
            for head, stamped in headers(msg):
                self.assertEqual(head.frame_id, FRAME, topic)
                if stamped:
                    self.assertEqual(head.stamp, stamp, topic)

    def assert_cans(self, poses, truth_cans):
        """One pose per true can, each within 3 mm and 1 deg of it."""
        from geometry_msgs.msg import PoseStamped

        self.assertEqual(len(poses), len(truth_cans))
        matched = set()
        for pose in poses:
            errors = [pose_error(PoseStamped(pose=pose), can) for can in truth_cans]
            i = int(np.argmin([centre for centre, _ in errors]))
            self.assertLess(errors[i][0], 3e-3)
            self.assertLess(errors[i][1], 1.0)
            matched.add(i)
        self.assertEqual(len(matched), len(truth_cans))

    def test_1_walkthrough_on_the_newest_cloud(self):
        """Modes 0-3 with selections in the cloud's frame: mode 0 takes a cloud of the stream and
        publishes it on kinect_pointcloud; modes 1-3 stay on it while newer clouds arrive; every
        output carries its stamp and frame, the can within 3 mm of the truth."""
        scene = self.scenes["one"]
        self.stream.show("one")
        self.assertGreater(self.client.select(select_points(scene.xyz, rect=table_rect(scene.labels))), 0)
        _, out = self.call_until_taken(0, "one")
        stamp = out["kinect_pointcloud"].header.stamp
        self.assert_stamped(out, stamp)
        self.stream.wait_for_more(2)  # the node now has newer clouds, which modes 1-3 must not take
        ok, message, out = self.call(1)
        self.assertTrue(ok, message)
        self.assert_stamped(out, stamp)
        self.assertGreater(self.client.select(select_points(scene.xyz, rect=pixel_rect(scene.labels,
                                                                                        sc.LABEL_CAN_SIDE))), 0)
        for mode in (2, 3):
            ok, message, out = self.call(mode)
            self.assertTrue(ok, message)
            self.assert_stamped(out, stamp)
        centre, axis = pose_error(out["can_pose"], scene.truth["cans"][0])
        self.assertLess(centre, 3e-3)
        self.assertLess(axis, 1.0)
        type(self).walkthrough_stamp = stamp

    def test_2_mode_4_takes_the_newest_cloud(self):
        """Mode 4 takes a cloud newer than mode 0's; every output carries its stamp and frame,
        and can_poses the scene's can."""
        message, out = self.call_until_taken(4, "one", after=self.walkthrough_stamp)
        self.assertIn("found 1 can(s)", message)
        self.assert_stamped(out, out["kinect_pointcloud"].header.stamp)
        self.assert_cans(out["can_poses"].poses, self.scenes["one"].truth["cans"])

    def test_3_a_new_scene_on_the_stream(self):
        """Once the stream shows another scene, mode 4 finds its two cans, stamped with its cloud."""
        self.stream.show("two")
        message, out = self.call_until_taken(4, "two")
        self.assertIn("found 2 can(s)", message)
        self.assert_stamped(out, out["kinect_pointcloud"].header.stamp)
        self.assert_cans(out["can_poses"].poses, self.scenes["two"].truth["cans"])
        self.assertEqual(len(out["cans"].cans), 2)

    def test_4_reconfigure_applies_to_the_next_call(self):
        """dynamic_reconfigure: max_radius 40 mm is logged and the next mode 4 finds only the 33 mm
        can; min_radius above max_radius is refused (logged, previous value kept, the search
        unchanged); max_radius back at 80 mm finds both cans again."""
        from dynamic_reconfigure.client import Client

        truth = self.scenes["two"].truth["cans"]
        reconfigure = Client("find_can", timeout=30)
        self.assertEqual(reconfigure.update_configuration({"max_radius": 0.04})["max_radius"], 0.04)
        self.wait_for_log(2, "reconfigured (from the next call): max_radius 0.08 -> 0.04")
        ok, message, out = self.call(4)
        self.assertTrue(ok and "found 1 can(s)" in message, message)
        self.assert_cans(out["can_poses"].poses, truth[:1])

        self.assertEqual(reconfigure.update_configuration({"min_radius": 0.05})["min_radius"], 0.015)
        self.wait_for_log(8, "reconfigure refused")
        ok, message, _ = self.call(4)
        self.assertTrue(ok and "found 1 can(s)" in message, message)

        reconfigure.update_configuration({"max_radius": 0.08})
        self.wait_for_log(2, "max_radius 0.04 -> 0.08")
        ok, message, out = self.call(4)
        self.assertTrue(ok and "found 2 can(s)" in message, message)
        self.assert_cans(out["can_poses"].poses, truth)


if __name__ == "__main__":
    rospy.init_node("find_can_live_test")
    rostest.rosrun(PKG, "find_can_live", Live)
