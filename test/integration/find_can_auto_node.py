#!/usr/bin/python3
"""rostest node of find_can_auto.test: process_mode 4 (FIND_CAN_AUTO) through the node, checked
against the scenes' ground truth.

The bundled scene is served by the find_can of find_can.launch (started by the .test file with
up_frame:=base_link). The generated scenes are written to a temporary directory in setUpClass and
each is loaded by its own find_can in a namespace (find_can_helpers.find_can_node):

- ``/tilted``: three cans (radii 33, 25 and 45 mm) and a box, the camera pitched 0.5 rad down, so
  "up" is none of the camera's axes; ``~frame_id`` tilted_camera, ``~up_frame`` tilted_base;
- ``/empty``: a table with only a box; no ``~up_frame``;
- ``/wall`` and ``/wall_up``: a grazing view of two cans before a box whose face is the largest
  plane in view, without and with ``~up_frame`` (wall_base, the table's frame).

The tests run in the order of their names, each from the state the previous one left: the
tilted scene's up transform is first missing, then sent, then changed and restored.
"""
import json
import os
import pathlib
import re
import shutil
import sys
import tempfile
import threading
import time
import unittest
from contextlib import ExitStack

import numpy as np
import roslib.packages
import rosnode
import rospy
import rostest
from shape_msgs.msg import SolidPrimitive
from visualization_msgs.msg import Marker
from find_can_helpers import (PKG, call_mode, call_mode_until, find_can_node, pixel_rect, pose_error,
                              pose_reaches_new_process, send_static_transforms, table_rect)

from example_pcl import scene as sc
from example_pcl.msg import CanArray
from example_pcl.select_patch import select_points
from example_pcl.find_can_client import FindCanClient, walkthrough
from example_pcl.messages import matrix_from_pose
from example_pcl.pcd import write_cloud

DATA = pathlib.Path(roslib.packages.get_pkg_dir(PKG)) / "data"
TILTED = sc.SceneSpec(camera_distance=1.1, tilt=0.5,
                      cans=[(0.0, 0.0, 0.033, 0.122), (-0.15, 0.06, 0.025, 0.10), (0.12, -0.08, 0.045, 0.15)],
                      boxes=[(0.18, 0.05, 0.1, 0.06, 0.12)], seed=5)
EMPTY = sc.SceneSpec(cans=[], boxes=[(0.0, 0.0, 0.1, 0.06, 0.12)], seed=2)
# A grazing view of two cans before a "wall" (a box 0.5 m x 0.4 m whose face is the largest plane in
# view): loaded twice, /wall without a prior, /wall_up with ~up_frame wall_base (the table frame).
WALL = sc.SceneSpec(camera_distance=1.0, tilt=0.2, cans=[(0.0, 0.0, 0.033, 0.122), (0.12, -0.05, 0.04, 0.1)],
                    boxes=[(0.0, 0.25, 0.5, 0.05, 0.4)], seed=7)
WALKED_CAN = 0  # the tilted scene's can the walkthrough registers: the node's ~can_radius, 33 mm
# A robot's base: its origin on the floor, 0.75 m below the table top and 0.4 m to the right of its
# centre (table frame +x); z up, x and y along the table's.
BASE_FROM_TABLE = np.array([[1.0, 0, 0, -0.4], [0, 1, 0, 0], [0, 0, 1, 0.75], [0, 0, 0, 1]])
# The same base tipped over 90 deg about its y axis: its +z then lies along the table.
TIPPED = np.array([[0.0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1]])
PRIOR = re.compile(r"up prior \((-?\d+\.\d+), (-?\d+\.\d+), (-?\d+\.\d+)\) \(\+z of (\w+)\)")


def transform(pose):
    """4x4 of a geometry_msgs/Pose."""
    return matrix_from_pose(pose)


def can_errors(pose, can):
    """(centre error in m, axis error in deg) of a geometry_msgs/Pose against a ground-truth can."""
    from geometry_msgs.msg import PoseStamped

    return pose_error(PoseStamped(pose=pose), can)


def same_pose(a, b):
    """Two geometry_msgs/Pose are the same transform (within float64 rounding)."""
    return np.allclose(transform(a), transform(b), atol=1e-9)


def latest(ns, topic, kind):
    """The message a subscriber connecting now gets on a latched topic (fails when none comes)."""
    return rospy.wait_for_message(f"{ns}/{topic}", kind, timeout=10)


