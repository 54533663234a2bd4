#!/usr/bin/python3
"""rostest node of find_can_errors.test: find_can's failures and alternative inputs over ROS.

The tests share one find_can (started by the .test file) and run in the order of their names,
each starting from the state the previous one left, as an operator's session would.
"""
import json
import pathlib
import sys
import unittest

import numpy as np
import roslib.packages
import rosnode
import rospy
import rostest
from find_can_helpers import OperatorClient, pose_error, send_static_transforms

from example_pcl.find_can_client import CAN_RECT, TABLE_RECT
from example_pcl.transforms import from_translation_quaternion_xyzw
from example_pcl.pcd import read_pcd
from example_pcl.select_patch import select_points

PKG = "example_pcl"
DATA = pathlib.Path(roslib.packages.get_pkg_dir(PKG)) / "data"
STRADDLING_RECT = (310, 240, 328, 262)  # the can's lower side and the table in front of it (~40 % table)
# camera_link from world: the frame a selection may come in, known to tf2 through a static transform.
CAMERA_FROM_WORLD = from_translation_quaternion_xyzw((0.05, -0.02, 0.1), (0.0, 0.0, 0.3826834, 0.9238795))


class Errors(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        import tf2_ros

        cls.xyz = np.ascontiguousarray(read_pcd(str(DATA / "test_pcd.pcd")).xyz)
        cls.truth = json.loads((DATA / "test_pcd.json").read_text())["cans"][0]
        cls.client = OperatorClient()
        cls.broadcaster = tf2_ros.StaticTransformBroadcaster()
        send_static_transforms(cls.broadcaster, {("camera_link", "world"): CAMERA_FROM_WORLD})

    def fails(self, mode, *fragments):
        ok, message = self.client.call(mode)
        self.assertFalse(ok, f"mode {mode} succeeded: {message}")
        for fragment in fragments:
            self.assertIn(fragment, message)
        self.assertTrue(rosnode.rosnode_ping("/find_can", max_count=1), "find_can died")
        return message

    def succeeds(self, mode):
        ok, message = self.client.call(mode)
        self.assertTrue(ok, f"mode {mode} failed: {message}")
        return message

    def test_1_out_of_order_before_any_selection(self):
        """Before any selection: mode 0 asks for a table patch, modes 1-3 ask to identify the table
        first (select a table patch, mode 0), unknown modes list the modes."""
        self.fails(0, "no patch selected; select a patch on the table")
        for mode in (1, 2, 3):
            self.fails(mode, "identify the table first: select a table patch and call mode 0")
        for mode in (5, -1, 1000):
            self.fails(mode, f"unknown mode {mode}", "0 IDENTIFY_PLANE", "3 COMPUTE_CYLINDRICAL_FIT_ERR_ITERATE")

    def test_2_bad_table_selections(self):
        """Empty, all-NaN, two-point and collinear selections are stored and make mode 0 fail with
        the reason and what to do; the node keeps running."""
        p = select_points(self.xyz, rect=TABLE_RECT)[0].astype(float)
        bad = [(np.zeros((0, 3)), "empty"), (np.full((30, 3), np.nan), "no finite point"),
               (p + [[0, 0, 0], [0.01, 0, 0]], "select a larger patch"),
               (p + np.outer(np.linspace(-0.02, 0.02, 40), [1.0, 0, 0]), "select an area")]
        for points, reason in bad:
            self.client.select(points)
            self.fails(0, reason)
        self.fails(1, "identify the table first")

    def test_3_selections_in_other_frames(self):
        """A selection in a frame tf2 does not know is rejected (acknowledged empty) and mode 0 says
        why; one in camera_link, which tf2 knows, is transformed into world and identifies the table."""
        patch = select_points(self.xyz, rect=TABLE_RECT)
        self.assertEqual(self.client.select(patch, frame_id="nowhere"), 0)
        self.fails(0, "frame 'nowhere'", "tf2 has no transform", "select a patch on the table again")
        in_camera = patch @ CAMERA_FROM_WORLD[:3, :3].T + CAMERA_FROM_WORLD[:3, 3]
        self.assertEqual(self.client.select(in_camera, frame_id="camera_link"), len(patch))
        message = self.succeeds(0)
        self.assertIn("table plane: normal (0.000, -0.621, -0.783), d=0.783 m", message)

    def test_4_out_of_order_after_the_plane(self):
        """With a plane: modes 2 and 3 ask for mode 1; after mode 1, mode 2 asks for a can patch and
        mode 3 for mode 2; a collinear can patch fails mode 2; mode 1 still gives the same points."""
        self.fails(2, "call mode 1 first")
        self.fails(3, "call mode 1 first")
        first = self.succeeds(1)
        self.fails(2, "no can patch yet; select a patch on the side of the can")
        self.fails(3, "no initial can estimate yet; select a can patch and call mode 2")
        p = select_points(self.xyz, rect=CAN_RECT)[0].astype(float)
        self.client.select(p + np.outer(np.linspace(-0.01, 0.01, 20), [1.0, 0, 0]))
        self.fails(2, "line")
        self.fails(3, "no initial can estimate yet")
        self.assertEqual(self.succeeds(1), first)

    def test_5_clicked_point_walkthrough(self):
        """Clicks (rviz's Publish Point) on the table and on the can's side select the scene points
        within ~patch_radius; the walkthrough then finds the centre within 3 mm."""
        table = self.xyz[390, 110]
        can = self.xyz[227, 319]
        self.assertGreater(self.client.click(table), 500)
        self.succeeds(0)
        self.succeeds(1)
        self.assertGreater(self.client.click(can), 100)
        self.succeeds(2)
        poses = self.client.count("can_pose")
        self.assertIn("converged in", self.succeeds(3))
        centre, axis = pose_error(self.client.wait_for("can_pose", after=poses), self.truth)
        rospy.loginfo("clicked walkthrough: centre error %.2f mm, axis error %.2f deg", centre * 1e3, axis)
        self.assertLess(centre, 3e-3)

    def test_6_can_patch_with_table_points(self):
        """A can patch that reaches onto the table: the table points are dropped (counted in the
        message) and the fit still finds the centre within 3 mm."""
        self.client.select(select_points(self.xyz, rect=STRADDLING_RECT))
        message = self.succeeds(2)
        dropped = int(message.split("points (")[1].split(" table points dropped")[0])
        self.assertGreater(dropped, 50)
        poses = self.client.count("can_pose")
        self.succeeds(3)
        centre, _ = pose_error(self.client.wait_for("can_pose", after=poses), self.truth)
        self.assertLess(centre, 3e-3)

    def test_7_state_kept_after_errors(self):
        """After failed calls (unknown mode, a rejected selection) mode 3 again returns the same
        centre: the plane, the points above and the can estimate survived."""
        before = self.succeeds(3).split(":")[0]
        self.fails(17, "unknown mode 17")
        self.client.select(np.zeros((0, 3)))
        self.fails(2, "empty")
        self.assertEqual(self.succeeds(3).split(":")[0], before)

    def test_8_select_patch_node(self):
        """`rosrun example_pcl select_patch` with _rect or _box delivers exactly the points
        select_points gives, which find_can stores as the patch; mode 0 then finds the table."""
        import subprocess

        node = roslib.packages.find_node(PKG, "select_patch")[0]
        box = [-0.3, 0.15, 0.8, -0.2, 0.25, 0.95]
        for param, value, expected in (("_rect", "[100, 380, 120, 400]", select_points(self.xyz, rect=TABLE_RECT)),
                                       ("_box", str(box), select_points(self.xyz, box=box))):
            before = self.client.count("selected_patch")
            run = subprocess.run([sys.executable, node, f"{param}:={value}"], stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, text=True, timeout=60)
            self.assertEqual(run.returncode, 0, run.stdout)
            ack = self.client.wait_for("selected_patch", after=before)
            self.assertEqual(ack.width * ack.height, len(expected), run.stdout)
            self.assertIn("table plane: normal (0.000, -0.621, -0.783)", self.succeeds(0))


if __name__ == "__main__":
    rospy.init_node("find_can_errors_test", anonymous=True)
    rostest.rosrun(PKG, "find_can_errors", Errors, sys.argv)
