#!/usr/bin/python3
"""Streams a generated moving sequence (example_pcl.scene_sequence) into can_tracker and prints its tracks.

Used by tools/demo_tracker.sh (make demo-tracker). Publishes each frame at --rate Hz on
/camera/depth/points (frame ``camera``) with the camera's pose in the table frame on /tf at the
cloud's stamp, and prints one line per frame of /cans: the truth's cans and the tracks (id, base
centre in the tracker's frame, radius). Needs a master and can_tracker running.
"""
import argparse
import sys
import threading

import numpy as np
import rospy
import tf2_ros
from sensor_msgs.msg import PointCloud2

from example_pcl import conversions, messages, transforms
from example_pcl import scene_sequence as ss
from example_pcl.msg import CanArray


def camera_transform(frame, stamp):
    """geometry_msgs/TransformStamped table -> camera of a scene_sequence Frame at stamp."""
    return messages.transform_stamped(transforms.invert(np.array(frame.truth["camera_from_table"])), "table",
                                      "camera", stamp)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=36, help="frames of the sequence (default 36)")
    parser.add_argument("--rate", type=float, default=30.0, help="Hz (default 30)")
    parser.add_argument("--loops", type=int, default=1, help="times the sequence is played (default 1)")
    args = parser.parse_args(rospy.myargv()[1:])
    rospy.init_node("stream_sequence")
    print(f"stream_sequence: rendering {args.frames} frames (cached after the first run) ...", flush=True)
    frames = ss.render_sequence(ss.SequenceSpec(n_frames=args.frames, rate=args.rate))
    lock, outputs = threading.Lock(), {}

    def on_cans(msg):
        with lock:
            outputs[msg.header.stamp.to_nsec()] = msg

    rospy.Subscriber("/cans", CanArray, on_cans, queue_size=100)
    pub = rospy.Publisher("/camera/depth/points", PointCloud2, queue_size=2)
    tf = tf2_ros.TransformBroadcaster()
    deadline = rospy.get_time() + 30
    while pub.get_num_connections() == 0 and not rospy.is_shutdown():  # can_tracker subscribes (lazy) once we do
        if rospy.get_time() > deadline:
            print("stream_sequence: can_tracker did not subscribe within 30 s", file=sys.stderr)
            return 1
        rospy.sleep(0.1)
    rate, sent = rospy.Rate(args.rate), []
    t0 = rospy.get_time() + 0.5
    for loop in range(args.loops):
        for f in frames:
            stamp = rospy.Time.from_sec(t0 + (loop * len(frames) + f.index) / args.rate)
            tf.sendTransform(camera_transform(f, stamp))
            pub.publish(conversions.xyz_to_cloud(f.xyz, frame_id="camera", stamp=stamp))
            sent.append((stamp, f))
            rate.sleep()
    rospy.sleep(1.0)
    print(f"{'frame':>5}  {'truth (id: radius mm)':<28}tracks (id: x, y, z mm in the tracker's frame, r mm, "
          "confidence)")
    with lock:
        for stamp, f in sent:
            truth = " ".join(f"{c['id']}:{1e3 * c['radius']:.0f}" for c in f.truth["cans"])
            msg = outputs.get(stamp.to_nsec())
            if msg is None:
                tracks = "(skipped: the tracker took a newer frame)"
            else:
                p = [(c.pose.position.x, c.pose.position.y, c.pose.position.z) for c in msg.cans]
                tracks = "  ".join(f"{c.id}: ({', '.join(str(round(1e3 * v)) for v in xyz)}) r {1e3 * c.radius:.1f} "
                                   f"c {c.confidence:.2f}" for c, xyz in zip(msg.cans, p))
            print(f"{f.index:5d}  {truth:<28}{tracks}")
        print(f"stream_sequence: {len(sent)} clouds sent, {len(outputs)} tracked; ids stay while a can is in view, "
              "a new can gets a new id, a removed one is dropped after ~max_missed frames")
    return 0 if outputs else 1


if __name__ == "__main__":
    sys.exit(main())
