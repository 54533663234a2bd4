"""pcd_publisher: streams a PCD file as sensor_msgs/PointCloud2, standing in for a Kinect.

``rosrun example_pcl pcd_publisher _file:=X _rate:=30 _frame_id:=camera_depth_optical_frame``
publishes the cloud of X on ``kinect/depth/points`` (relative, so /kinect/depth/points by default
and remappable), latched, with a fresh stamp each time.

Private params (logged at start-up with the resolved topic):

- ``~file`` (str, default the package's bundled scene ``data/test_pcd.pcd``).
- ``~rate`` (Hz, default 1): 0 publishes once (latched) and keeps the node up.
- ``~frame_id`` (str, default ``camera_depth_optical_frame``; a leading slash is removed).

The file is read and converted once; every field, the organized shape and is_dense are
published as the file holds them.
"""
from __future__ import annotations

import dataclasses
import os
from typing import Callable

from example_pcl.conversions import array_to_cloud
from example_pcl.errors import PerceptionError
from example_pcl.pcd import read_pcd
from example_pcl.resources import default_scene_path

TOPIC = "kinect/depth/points"
DEFAULT_FRAME_ID = "camera_depth_optical_frame"


@dataclasses.dataclass(frozen=True)
class PublisherConfig:
    """The effective configuration of pcd_publisher."""

    file: str = ""
    rate: float = 1.0
    frame_id: str = DEFAULT_FRAME_ID

    @classmethod
    def from_params(cls, get_param: Callable[[str, object], object]) -> "PublisherConfig":
        """Reads ``~file``, ``~rate``, ``~frame_id`` through ``get_param(name, default)`` and validates."""
        try:
            config = cls(file=os.path.abspath(os.path.expanduser(str(get_param("~file", "") or default_scene_path()))),
                         rate=float(get_param("~rate", cls.rate)),
                         frame_id=str(get_param("~frame_id", cls.frame_id)).lstrip("/"))
        except (TypeError, ValueError) as e:
            raise PerceptionError(f"bad parameter value: {e}") from None
        if not config.rate >= 0:
            raise PerceptionError(f"~rate must be >= 0 Hz (0 = publish once), got {config.rate}")
        if not config.frame_id:
            raise PerceptionError("~frame_id must not be empty")
        return config


def load_cloud_message(path: str, frame_id: str):
    """The PointCloud2 of a PCD file: every field, the organized shape and is_dense kept.

    Raises PerceptionError naming the file when it is missing or malformed.
    """
    if not os.path.isfile(path):
        hint = " (generate the bundled scene with `rosrun example_pcl make_scene` or pass _file:=...)" \
            if path == default_scene_path() else ""
        raise PerceptionError(f"PCD file '{path}' does not exist{hint}")
    cloud = read_pcd(path)
    return array_to_cloud(cloud.points, frame_id=frame_id, is_dense=cloud.is_dense)


class PcdPublisherNode:
    """Publishes one cloud, read once, latched, at ``rate`` Hz with a fresh stamp each time."""

    def __init__(self, config: PublisherConfig, msg):
        import rospy
        from sensor_msgs.msg import PointCloud2

        self._rospy = rospy
        self.config = config
        self.msg = msg
        self.topic = rospy.resolve_name(TOPIC)
        # queue_size: a slow subscriber loses frames (pcd_save counts them) instead of stalling the stream.
        self.publisher = rospy.Publisher(TOPIC, PointCloud2, queue_size=2, latch=True)

    def publish(self) -> None:
        self.msg.header.stamp = self._rospy.Time.now()
        self.publisher.publish(self.msg)

    def spin(self) -> None:
        rospy = self._rospy
        if self.config.rate == 0:
            self.publish()
            rospy.spin()
            return
        rate = rospy.Rate(self.config.rate)
        while not rospy.is_shutdown():
            self.publish()
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                break


def main(argv=None) -> int:
    """Entry point of ``rosrun example_pcl pcd_publisher``; returns the exit code."""
    import sys

    import rospy

    rospy.init_node("pcd_publisher", argv=sys.argv if argv is None else argv)
    try:
        config = PublisherConfig.from_params(rospy.get_param)
        msg = load_cloud_message(config.file, config.frame_id)
    except PerceptionError as e:
        rospy.logfatal("pcd_publisher: %s", e)
        return 1
    node = PcdPublisherNode(config, msg)
    rospy.loginfo("pcd_publisher: publishing %s (%dx%d, fields %s, %s) on %s in frame '%s' %s",
                  config.file, msg.width, msg.height, " ".join(f.name for f in msg.fields),
                  "dense" if msg.is_dense else "with NaN points", node.topic, config.frame_id,
                  f"at {config.rate:g} Hz" if config.rate else "once (latched)")
    node.spin()
    return 0
