"""A Python client of a running find_can node, and the seed's operator walkthrough through it.

:class:`FindCanClient` publishes selections on ``selected_points`` (waiting for the node's
acknowledgement on ``selected_patch``), calls ``process_mode`` and keeps the latest
``plane_model`` and ``can_pose``. :func:`walkthrough` is the operator's flow (table patch, modes 0
and 1, can patch, modes 2 and 3) as ``make demo`` runs it; TABLE_RECT and CAN_RECT are its patches
on the bundled scene.
"""
import threading
import time

import numpy as np

from example_pcl.errors import PerceptionError

# Pixel rectangles (u0, v0, u1, v1) of the bundled scene (data/test_pcd.pcd): on the table left of
# and below the can, and on the middle of the can's side facing the sensor.
TABLE_RECT = (100, 380, 120, 400)
CAN_RECT = (312, 220, 326, 234)


class FindCanClient:
    """Talks to find_can: publishes selections, waits for their acknowledgement on
    selected_patch, calls process_mode and keeps the latest message of each topic it follows.

    rospy must be initialised. namespace: where the node's topics and service live ("" = here);
    frame_id: the frame selections are sent in (the node's ~frame_id, unless tf2 knows a transform
    from it); timeout: s to wait for the node and for each reply.
    """

    TOPICS = ("selected_patch", "plane_model", "can_pose", "kinect_pointcloud")

    def __init__(self, namespace="", timeout=30.0, frame_id="world"):
        import rospy
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import PointCloud2

        from example_pcl.srv import ProcessMode

        self._rospy = rospy
        self.timeout = timeout
        self.frame_id = frame_id
        self.namespace = namespace.rstrip("/") + "/" if namespace else ""
        self._cond = threading.Condition()
        self.latest = {}  # topic -> (count, message)
        self._acks = {}  # selected_patch stamp -> points acknowledged, until acknowledged() takes it
        self.selected_pub = rospy.Publisher(self.namespace + "selected_points", PointCloud2, queue_size=2)
        kinds = {"can_pose": PoseStamped}
        self.subscribers = [rospy.Subscriber(self.namespace + topic, kinds.get(topic, PointCloud2), self._store,
                                             callback_args=topic, queue_size=2) for topic in self.TOPICS]
        self.service_name = rospy.resolve_name(self.namespace + "process_mode")
        rospy.wait_for_service(self.service_name, timeout=timeout)
        self._service = rospy.ServiceProxy(self.service_name, ProcessMode, persistent=False)
        self.wait_for_subscriber(self.selected_pub)

    def wait_for_subscriber(self, publisher):
        """Returns once the node subscribes to `publisher`; PerceptionError after the timeout."""
        deadline = time.monotonic() + self.timeout
        while publisher.get_num_connections() == 0:
            if time.monotonic() > deadline:
                raise PerceptionError(f"find_can does not subscribe to {publisher.resolved_name}")
            time.sleep(0.02)

    def _store(self, msg, topic):
        with self._cond:
            count = self.latest.get(topic, (0, None))[0] + 1
            self.latest[topic] = (count, msg)
            if topic == "selected_patch":
                self._acks[msg.header.stamp] = msg.width * msg.height
            self._cond.notify_all()

    def count(self, topic):
        """How many messages of a topic arrived so far."""
        with self._cond:
            return self.latest.get(topic, (0, None))[0]

    def wait_for(self, topic, after=0, predicate=None):
        """The first message of `topic` after `after` arrived messages (and matching predicate)."""
        def arrived():
            count, msg = self.latest.get(topic, (0, None))
            return msg if count > after and (predicate is None or predicate(msg)) else None

        return self._wait(arrived, f"no message on {topic}")

    def _wait(self, get, what):
        """get() (called under the lock, on each message) once it is not None; PerceptionError
        saying `what` after the timeout."""
        deadline = time.monotonic() + self.timeout
        with self._cond:
            while True:
                value = get()
                if value is not None:
                    return value
                left = deadline - time.monotonic()
                if left <= 0:
                    raise PerceptionError(f"{what} within {self.timeout} s")
                self._cond.wait(left)

    def stamp(self):
        """A stamp the node copies into its acknowledgement: unique per selection."""
        now = self._rospy.Time.now()
        return now if not now.is_zero() else self._rospy.Time(0, 1)

    def select(self, points, frame_id=None):
        """Publishes points (N, 3, m) on selected_points in frame_id (default the client's);
        returns how many the node stored (0 = rejected)."""
        from example_pcl.conversions import xyz_to_cloud

        stamp = self.stamp()
        self.selected_pub.publish(xyz_to_cloud(np.asarray(points, np.float32).reshape(-1, 3),
                                               frame_id=frame_id or self.frame_id, stamp=stamp))
        return self.acknowledged(stamp)

    def acknowledged(self, stamp):
        """How many points the node stored for the selection sent with `stamp` (0 = rejected)."""
        # By stamp, not the latest message: another selection's acknowledgement may follow at once.
        return self._wait(lambda: self._acks.pop(stamp, None), "no acknowledgement on selected_patch")

    def call(self, mode):
        """process_mode(mode): (success, message)."""
        response = self._service(mode)
        return response.success, response.message


def walkthrough(client, xyz, table_rect=TABLE_RECT, can_rect=CAN_RECT, say=print):
    """The seed's operator flow against a running node: returns (can_pose message, plane points,
    model points). xyz: the node's organized scene (H, W, 3), for the pixel rectangles. Raises
    PerceptionError at the first step that fails."""
    from example_pcl.conversions import cloud_to_xyz
    from example_pcl.select_patch import select_points

    def step(mode, posed=False):
        """(the step's plane_model points, its can_pose when `posed`, else None)."""
        before, poses = client.count("plane_model"), client.count("can_pose")
        ok, message = client.call(mode)
        say(f"  mode {mode}: {message}")
        if not ok:
            raise PerceptionError(f"mode {mode} failed: {message}")
        model = cloud_to_xyz(client.wait_for("plane_model", after=before), copy=True)
        # Each topic comes on its own connection: a step's pose may arrive after its model, and
        # counted from after mode 2's model, mode 2's late pose was taken for mode 3's.
        return model, client.wait_for("can_pose", after=poses) if posed else None

    n = client.select(select_points(xyz, rect=table_rect))
    say(f"  table patch: pixels {list(table_rect)}, {n} points")
    plane, _ = step(0)
    step(1)
    n = client.select(select_points(xyz, rect=can_rect))
    say(f"  can patch: pixels {list(can_rect)}, {n} points")
    step(2, posed=True)
    model, pose = step(3, posed=True)
    return pose, plane, model
