"""select_patch: an operator's selection without a mouse, for scripted walkthroughs and tests.

``rosrun example_pcl select_patch _pcd_file:=SCENE.pcd _rect:="[u0, v0, u1, v1]"`` selects the
pixels u0..u1 (columns), v0..v1 (rows), both inclusive, of the organized cloud;
``_box:="[xmin, ymin, zmin, xmax, ymax, zmax]"`` selects the points inside a box (sensor frame,
metres, bounds inclusive). The finite selected points are published once, latched, on
``selected_points`` (sensor_msgs/PointCloud2, relative name) in ``~frame_id`` (default "world",
find_can's), as rviz's selected-points tools do; the node waits up to ``~wait`` seconds (default
10) for a subscriber, gives it a moment to receive the message, and exits.

:func:`select_points` is the same selection as a function on arrays.
"""
import os
import sys
import time

import numpy as np

from example_pcl.errors import PerceptionError

TOPIC = "selected_points"


def parse_numbers(value, count, name):
    """`count` finite floats from a list or a string such as "[1, 2, 3, 4]"; PerceptionError otherwise."""
    if isinstance(value, str):
        value = value.strip().strip("[]()").replace(",", " ").split()
    try:
        numbers = [float(v) for v in value]
    except (TypeError, ValueError):
        raise PerceptionError(f"{name} must be {count} numbers, got {value!r}") from None
    if len(numbers) != count or not np.isfinite(numbers).all():
        raise PerceptionError(f"{name} must be {count} finite numbers, got {value!r}")
    return numbers


def select_points(xyz, rect=None, box=None):
    """The finite points of a cloud inside a pixel rectangle or a box: float32 (N, 3), sensor frame (m).

    xyz: (H, W, 3) organized or (N, 3) cloud (m). rect: (u0, v0, u1, v1) pixel columns and rows,
    inclusive, clipped to the image (organized clouds only). box: (xmin, ymin, zmin, xmax, ymax,
    zmax), metres, inclusive. Exactly one of rect and box. The result may be empty.
    """
    xyz = np.asarray(xyz, dtype=np.float32)
    if (rect is None) == (box is None):
        raise PerceptionError("give exactly one of rect [u0, v0, u1, v1] and box [xmin, ymin, zmin, xmax, ymax, zmax]")
    if rect is not None:
        if xyz.ndim != 3 or xyz.shape[-1] != 3:
            raise PerceptionError(f"a pixel rectangle needs an organized cloud (H, W, 3), got shape {xyz.shape}")
        u0, v0, u1, v1 = (int(round(c)) for c in parse_numbers(rect, 4, "rect"))
        u0, u1 = sorted((u0, u1))
        v0, v1 = sorted((v0, v1))
        height, width = xyz.shape[:2]
        pts = xyz[max(v0, 0):min(v1, height - 1) + 1, max(u0, 0):min(u1, width - 1) + 1].reshape(-1, 3)
    else:
        lo_hi = np.array(parse_numbers(box, 6, "box"), dtype=np.float32)
        lo, hi = np.minimum(lo_hi[:3], lo_hi[3:]), np.maximum(lo_hi[:3], lo_hi[3:])
        pts = xyz.reshape(-1, 3)
        with np.errstate(invalid="ignore"):
            pts = pts[((pts >= lo) & (pts <= hi)).all(axis=1)]
    return np.ascontiguousarray(pts[np.isfinite(pts).all(axis=1)])


def main(argv=None) -> int:
    """Entry point of ``rosrun example_pcl select_patch``; returns the exit code."""
    import rospy
    from sensor_msgs.msg import PointCloud2

    from example_pcl.conversions import xyz_to_cloud
    from example_pcl.pcd import read_pcd
    from example_pcl.resources import default_scene_path

    rospy.init_node("select_patch", argv=sys.argv if argv is None else argv, anonymous=True)
    try:
        path = os.path.abspath(os.path.expanduser(str(rospy.get_param("~pcd_file", "") or default_scene_path())))
        frame_id = str(rospy.get_param("~frame_id", "world")).lstrip("/")
        wait = float(rospy.get_param("~wait", 10.0))
        if not os.path.isfile(path):
            raise PerceptionError(f"PCD file '{path}' does not exist")
        points = select_points(read_pcd(path).xyz, rect=rospy.get_param("~rect", None),
                               box=rospy.get_param("~box", None))
    except (PerceptionError, ValueError) as e:
        rospy.logfatal("select_patch: %s", e)
        return 1
    pub = rospy.Publisher(TOPIC, PointCloud2, queue_size=1, latch=True)
    rospy.loginfo("select_patch: %d point(s) of %s on %s in frame '%s'", len(points), path,
                  rospy.resolve_name(TOPIC), frame_id)
    deadline = time.monotonic() + wait
    while pub.get_num_connections() == 0 and time.monotonic() < deadline and not rospy.is_shutdown():
        time.sleep(0.05)
    if pub.get_num_connections() == 0:
        rospy.logerr("select_patch: no subscriber on %s within %g s; nothing delivered", rospy.resolve_name(TOPIC), wait)
        return 1
    pub.publish(xyz_to_cloud(points, frame_id=frame_id, stamp=rospy.Time.now()))
    time.sleep(0.5)  # let the transport hand the message over before the node goes away
    return 0
