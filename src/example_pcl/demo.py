"""The seed's walkthrough, headless: a scripted operator for a running find_can node.

``python3 -m example_pcl.demo`` (``make demo`` runs it through tools/demo.sh, which starts
``find_can.launch rviz:=false`` first) selects a table patch (a pixel rectangle of the bundled
scene), calls modes 0 and 1, selects a can patch, calls modes 2 and 3, printing each step's
message; then prints the can's pose with its error against the scene's ground truth (the .json
beside the .pcd) and writes a picture of the result (the scene's depth coloured by z, the table's
inliers, the registered can model) to build/demo/find_can.png.

:class:`FindCanClient` is that operator as a class, also used by the rostests.
"""
import argparse
import json
import os
import pathlib
import sys
import threading
import time

import numpy as np

from example_pcl import scene as scene_module
from example_pcl.errors import PerceptionError

PROJECT = pathlib.Path(__file__).resolve().parents[2]
# Pixel rectangles (u0, v0, u1, v1) of the bundled scene: on the table left of and below the can,
# and on the middle of the can's side facing the sensor.
TABLE_RECT = (100, 380, 120, 400)
CAN_RECT = (312, 220, 326, 234)


class FindCanClient:
    """Talks to find_can: publishes selections, waits for their acknowledgement on
    selected_patch, calls process_mode and keeps the latest plane_model and can_pose.

    rospy must be initialised. namespace: where the node's topics and service live ("" = here);
    frame_id: the frame selections and clicks are sent in (the node's ~frame_id, unless tf2 knows
    a transform from it).
    """

    def __init__(self, namespace="", timeout=30.0, frame_id="world"):
        import rospy
        from geometry_msgs.msg import PointStamped, PoseStamped
        from sensor_msgs.msg import PointCloud2

        from example_pcl.srv import ProcessMode

        self._rospy = rospy
        self.timeout = timeout
        self.frame_id = frame_id
        ns = namespace.rstrip("/") + "/" if namespace else ""
        self._cond = threading.Condition()
        self.latest = {}  # topic -> (count, message)
        self._acks = {}  # selected_patch stamp -> points acknowledged, until _acknowledged takes it
        self.selected_pub = rospy.Publisher(ns + "selected_points", PointCloud2, queue_size=2)
        self.clicked_pub = rospy.Publisher(ns + "clicked_point", PointStamped, queue_size=2)
        self.subscribers = [rospy.Subscriber(ns + topic, kind, self._store, callback_args=topic, queue_size=2)
                            for topic, kind in (("selected_patch", PointCloud2), ("plane_model", PointCloud2),
                                                ("can_pose", PoseStamped), ("kinect_pointcloud", PointCloud2))]
        self.service_name = rospy.resolve_name(ns + "process_mode")
        rospy.wait_for_service(self.service_name, timeout=timeout)
        self._service = rospy.ServiceProxy(self.service_name, ProcessMode, persistent=False)
        deadline = time.monotonic() + timeout
        while min(self.selected_pub.get_num_connections(), self.clicked_pub.get_num_connections()) == 0:
            if time.monotonic() > deadline:
                raise PerceptionError("find_can does not subscribe to selected_points / clicked_point")
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

    def _stamp(self):
        # A stamp the node copies into its acknowledgement: unique per selection.
        now = self._rospy.Time.now()
        return now if not now.is_zero() else self._rospy.Time(0, 1)

    def select(self, points, frame_id=None):
        """Publishes points (N, 3, m) on selected_points in frame_id (default the client's);
        returns how many the node stored (0 = rejected)."""
        from example_pcl.conversions import xyz_to_cloud

        stamp = self._stamp()
        self.selected_pub.publish(xyz_to_cloud(np.asarray(points, np.float32).reshape(-1, 3),
                                               frame_id=frame_id or self.frame_id, stamp=stamp))
        return self._acknowledged(stamp)

    def click(self, point, frame_id=None):
        """Publishes a clicked_point (x, y, z, m) in frame_id (default the client's); returns how
        many scene points the node selected."""
        from geometry_msgs.msg import PointStamped

        msg = PointStamped()
        msg.header.frame_id, msg.header.stamp = frame_id or self.frame_id, self._stamp()
        msg.point.x, msg.point.y, msg.point.z = (float(v) for v in point)
        self.clicked_pub.publish(msg)
        return self._acknowledged(msg.header.stamp)

    def _acknowledged(self, stamp):
        # By stamp, not the latest message: another selection's acknowledgement may follow at once.
        return self._wait(lambda: self._acks.pop(stamp, None), "no acknowledgement on selected_patch")

    def call(self, mode):
        """process_mode(mode): (success, message)."""
        response = self._service(mode)
        return response.success, response.message


def pose_error(pose_msg, truth_can):
    """(centre error in m, axis error in degrees) of a can_pose against a ground-truth can
    (scene.json's ``cans[i]``: base_center, axis; same frame)."""
    from example_pcl.messages import matrix_from_pose

    T = matrix_from_pose(pose_msg.pose)
    centre_error = float(np.linalg.norm(T[:3, 3] - np.asarray(truth_can["base_center"])))
    cos = np.clip(T[:3, 2] @ np.asarray(truth_can["axis"]), -1.0, 1.0)
    return centre_error, float(np.degrees(np.arccos(cos)))


