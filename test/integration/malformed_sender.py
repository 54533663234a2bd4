#!/usr/bin/python3
"""Publishes each kind of malformed PointCloud2 twice on a topic, then a good cloud until killed.

    malformed_sender.py TOPIC GOOD_OUT.npz [--latched]

Used by test_malformed_messages.py against pcd_save and find_can. The good cloud's points are
saved to GOOD_OUT.npz first so the test can compare what the node did with them.
"""
import sys

import numpy as np
import rospy
from sensor_msgs.msg import PointCloud2

from example_pcl import conversions

KINDS = ("unknown field type", "missing z", "point_step smaller than the fields", "data shorter than declared",
         "width x height = 0", "all NaN", "10 million points")


def good_cloud():
    rng = np.random.default_rng(3)
    xyz = rng.normal(size=(30, 40, 3)).astype(np.float32)
    xyz[::5, ::7] = np.nan
    return conversions.xyz_to_cloud(xyz, rng.integers(0, 256, (30, 40, 3), dtype=np.uint8), frame_id="world")


def malformed(kind):
    msg = good_cloud()
    if kind == "unknown field type":
        msg.fields[0].datatype = 42
    elif kind == "missing z":
        msg.fields = [f for f in msg.fields if f.name != "z"]
    elif kind == "point_step smaller than the fields":
        msg.point_step = 8
        msg.row_step = 8 * msg.width
        msg.data = msg.data[:msg.row_step * msg.height]
    elif kind == "data shorter than declared":
        msg.data = msg.data[:-10]
    elif kind == "width x height = 0":
        msg.width, msg.row_step, msg.data = 0, 0, b""
    elif kind == "all NaN":
        msg = conversions.xyz_to_cloud(np.full((30, 40, 3), np.nan, np.float32), frame_id="world")
    elif kind == "10 million points":
        msg = conversions.xyz_to_cloud(np.ones((10_000_000, 3), np.float32), frame_id="world")
    return msg


def main():
    topic, good_out = sys.argv[1], sys.argv[2]
    rospy.init_node("malformed_sender", anonymous=True)
    good = good_cloud()
    np.savez(good_out, xyz=conversions.cloud_to_xyz(good, copy=True))
    pub = rospy.Publisher(topic, PointCloud2, queue_size=20)
    while pub.get_num_connections() == 0 and not rospy.is_shutdown():
        rospy.sleep(0.1)
    rospy.sleep(0.5)
    for kind in KINDS:
        msg = malformed(kind)
        for _ in range(2):
            pub.publish(msg)
            rospy.sleep(0.3)
        rospy.loginfo("sent twice: %s", kind)
    rate = rospy.Rate(5)
    while not rospy.is_shutdown():
        pub.publish(good)
        rate.sleep()


if __name__ == "__main__":
    main()
