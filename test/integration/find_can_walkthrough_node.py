#!/usr/bin/python3
"""rostest node of find_can_walkthrough.test: the operator's walkthrough over ROS, checked
against the scenes' ground truth.

The bundled scene is served by the find_can of find_can.launch (started by the .test file). The
generated scenes are written to a temporary directory in setUpClass, and each is loaded by its own
find_can, started here in a namespace of its own (``/scene_N``, find_can_helpers.find_can_node).
"""
import json
import os
import pathlib
import shutil
import sys
import tempfile
import unittest

import numpy as np
import roslib.packages
import rospy
import rostest
from find_can_helpers import PKG, find_can_node, pixel_rect, pose_error, send_static_transforms, table_rect

from example_pcl import scene as sc
from example_pcl.find_can_client import FindCanClient, walkthrough
from example_pcl.messages import matrix_from_pose
from example_pcl.transforms import from_translation_quaternion_xyzw
from example_pcl.pcd import read_pcd, write_cloud

DATA = pathlib.Path(roslib.packages.get_pkg_dir(PKG)) / "data"

# (distance m, tilt rad, cans as (x, y) in the table frame, index of the can to find, target_frame)
SCENES = [
    (0.6, 1.2, [(0.0, 0.0), (0.1, 0.07)], 1, ""),
    (1.0, 0.7, [(0.0, 0.0), (-0.12, -0.05)], 1, "base_link"),
    (1.5, 0.9, [(0.0, 0.0)], 0, ""),
]
# base_link from world (the sensor frame as find_can publishes it): a robot's base 0.8 m behind
# and 0.5 m below a sensor looking down, as a static transform the test node broadcasts.
BASE_FROM_WORLD = from_translation_quaternion_xyzw((0.2, -0.1, 0.8), (0.5, -0.5, 0.5, -0.5))


class Walkthrough(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="find_can_walkthrough_")
        cls.scenes = []
        for i, (distance, tilt, cans, target, _) in enumerate(SCENES):
            spec = sc.SceneSpec(camera_distance=distance, tilt=tilt, cans=[(x, y, 0.033, 0.122) for x, y in cans],
                                seed=10 + i)
            scene = sc.generate_scene(spec)
            path = os.path.join(cls.tmp, f"scene_{i}.pcd")
            write_cloud(path, scene.xyz, rgb=scene.rgb)
            cls.scenes.append((path, scene))
        import tf2_ros

        cls.broadcaster = tf2_ros.StaticTransformBroadcaster()
        send_static_transforms(cls.broadcaster, {("base_link", "world"): BASE_FROM_WORLD})

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_bundled_scene(self):
        """The demo's walkthrough on the bundled scene through find_can.launch: every step succeeds,
        the centre is within 3 mm and the axis within 1 deg of data/test_pcd.json, mode 3 reports
        its RMS error and iterations, and can_marker is the can's cylinder."""
        from visualization_msgs.msg import Marker

        xyz = np.ascontiguousarray(read_pcd(str(DATA / "test_pcd.pcd")).xyz)
        client = FindCanClient()
        messages = []
        pose, plane, model = walkthrough(client, xyz, say=messages.append)
        truth = json.loads((DATA / "test_pcd.json").read_text())["cans"][0]
        centre, axis = pose_error(pose, truth)
        rospy.loginfo("bundled scene: centre error %.2f mm, axis error %.2f deg", centre * 1e3, axis)
        self.assertLess(centre, 3e-3)
        self.assertLess(axis, 1.0)
        self.assertEqual(pose.header.frame_id, "world")
        self.assertRegex(messages[-1], r"converged in \d+ iterations, RMS radial error \d+\.\d mm")
        self.assertGreater(len(plane), 100000)
        marker = rospy.wait_for_message("can_marker", Marker, timeout=10)
        self.assertEqual((marker.type, marker.action), (Marker.CYLINDER, Marker.ADD))
        self.assertAlmostEqual(marker.scale.x, 0.066)
        self.assertAlmostEqual(marker.scale.z, 0.122)

    def test_generated_scenes(self):
        """On generated scenes (0.6, 1.0 and 1.5 m away, tilts 0.7-1.2 rad, cans off the image centre)
        the walkthrough puts the centre within 3 mm of the truth; with ~target_frame set, can_pose
        is also published in that frame, equal to the tf2 transform of can_pose."""
        from geometry_msgs.msg import PoseStamped

        for i, ((path, scene), (_, _, _, target, target_frame)) in enumerate(zip(self.scenes, SCENES)):
            ns = f"/scene_{i}"
            params = {"target_frame": target_frame} if target_frame else {}
            with find_can_node(ns, path, os.path.join(self.tmp, f"scene_{i}.log"), **params):
                client = FindCanClient(ns)
                messages = []
                pose, _, _ = walkthrough(client, scene.xyz, table_rect=table_rect(scene.labels),
                                         can_rect=pixel_rect(scene.labels, sc.LABEL_CAN_SIDE + target, half=3),
                                         say=messages.append)
                centre, axis = pose_error(pose, scene.truth["cans"][target])
                rospy.loginfo("scene %d (%s m, tilt %s): centre error %.2f mm, axis error %.2f deg; %s", i,
                              SCENES[i][0], SCENES[i][1], centre * 1e3, axis, messages[-1])
                self.assertLess(centre, 3e-3, messages)
                self.assertLess(axis, 1.0, messages)
                if target_frame:
                    in_target = rospy.wait_for_message(f"{ns}/can_pose_target", PoseStamped, timeout=10)
                    self.assertEqual(in_target.header.frame_id, target_frame)
                    expected = BASE_FROM_WORLD @ matrix_from_pose(pose.pose)
                    got = matrix_from_pose(in_target.pose)
                    np.testing.assert_allclose(got, expected, atol=1e-6)
                    self.assertIn(f"in {target_frame}: (", messages[-1])


if __name__ == "__main__":
    rospy.init_node("find_can_walkthrough_test", anonymous=True)
    rostest.rosrun(PKG, "find_can_walkthrough", Walkthrough, sys.argv)