def write_picture(path, xyz, plane_points, model_points, title=""):
    """A PNG of the result: the organized scene's depth coloured by z (m), the table's inliers
    tinted, the registered model's points projected with the simulated Kinect's intrinsics."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def project(points):
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        pts = pts[np.isfinite(pts).all(axis=1) & (pts[:, 2] > 0)]
        return (scene_module.FX * pts[:, 0] / pts[:, 2] + scene_module.CX,
                scene_module.FY * pts[:, 1] / pts[:, 2] + scene_module.CY)

    height, width = xyz.shape[:2]
    fig, ax = plt.subplots(figsize=(9, 6.75), dpi=100)
    image = ax.imshow(xyz[..., 2], cmap="viridis", interpolation="nearest")
    fig.colorbar(image, ax=ax, fraction=0.035, label="z (m, sensor frame)")
    if plane_points is not None and len(plane_points):
        u, v = project(plane_points)
        overlay = np.zeros((height, width, 4))
        inside = (u >= -0.5) & (u < width - 0.5) & (v >= -0.5) & (v < height - 0.5)
        overlay[np.round(v[inside]).astype(int), np.round(u[inside]).astype(int)] = (1.0, 0.55, 0.0, 0.45)
        ax.imshow(overlay, interpolation="nearest")
    if model_points is not None and len(model_points):
        u, v = project(model_points)
        ax.plot(u, v, ",", color="red", label="registered can model")
        ax.legend(loc="upper right")
    ax.set_xlim(-0.5, width - 0.5)
    ax.set_ylim(height - 0.5, -0.5)
    ax.set_title(title or "find_can: scene (z), table inliers (orange), registered can (red)", fontsize=9)
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return path


def walkthrough(client, xyz, table_rect=TABLE_RECT, can_rect=CAN_RECT, say=print):
    """The seed's operator flow against a running node: returns (can_pose message, plane points,
    model points). Raises PerceptionError at the first step that fails."""
    from example_pcl.conversions import cloud_to_xyz
    from example_pcl.select_patch import select_points

    def step(mode):
        before = client.count("plane_model")
        ok, message = client.call(mode)
        say(f"  mode {mode}: {message}")
        if not ok:
            raise PerceptionError(f"mode {mode} failed: {message}")
        return cloud_to_xyz(client.wait_for("plane_model", after=before), copy=True)

    n = client.select(select_points(xyz, rect=table_rect))
    say(f"  table patch: pixels {list(table_rect)}, {n} points")
    plane = step(0)
    step(1)
    n = client.select(select_points(xyz, rect=can_rect))
    say(f"  can patch: pixels {list(can_rect)}, {n} points")
    step(2)
    poses = client.count("can_pose")
    model = step(3)
    return client.wait_for("can_pose", after=poses), plane, model


def main(argv=None):
    """``python3 -m example_pcl.demo [--pcd F] [--out PNG]``: the walkthrough; returns the exit status."""
    parser = argparse.ArgumentParser(prog="find_can demo", description=__doc__.split("\n\n")[0])
    parser.add_argument("--pcd", default=str(PROJECT / "data" / "test_pcd.pcd"), help="the scene find_can loaded")
    parser.add_argument("--out", default=str(PROJECT / "build" / "demo" / "find_can.png"), help="picture to write")
    parser.add_argument("--timeout", type=float, default=30.0, help="s to wait for the node and each reply")
    args = parser.parse_args(argv)

    import rospy

    from example_pcl.pcd import read_pcd

    rospy.init_node("find_can_demo", anonymous=True, disable_signals=False)
    start = time.monotonic()
    try:
        xyz = np.ascontiguousarray(read_pcd(args.pcd).xyz)
        print(f"find_can demo on {args.pcd}:")
        client = FindCanClient(timeout=args.timeout)
        pose, plane, model = walkthrough(client, xyz)
    except (PerceptionError, rospy.ROSException) as e:
        print(f"demo failed: {e}", file=sys.stderr)
        return 1
    p, q = pose.pose.position, pose.pose.orientation
    print(f"can pose in '{pose.header.frame_id}': position ({p.x:.4f}, {p.y:.4f}, {p.z:.4f}) m, "
          f"orientation (x, y, z, w) ({q.x:.4f}, {q.y:.4f}, {q.z:.4f}, {q.w:.4f})")
    truth_file = scene_module.truth_path(args.pcd)
    title = ""
    if truth_file.is_file():
        truth = json.loads(truth_file.read_text())
        centre, axis = pose_error(pose, truth["cans"][0])
        title = f"find_can: centre error {centre * 1e3:.2f} mm, axis error {axis:.2f} deg"
        print(f"error against the ground truth ({truth_file.name}): centre {centre * 1e3:.2f} mm, axis {axis:.2f} deg")
    out = write_picture(args.out, xyz, plane, model, title)
    print(f"picture written to {os.path.relpath(out)} ({time.monotonic() - start:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
