"""Helpers of the find_can rostest nodes (imported from beside them): a find_can per generated scene,
process_mode calls without a client, an operator that also clicks, a pose's error against the
ground truth, static transforms, pixel patches of a scene's labels.

rospy must be initialised by the test node before any of these talk to the graph.
"""
import contextlib
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import roslib.packages
import rospy

from example_pcl import scene as sc
from example_pcl.find_can_client import FindCanClient
from example_pcl.messages import matrix_from_pose, transform_stamped

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tools"))
from netns_graph import stop_process  # noqa: E402

PKG = "example_pcl"


@contextlib.contextmanager
def find_can_node(ns, pcd_file, log_path, **params):
    """A find_can loading `pcd_file`, run as a subprocess in namespace `ns` (``__ns:=ns``) with the
    private params given (``up_frame="base_link"`` -> ``_up_frame:=base_link``), its output in
    `log_path`; stopped with SIGINT (killed after 15 s) on leaving. A node loads one scene, so a
    test of several scenes needs a node per scene, and only the test node knows their paths."""
    node = roslib.packages.find_node(PKG, "find_can")[0]
    args = [sys.executable, node, f"__ns:={ns}", "__name:=find_can", f"_pcd_file:={pcd_file}"]
    args += [f"_{name}:={value}" for name, value in params.items()]
    with open(log_path, "w") as log:
        proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        yield proc
    finally:
        stop_process(proc, signal.SIGINT, timeout=15)


class OperatorClient(FindCanClient):
    """A FindCanClient that also clicks, as rviz's Publish Point tool does (clicked_point)."""

    def __init__(self, namespace="", timeout=30.0, frame_id="world"):
        from geometry_msgs.msg import PointStamped

        super().__init__(namespace, timeout, frame_id)
        self.clicked_pub = rospy.Publisher(self.namespace + "clicked_point", PointStamped, queue_size=2)
        self.wait_for_subscriber(self.clicked_pub)

    def click(self, point, frame_id=None):
        """Publishes a clicked_point (x, y, z, m) in frame_id (default the client's); returns how
        many scene points the node selected."""
        from geometry_msgs.msg import PointStamped

        msg = PointStamped()
        msg.header.frame_id, msg.header.stamp = frame_id or self.frame_id, self.stamp()
        msg.point.x, msg.point.y, msg.point.z = (float(v) for v in point)
        self.clicked_pub.publish(msg)
        return self.acknowledged(msg.header.stamp)


def pose_error(pose_msg, truth_can):
    """(centre error in m, axis error in degrees) of a geometry_msgs/PoseStamped against a
    ground-truth can (scene.json's ``cans[i]``; same frame)."""
    return sc.can_pose_error(matrix_from_pose(pose_msg.pose), truth_can)


def call_mode(ns, mode, timeout=30.0):
    """process_mode(mode) of the find_can in `ns` ("" = here), subscribing to nothing: (success, message)."""
    from example_pcl.srv import ProcessMode

    name = (ns.rstrip("/") + "/process_mode") if ns else "process_mode"
    rospy.wait_for_service(name, timeout=timeout)
    response = rospy.ServiceProxy(name, ProcessMode)(mode)
    return response.success, response.message


def call_mode_until(ns, mode, done, timeout=15.0):
    """Calls process_mode(mode) until done(success, message) holds, for what the node learns
    asynchronously (a transform just sent); returns the last (success, message)."""
    deadline = time.monotonic() + timeout
    while True:
        answer = call_mode(ns, mode)
        if done(*answer) or time.monotonic() > deadline:
            return answer
        time.sleep(0.2)


def pose_reaches_new_process(topic, timeout):
    """Whether a subscriber started now in another process gets a geometry_msgs/PoseStamped on topic
    within timeout (s): what a latched publisher hands a new subscriber (this process's subscribers
    would replay what their connections already received)."""
    probe = ("import sys, rospy\nfrom geometry_msgs.msg import PoseStamped\n"
             "rospy.init_node('latch_probe', anonymous=True)\n"
             "try:\n    rospy.wait_for_message(sys.argv[1], PoseStamped, timeout=float(sys.argv[2]))\n"
             "    print('received')\nexcept rospy.ROSException:\n    print('nothing')\n")
    out = subprocess.run([sys.executable, "-c", probe, topic, str(timeout)], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, timeout=timeout + 60)
    lines = out.stdout.strip().splitlines()
    assert out.returncode == 0 and lines and lines[-1] in ("received", "nothing"), out.stdout
    return lines[-1] == "received"


def send_static_transforms(broadcaster, transforms):
    """Sends {(parent, child): 4x4 T_parent_from_child} on /tf_static in one message: the latched
    topic holds only the last message a process sent, so every frame goes in each one."""
    now = rospy.Time.now()
    broadcaster.sendTransform([transform_stamped(T, parent, child, now) for (parent, child), T in transforms.items()])


def pixel_rect(labels, label, qv=0.5, qu=0.5, half=4):
    """[u0, v0, u1, v1] around quantiles of the pixels of a label, all pixels of that label."""
    vs, us = np.nonzero(labels == label)
    v, u = int(np.quantile(vs, qv)), int(np.quantile(us, qu))
    assert (labels[v - half:v + half + 1, u - half:u + half + 1] == label).all(), f"no clean patch of label {label}"
    return (u - half, v - half, u + half, v + half)


def table_rect(labels):
    """A pixel rectangle that sees only the table top, away from the objects."""
    for qv, qu in ((0.8, 0.2), (0.8, 0.8), (0.5, 0.15)):
        try:
            return pixel_rect(labels, sc.LABEL_TABLE, qv, qu, half=6)
        except AssertionError:
            continue
    raise AssertionError("no table patch")