class MarkerDisplay:
    """What rviz's MarkerArray display shows of a topic: each array's markers applied in order as
    rviz does (DELETEALL clears the display, DELETE removes its (ns, id), ADD sets it)."""

    def __init__(self, topic):
        from visualization_msgs.msg import MarkerArray

        self.topic = topic
        self.shown = {}
        self.arrays = 0
        self._cond = threading.Condition()
        self._sub = rospy.Subscriber(topic, MarkerArray, self._apply, queue_size=10)

    def _apply(self, msg):
        from visualization_msgs.msg import Marker

        with self._cond:
            for marker in msg.markers:
                if marker.action == Marker.DELETEALL:
                    self.shown.clear()
                elif marker.action == Marker.DELETE:
                    self.shown.pop((marker.ns, marker.id), None)
                else:
                    self.shown[(marker.ns, marker.id)] = marker
            self.arrays += 1
            self._cond.notify_all()

    def wait_until(self, done, timeout=10.0):
        """The markers shown once done(shown) holds after a new array; fails after `timeout` s."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not (self.arrays and done(self.shown)):
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"{self.topic} still shows {sorted(self.shown)} after {timeout} s")
                self._cond.wait(left)
            return dict(self.shown)


class Auto(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        import tf2_ros
        from rosgraph_msgs.msg import Log

        cls.tmp = tempfile.mkdtemp(prefix="find_can_auto_")
        cls.error_logs = []  # (node, text) of every ERROR on /rosout
        cls.rosout = rospy.Subscriber("/rosout", Log, cls.on_rosout, queue_size=100)
        cls.scenes = {}
        cls.nodes = ExitStack()
        try:
            for name, spec, params in (("tilted", TILTED, {"frame_id": "tilted_camera", "up_frame": "tilted_base"}),
                                       ("empty", EMPTY, {}),
                                       ("wall", WALL, {}),
                                       ("wall_up", WALL, {"frame_id": "wall_camera", "up_frame": "wall_base"})):
                scene = sc.generate_scene(spec)
                path = os.path.join(cls.tmp, f"{name}.pcd")
                write_cloud(path, scene.xyz, rgb=scene.rgb)
                cls.nodes.enter_context(find_can_node(f"/{name}", path, os.path.join(cls.tmp, f"{name}.log"),
                                                      **params))
                cls.scenes[name] = scene
        except BaseException:
            cls.nodes.close()
            raise
        bundled = np.asarray(json.loads((DATA / "test_pcd.json").read_text())["camera_from_table"])
        cls.transforms = {("base_link", "world"): BASE_FROM_TABLE @ np.linalg.inv(bundled),
                          ("wall_base", "wall_camera"): sc.camera_pose(WALL)}
        cls.broadcaster = tf2_ros.StaticTransformBroadcaster()
        send_static_transforms(cls.broadcaster, cls.transforms)  # tilted_base -> tilted_camera not yet

    @classmethod
    def on_rosout(cls, log):
        if log.level == log.ERROR:
            cls.error_logs.append((log.name, log.msg))

    @classmethod
    def tearDownClass(cls):
        cls.nodes.close()
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def send_tilted_base(self, T_base_from_table):
        """Sends tilted_base -> tilted_camera for a base placed so in the tilted scene's table frame;
        returns the base's +z in the camera frame, the up prior the node should use."""
        T = T_base_from_table @ sc.camera_pose(TILTED)  # camera_pose: table from camera
        send_static_transforms(self.broadcaster, {**self.transforms, ("tilted_base", "tilted_camera"): T})
        return np.linalg.inv(T)[:3, 2]

    def assert_prior(self, message, expected, frame):
        match = PRIOR.search(message)
        self.assertIsNotNone(match, message)
        np.testing.assert_allclose([float(v) for v in match.groups()[:3]], expected, atol=1.5e-3, err_msg=message)
        self.assertEqual(match.group(4), frame)

    def assert_alive(self, ns):
        self.assertTrue(rosnode.rosnode_ping(f"{ns}/find_can", max_count=1), f"{ns}/find_can died")

    def test_1_bundled_scene_through_the_launch_file(self):
        """find_can.launch's up_frame arg reaches the node: mode 4 on the bundled scene, with no
        selection, takes base_link's +z from tf2 as up (the table normal of data/test_pcd.json),
        answers success and finds the one can within 3 mm and 1 deg of the truth."""
        from geometry_msgs.msg import PoseArray

        truth = json.loads((DATA / "test_pcd.json").read_text())
        ok, message = call_mode_until("", 4, lambda ok, _: ok)
        self.assertTrue(ok, message)
        self.assertIn("found 1 can(s)", message)
        self.assert_prior(message, truth["table"]["normal"], "base_link")
        poses = latest("", "can_poses", PoseArray)
        self.assertEqual((len(poses.poses), poses.header.frame_id), (1, "world"))
        centre, axis = can_errors(poses.poses[0], truth["cans"][0])
        self.assertLess(centre, 3e-3)
        self.assertLess(axis, 1.0)

    def test_2_missing_up_transform_is_an_error_not_a_guess(self):
        """With ~up_frame set and no transform from it, mode 4 answers success=False naming the
        frame and what to do, logs an ERROR, publishes nothing, and the node keeps running."""
        ok, message = call_mode("/tilted", 4)
        self.assertFalse(ok, message)
        for fragment in ("no up prior", "~up_frame 'tilted_base'", "'tilted_camera'", "clear ~up_frame"):
            self.assertIn(fragment, message)
        deadline = time.monotonic() + 10
        while not any(name == "/tilted/find_can" and "no up prior" in text for name, text in self.error_logs):
            self.assertLess(time.monotonic(), deadline, f"no ERROR from /tilted/find_can on /rosout: {self.error_logs}")
            time.sleep(0.1)
        from geometry_msgs.msg import PoseArray

        with self.assertRaises(rospy.ROSException):  # latched: anything published would come at once
            rospy.wait_for_message("/tilted/can_poses", PoseArray, timeout=2)
        self.assertEqual(call_mode("/tilted", 1)[1].split(";")[0], "no table plane yet")  # nothing ran
        self.assert_alive("/tilted")

    def test_3_every_can_through_the_node(self):
        """Once tilted_base is sent, mode 4 (no selection) uses its +z as up (the table normal),
        answers success; can_poses has one pose per true can, each within 3 mm of its base centre,
        z along the table normal (1 deg); can_markers a DELETEALL then one CYLINDER per can in the
        same order (frame, ns, distinct ids, diameter within 2 mm and height within 6 mm of the
        truth); can_pose and can_marker the best (first) can; all latched: a subscriber that
        connects after the call gets them."""
        from geometry_msgs.msg import PoseArray, PoseStamped
        from visualization_msgs.msg import Marker, MarkerArray

        truth = self.scenes["tilted"].truth
        up = self.send_tilted_base(BASE_FROM_TABLE)
        np.testing.assert_allclose(up, truth["table"]["normal"], atol=1e-9)
        ok, message = call_mode_until("/tilted", 4, lambda ok, m: "no up prior" not in m)
        self.assertTrue(ok, message)
        self.assertIn("found 3 can(s)", message)
        self.assert_prior(message, up, "tilted_base")
        time.sleep(1.0)  # a subscriber connecting now missed every message not latched
        poses = latest("/tilted", "can_poses", PoseArray)
        markers = latest("/tilted", "can_markers", MarkerArray).markers
        best_pose = latest("/tilted", "can_pose", PoseStamped)
        best_marker = latest("/tilted", "can_marker", Marker)

        self.assertEqual(poses.header.frame_id, "tilted_camera")
        self.assertEqual(len(poses.poses), len(truth["cans"]))
        matched = []
        for pose in poses.poses:
            found = [can_errors(pose, can) for can in truth["cans"]]
            i = int(np.argmin([centre for centre, _ in found]))
            rospy.loginfo("tilted scene: can %d (r %.0f mm): centre error %.2f mm, axis error %.2f deg", i,
                          truth["cans"][i]["radius"] * 1e3, found[i][0] * 1e3, found[i][1])
            self.assertLess(found[i][0], 3e-3)
            self.assertLess(found[i][1], 1.0)
            matched.append(i)
        self.assertEqual(sorted(matched), [0, 1, 2])

        self.assertEqual(markers[0].action, Marker.DELETEALL)
        self.assertEqual(len(markers), 1 + len(poses.poses))
        self.assertEqual(len({m.id for m in markers[1:]}), len(poses.poses))
        for marker, pose, i in zip(markers[1:], poses.poses, matched):
            can = truth["cans"][i]
            self.assertEqual((marker.type, marker.action, marker.ns, marker.header.frame_id),
                             (Marker.CYLINDER, Marker.ADD, "can_markers", "tilted_camera"))
            self.assertAlmostEqual(marker.scale.x, marker.scale.y)
            self.assertAlmostEqual(marker.scale.x, 2 * can["radius"], delta=2e-3)
            self.assertAlmostEqual(marker.scale.z, can["height"], delta=6e-3)
            # a Marker's pose is the cylinder's centre: half its height up the can's axis
            T = transform(pose)
            np.testing.assert_allclose(transform(marker.pose)[:3, 3], T[:3, 3] + 0.5 * marker.scale.z * T[:3, 2],
                                       atol=1e-6)

        self.assertEqual(best_pose.header.frame_id, "tilted_camera")
        self.assertTrue(same_pose(best_pose.pose, poses.poses[0]))
        self.assertEqual((best_marker.ns, best_marker.id, best_marker.action), ("can", 0, Marker.ADD))
        self.assertAlmostEqual(best_marker.scale.x, markers[1].scale.x)
        self.assertTrue(same_pose(best_marker.pose, markers[1].pose))
        type(self).best = matched[0]

    def test_4_up_is_looked_up_at_each_call(self):
        """The base tipped over (its +z along the table): the next mode 4 uses that up, finds no
        table, answers success=False and clears can_poses and can_markers (rviz's display of the
        three cans empties); the base set right again, mode 4 finds the three cans again."""
        from geometry_msgs.msg import PoseArray

        display = MarkerDisplay("/tilted/can_markers")
        self.assertEqual(len(display.wait_until(lambda shown: len(shown) == 3)), 3)  # the latched array
        tipped_up = self.send_tilted_base(TIPPED @ BASE_FROM_TABLE)
        ok, message = call_mode_until("/tilted", 4, lambda ok, m: PRIOR.search(m) and abs(
            float(PRIOR.search(m).group(1))) > 0.9)
        self.assertFalse(ok, message)
        self.assert_prior(message, tipped_up, "tilted_base")
        self.assertIn("no plane within 0.35 rad of up", message)
        self.assertEqual(latest("/tilted", "can_poses", PoseArray).poses, [])
        self.assertEqual(display.wait_until(lambda shown: not shown), {})
        self.assert_alive("/tilted")

        self.send_tilted_base(BASE_FROM_TABLE)
        ok, message = call_mode_until("/tilted", 4, lambda ok, _: ok)
        self.assertIn("found 3 can(s)", message)
        self.assertEqual(len(latest("/tilted", "can_poses", PoseArray).poses), 3)
        self.assertEqual(len(display.wait_until(lambda shown: len(shown) == 3)), 3)

    def test_5_operator_modes_and_mode_4_share_outputs(self):
        """The walkthrough (modes 0-3) on the 33 mm can puts it on can_pose and can_marker; mode 4
        then overwrites both with the best can (another one), and publishes every can on can_poses
        and cans (each with its SolidPrimitive); the walkthrough again puts the 33 mm can back, and its
        mode 0 empties can_poses and cans: mode 4's cans are forgotten (issue 14)."""
        from geometry_msgs.msg import PoseArray
        from visualization_msgs.msg import Marker

        scene = self.scenes["tilted"]
        cans = scene.truth["cans"]
        self.assertNotEqual(self.best, WALKED_CAN, "pick a walked can that is not mode 4's best")
        client = FindCanClient("/tilted", frame_id="tilted_camera")

        def walk():
            messages = []
            pose, _, _ = walkthrough(client, scene.xyz, table_rect=table_rect(scene.labels),
                                     can_rect=pixel_rect(scene.labels, sc.LABEL_CAN_SIDE + WALKED_CAN, half=3),
                                     say=messages.append)
            self.assertLess(pose_error(pose, cans[WALKED_CAN])[0], 3e-3, messages)
            marker = latest("/tilted", "can_marker", Marker)
            self.assertAlmostEqual(marker.scale.x, 2 * 0.033)  # the node's ~can_radius
            return pose

        walk()
        before = client.count("can_pose")
        ok, message = call_mode("/tilted", 4)
        self.assertTrue(ok, message)
        pose = client.wait_for("can_pose", after=before)
        self.assertLess(pose_error(pose, cans[self.best])[0], 3e-3)
        self.assertAlmostEqual(latest("/tilted", "can_marker", Marker).scale.x, 2 * cans[self.best]["radius"],
                               delta=2e-3)
        poses = latest("/tilted", "can_poses", PoseArray)
        self.assertEqual(len(poses.poses), 3)
        self.assertLess(can_errors(poses.poses[0], cans[self.best])[0], 3e-3)
        found = latest("/tilted", "cans", CanArray)
        self.assertEqual([c.id for c in found.cans], [0, 1, 2])
        self.assertTrue(same_pose(found.cans[0].pose, poses.poses[0]))
        shape = found.cans[0].shape
        self.assertEqual(shape.type, SolidPrimitive.CYLINDER)
        self.assertAlmostEqual(shape.dimensions[SolidPrimitive.CYLINDER_RADIUS], found.cans[0].radius)
        self.assertAlmostEqual(shape.dimensions[SolidPrimitive.CYLINDER_HEIGHT], found.cans[0].height)
        walk()
        self.assertEqual(latest("/tilted", "can_poses", PoseArray).poses, [])
        self.assertEqual(len(latest("/tilted", "cans", CanArray).cans), 1)  # the walked can, from mode 3

    def test_8_a_new_table_forgets_the_can(self):
        """After mode 0 starts a new walkthrough, no latched output shows the forgotten can: a new
        subscriber (another process: this one's subscribers keep what they received) gets no
        can_pose, can_markers holds only a DELETEALL, can_poses and cans are empty; a subscriber
        connected before mode 0 stays connected and gets the next can_pose."""
        from geometry_msgs.msg import PoseArray, PoseStamped
        from visualization_msgs.msg import MarkerArray

        scene = self.scenes["tilted"]
        ok, message = call_mode("/tilted", 4)
        self.assertTrue(ok, message)
        self.assertEqual(len(latest("/tilted", "can_poses", PoseArray).poses), 3)
        client = FindCanClient("/tilted", frame_id="tilted_camera")
        client.select(select_points(scene.xyz, rect=table_rect(scene.labels)))
        ok, message = call_mode("/tilted", 0)
        self.assertTrue(ok, message)
        time.sleep(1.0)
        self.assertEqual(latest("/tilted", "can_poses", PoseArray).poses, [])
        self.assertEqual(latest("/tilted", "cans", CanArray).cans, [])
        self.assertEqual([m.action for m in latest("/tilted", "can_markers", MarkerArray).markers],
                         [Marker.DELETEALL])
        self.assertFalse(pose_reaches_new_process("/tilted/can_pose", timeout=4.0))
        # The walkthrough's can_pose still reaches a subscriber that was connected before mode 0.
        poses = []
        sub = rospy.Subscriber("/tilted/can_pose", PoseStamped, poses.append)
        try:
            time.sleep(1.0)
            poses.clear()
            client.select(select_points(scene.xyz, rect=pixel_rect(scene.labels, sc.LABEL_CAN_SIDE + WALKED_CAN, half=3)))
            for mode in (1, 2, 3):
                ok, message = call_mode("/tilted", mode)
                self.assertTrue(ok, message)
            deadline = time.monotonic() + 10
            while not poses and time.monotonic() < deadline:
                time.sleep(0.1)
            self.assertTrue(poses, "no can_pose after modes 1-3 on a subscriber connected before mode 0")
        finally:
            sub.unregister()

    def test_6_no_can_scene(self):
        """A table with only a box: mode 4 answers success=False saying no can was found and why
        the box is not one; can_poses is an empty PoseArray and can_markers holds only a
        DELETEALL, both latched; the node keeps running and answers the same again."""
        from geometry_msgs.msg import PoseArray
        from visualization_msgs.msg import Marker, MarkerArray

        ok, message = call_mode("/empty", 4)
        self.assertFalse(ok, message)
        for fragment in ("no can found: 1 object(s) on the support plane, none a can", "object 1 (",
                         "try the operator modes 0-3"):
            self.assertIn(fragment, message)
        time.sleep(1.0)
        poses = latest("/empty", "can_poses", PoseArray)
        self.assertEqual((poses.poses, poses.header.frame_id), ([], "world"))
        markers = latest("/empty", "can_markers", MarkerArray).markers
        self.assertEqual([m.action for m in markers], [Marker.DELETEALL])
        self.assert_alive("/empty")
        self.assertEqual(call_mode("/empty", 4), (False, message))


    def test_7_up_prior_keeps_a_wall_from_being_the_table(self):
        """The grazing view before a wall: without ~up_frame the wall's face wins and mode 4 finds
        no can; with ~up_frame (its transform sent) the same scene gives both cans within 3 mm."""
        from geometry_msgs.msg import PoseArray

        ok, message = call_mode("/wall", 4)
        self.assertFalse(ok, message)
        ok, message = call_mode("/wall_up", 4)
        self.assertTrue(ok, message)
        self.assert_prior(message, self.scenes["wall_up"].truth["table"]["normal"], "wall_base")
        poses = latest("/wall_up", "can_poses", PoseArray).poses
        self.assertEqual(len(poses), 2, message)
        for pose in poses:
            errors = [can_errors(pose, can) for can in self.scenes["wall_up"].truth["cans"]]
            centre, axis = min(errors)
            self.assertLess(centre, 3e-3, errors)
            self.assertLess(axis, 1.0, errors)

if __name__ == "__main__":
    rospy.init_node("find_can_auto_test", anonymous=True)
    rostest.rosrun(PKG, "find_can_auto", Auto, sys.argv)
