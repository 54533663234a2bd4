"""find_can: the operator registers a can on a table, step by step, and gets its pose.

``rosrun example_pcl find_can`` (or ``roslaunch example_pcl find_can.launch``) loads a PCD scene
and waits for the operator (see example_pcl.can_finder for the steps):

1. select a patch on the table (rviz's Publish Point tool on ``clicked_point``, a selected-points
   tool or ``rosrun example_pcl select_patch`` on ``selected_points``);
2. ``rosservice call process_mode 0`` (IDENTIFY_PLANE), then ``process_mode 1`` (FIND_PNTS_ABOVE_PLANE);
3. select a patch on the side of the can facing the sensor;
4. ``process_mode 2`` (COMPUTE_CYLINDRICAL_FIT_ERR_INIT), then ``process_mode 3``
   (COMPUTE_CYLINDRICAL_FIT_ERR_ITERATE): the can's pose on ``can_pose``.

Topics (relative names; everything published latched, once per change, in ``~frame_id``):

- published: ``kinect_pointcloud`` (sensor_msgs/PointCloud2, the scene), ``plane_model``
  (PointCloud2, what the last step found: the table's inliers, the points above it, or the can
  model at the estimate), ``can_pose`` (geometry_msgs/PoseStamped: origin at the centre of the
  can's base, z along its axis), ``can_marker`` (visualization_msgs/Marker, a CYLINDER); after
  mode 4 also ``can_poses`` (geometry_msgs/PoseArray) and ``can_markers`` (MarkerArray: a DELETEALL,
  then one CYLINDER per can), published empty when the search finds none; and with
  ``~target_frame`` set, ``can_pose_target`` (the pose in that frame, through tf2); and
  ``selected_patch`` (PointCloud2, the latest selection as stored, its header's stamp copied from
  the selection's, empty when it was rejected: an acknowledgement a script can wait for before
  calling the next mode);
- subscribed: ``selected_points`` (PointCloud2) and ``clicked_point`` (geometry_msgs/PointStamped:
  the scene points within ~patch_radius of it become the patch);
- service ``process_mode`` (example_pcl/ProcessMode): ``int32 mode`` -> ``bool success, string
  message``, the message one line with the step's numbers.

Private params (logged at start-up): ``~pcd_file`` (default the package's data/test_pcd.pcd;
relative to the working directory), ``~frame_id`` ("world": the frame the cloud is published in,
i.e. the sensor frame as rviz knows it), ``~z_eps`` (0.01 m), ``~z_threshold`` (0.01 m),
``~can_radius`` (0.033 m), ``~can_height`` (0.122 m), ``~patch_radius`` (0.03 m), ``~r_eps``
(0.01 m), ``~max_iterations`` (50), ``~fit_margin`` (0.02 m), ``~target_frame`` ("" = none),
``~up_frame`` ("" = none: mode 4 takes the table's "up" from this frame's +z axis, looked up
through tf2 in ``~frame_id`` at each call; no transform, no search).
"""
import dataclasses
import os
import sys
import threading
from typing import Callable

import numpy as np

from example_pcl import messages, transforms
from example_pcl.can_finder import CanFinder, FinderConfig, Mode, describe_modes
from example_pcl.errors import PerceptionError, warning_kind

SCENE_TOPIC = "kinect_pointcloud"
MODEL_TOPIC = "plane_model"
POSE_TOPIC = "can_pose"
TARGET_POSE_TOPIC = "can_pose_target"
MARKER_TOPIC = "can_marker"
POSES_TOPIC = "can_poses"
MARKERS_TOPIC = "can_markers"
PATCH_TOPIC = "selected_patch"
SELECTED_TOPIC = "selected_points"
CLICKED_TOPIC = "clicked_point"
SERVICE = "process_mode"
MAX_SELECTION_POINTS = 2_000_000  # more is a runaway publisher, not an operator's selection


def package_path(*parts):
    """A path inside the example_pcl package ($(rospack find example_pcl)/...), or this checkout."""
    try:
        import rospkg

        root = rospkg.RosPack().get_path("example_pcl")
    except Exception:  # rospkg missing or the package not on ROS_PACKAGE_PATH: use this checkout
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return os.path.join(root, *parts)


@dataclasses.dataclass(frozen=True)
class FindCanConfig:
    """The effective configuration of find_can: the scene, frames (up_frame: mode 4's up prior is
    its +z axis; "" = no prior), the patch radius of a clicked point (m) and the pipeline's
    FinderConfig."""

    pcd_file: str
    frame_id: str = "world"
    target_frame: str = ""
    up_frame: str = ""
    patch_radius: float = 0.03
    finder: FinderConfig = FinderConfig()

    @classmethod
    def from_params(cls, get_param: Callable[[str, object], object]) -> "FindCanConfig":
        """Reads the private params through ``get_param(name, default)``; raises PerceptionError
        for a value that cannot work."""
        f = FinderConfig()
        try:
            finder = FinderConfig(
                z_eps=float(get_param("~z_eps", f.z_eps)), z_threshold=float(get_param("~z_threshold", f.z_threshold)),
                can_radius=float(get_param("~can_radius", f.can_radius)),
                can_height=float(get_param("~can_height", f.can_height)),
                r_eps=float(get_param("~r_eps", f.r_eps)), max_iterations=int(get_param("~max_iterations", f.max_iterations)),
                fit_margin=float(get_param("~fit_margin", f.fit_margin)))
            pcd_file = str(get_param("~pcd_file", "") or package_path("data", "test_pcd.pcd"))
            config = cls(pcd_file=os.path.abspath(os.path.expanduser(pcd_file)),
                         frame_id=str(get_param("~frame_id", cls.frame_id)).strip().lstrip("/"),
                         target_frame=str(get_param("~target_frame", cls.target_frame) or "").strip().lstrip("/"),
                         up_frame=str(get_param("~up_frame", cls.up_frame) or "").strip().lstrip("/"),
                         patch_radius=float(get_param("~patch_radius", cls.patch_radius)), finder=finder)
        except (TypeError, ValueError) as e:
            raise PerceptionError(f"bad parameter value: {e}") from None
        finder.validate()
        if not config.frame_id:
            raise PerceptionError("~frame_id must not be empty")
        if not config.patch_radius > 0:
            raise PerceptionError(f"~patch_radius must be > 0 m, got {config.patch_radius}")
        return config

    def describe(self):
        """One line: every effective value, for the start-up log."""
        f = self.finder
        return (f"pcd_file={self.pcd_file} frame_id={self.frame_id} target_frame={self.target_frame or '(none)'} "
                f"up_frame={self.up_frame or '(none)'} "
                f"z_eps={f.z_eps} m z_threshold={f.z_threshold} m can_radius={f.can_radius} m "
                f"can_height={f.can_height} m patch_radius={self.patch_radius} m r_eps={f.r_eps} m "
                f"max_iterations={f.max_iterations} fit_margin={f.fit_margin} m")


# --- the node -------------------------------------------------------------------------------------


class FindCanNode:
    """Wires ROS to a CanFinder: selections in, one service call per step, results out, latched.

    Every callback takes the same lock, so a step never sees a selection change half-way.
    """

    def __init__(self, config: FindCanConfig, scene_points):
        import rospy
        import tf2_ros
        from geometry_msgs.msg import PointStamped, PoseArray, PoseStamped
        from sensor_msgs.msg import PointCloud2
        from visualization_msgs.msg import Marker, MarkerArray

        from example_pcl.conversions import array_to_cloud, xyz_view
        from example_pcl.srv import ProcessMode

        self._rospy = rospy
        self.config = config
        self.lock = threading.Lock()
        self._warned_kinds = set()
        xyz = np.ascontiguousarray(xyz_view(scene_points), dtype=np.float32)
        self.finder = CanFinder(xyz, config.finder)
        self.tf_buffer = tf2_ros.Buffer()
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)

        def pub(topic, kind):
            return rospy.Publisher(topic, kind, queue_size=1, latch=True)

        self.scene_pub = pub(SCENE_TOPIC, PointCloud2)
        self.model_pub = pub(MODEL_TOPIC, PointCloud2)
        self.pose_pub = pub(POSE_TOPIC, PoseStamped)
        self.marker_pub = pub(MARKER_TOPIC, Marker)
        self.target_pub = pub(TARGET_POSE_TOPIC, PoseStamped) if config.target_frame else None
        self.patch_pub = pub(PATCH_TOPIC, PointCloud2)
        self.poses_pub = pub(POSES_TOPIC, PoseArray)
        self.markers_pub = pub(MARKERS_TOPIC, MarkerArray)
        self.scene_pub.publish(array_to_cloud(scene_points, frame_id=config.frame_id, stamp=rospy.Time.now()))
        self.subscribers = [rospy.Subscriber(SELECTED_TOPIC, PointCloud2, self.on_selected_points, queue_size=2),
                            rospy.Subscriber(CLICKED_TOPIC, PointStamped, self.on_clicked_point, queue_size=2)]
        self.service = rospy.Service(SERVICE, ProcessMode, self.on_process_mode)

    def topics(self):
        """The resolved names of the node's topics and service, for the start-up log."""
        resolve = self._rospy.resolve_name
        return {name: resolve(name) for name in (SCENE_TOPIC, MODEL_TOPIC, POSE_TOPIC, MARKER_TOPIC, POSES_TOPIC,
                                                 MARKERS_TOPIC, PATCH_TOPIC,
                                                 SELECTED_TOPIC, CLICKED_TOPIC, SERVICE)}

    # --- frames ---

    def _lookup_into_scene(self, frame_id, timeout):
        """The latest tf2 transform (geometry_msgs/Transform) from `frame_id` into ~frame_id, or
        None with tf2's reason when it has none within `timeout` (s)."""
        import tf2_ros

        try:
            return self.tf_buffer.lookup_transform(self.config.frame_id, frame_id, self._rospy.Time(0),
                                                   self._rospy.Duration(timeout)).transform, None
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as e:
            return None, str(e)

    def _to_scene_frame(self, frame_id, what):
        """4x4 from `frame_id` into ~frame_id (identity when they match or frame_id is empty);
        raises PerceptionError when tf2 cannot give it."""
        frame_id = (frame_id or "").lstrip("/")
        if not frame_id or frame_id == self.config.frame_id:
            return None
        tf, reason = self._lookup_into_scene(frame_id, 0.2)
        if tf is None:
            raise PerceptionError(f"{what} is in frame '{frame_id}', not '{self.config.frame_id}', and tf2 has no "
                                  f"transform between them ({reason}); set rviz's fixed frame to "
                                  f"'{self.config.frame_id}'")
        return messages.matrix_from_transform(tf)

    def _up_prior(self):
        """Mode 4's up prior: the +z axis of ~up_frame in ~frame_id, looked up through tf2 now
        (unit (3,)); None without ~up_frame. Raises PerceptionError when tf2 has no transform,
        so the search never runs on a guessed "up"."""
        up_frame = self.config.up_frame
        if not up_frame:
            return None
        tf, reason = self._lookup_into_scene(up_frame, 0.5)
        if tf is None:
            raise PerceptionError(f"no up prior: tf2 has no transform from ~up_frame '{up_frame}' to "
                                  f"'{self.config.frame_id}' ({reason}); publish it (e.g. a static transform) "
                                  "or clear ~up_frame to search without a prior")
        q = tf.rotation
        return transforms.up_vector((q.x, q.y, q.z, q.w))

    # --- callbacks ---

    def on_selected_points(self, msg):
        """selected_points: the points become the latest selection (in ~frame_id)."""
        from example_pcl.conversions import validate_cloud, xyz_view

        with self.lock:
            try:
                pts = np.asarray(xyz_view(validate_cloud(msg, MAX_SELECTION_POINTS)), dtype=float).reshape(-1, 3)
                T = self._to_scene_frame(msg.header.frame_id, "the selection")
                if T is not None:
                    pts = transforms.apply(T, pts)
                n = self.finder.select(pts)
            except PerceptionError as e:
                self.finder.reject_selection(str(e))
                self._acknowledge(None, msg.header.stamp)
                kind = warning_kind(e)
                if kind in self._warned_kinds:
                    self._rospy.logdebug("find_can: selection rejected: %s", e)
                else:
                    self._warned_kinds.add(kind)
                    self._rospy.logwarn("find_can: selection rejected: %s (further selections rejected for this "
                                        "reason are logged at debug level)", e)
                return
            self._acknowledge(pts, msg.header.stamp)
            self._rospy.loginfo("find_can: selection of %d finite point(s) (of %d) stored as the patch for the next "
                                "mode 0 (table) or 2 (can)", n, len(pts))

    def on_clicked_point(self, msg):
        """clicked_point: the scene's points within ~patch_radius of the click become the selection."""
        with self.lock:
            p = np.array([msg.point.x, msg.point.y, msg.point.z])
            try:
                T = self._to_scene_frame(msg.header.frame_id, "the clicked point")
                if T is not None:
                    p = transforms.apply(T, p)
                pts = self.finder.points_near(p, self.config.patch_radius)
                n = self.finder.select(pts)
            except PerceptionError as e:
                self.finder.reject_selection(str(e))
                self._acknowledge(None, msg.header.stamp)
                self._rospy.logwarn("find_can: clicked point rejected: %s", e)
                return
            self._acknowledge(pts, msg.header.stamp)
            self._rospy.loginfo("find_can: clicked (%.3f, %.3f, %.3f): %d scene point(s) within %.0f mm stored as the "
                                "patch for the next mode 0 (table) or 2 (can)", p[0], p[1], p[2], n,
                                self.config.patch_radius * 1e3)

    def _acknowledge(self, points, stamp):
        """Publishes the stored selection (sensor frame; None = rejected, sent empty) on selected_patch."""
        from example_pcl.conversions import xyz_to_cloud

        pts = np.zeros((0, 3), np.float32) if points is None else np.asarray(points, dtype=np.float32).reshape(-1, 3)
        self.patch_pub.publish(xyz_to_cloud(pts, frame_id=self.config.frame_id, stamp=stamp))

    def on_process_mode(self, request):
        """process_mode: runs the step under the lock, publishes what it found, answers with its message."""
        from example_pcl.srv import ProcessModeResponse

        with self.lock:
            try:
                up = self._up_prior() if request.mode == Mode.FIND_CAN_AUTO else None
            except PerceptionError as e:
                self._rospy.logerr("find_can: mode %s not run: %s", request.mode, e)
                return ProcessModeResponse(success=False, message=str(e))
            prior = "" if up is None else "; up prior ({:.3f}, {:.3f}, {:.3f}) (+z of {})".format(
                *(up + 0.0), self.config.up_frame)  # + 0.0: no "-0.000"
            try:
                result = self.finder.process(request.mode, up=up)
                message = self._publish(result) + prior
            except PerceptionError as e:
                if request.mode == Mode.FIND_CAN_AUTO:  # the search ran and found no can: say so on can_poses
                    self._publish_all_cans((), self.config.frame_id, self._rospy.Time.now())
                self._rospy.logwarn("find_can: mode %s failed: %s%s", request.mode, e, prior)
                return ProcessModeResponse(success=False, message=f"{e}{prior}")
            self._rospy.loginfo("find_can: mode %d: %s", request.mode, message)
            return ProcessModeResponse(success=True, message=message)

    def _publish(self, result):
        """Publishes a step's result; returns its message (with the pose in ~target_frame when set)."""
        from example_pcl.conversions import xyz_to_cloud

        rospy, frame = self._rospy, self.config.frame_id
        stamp = rospy.Time.now()
        message = result.message
        if result.mode == Mode.IDENTIFY_PLANE:
            self.marker_pub.publish(messages.delete_marker(frame))
        self.model_pub.publish(xyz_to_cloud(result.model, frame_id=frame, stamp=stamp))
        if result.mode == Mode.FIND_CAN_AUTO:
            self._publish_all_cans(result.cans, frame, stamp)
        if result.can is not None:
            can = result.can
            pose = messages.pose_message(can.T_sensor_from_can, frame, stamp)
            self.pose_pub.publish(pose)
            self.marker_pub.publish(messages.can_marker(can.T_sensor_from_can, can.radius, can.height, frame, stamp))
            message += f" (frame {frame})"
            if self.target_pub is not None:
                message += "; " + self._publish_in_target(pose)
        return message

    def _publish_all_cans(self, cans, frame, stamp):
        """Mode 4's can_poses (PoseArray) and can_markers (MarkerArray: a DELETEALL, so no marker of
        an earlier search stays, then one cylinder per can); both empty of cans when none was found."""
        self.poses_pub.publish(messages.can_poses(cans, frame, stamp))
        self.markers_pub.publish(messages.can_markers(cans, frame, stamp))

    def _publish_in_target(self, pose):
        """Publishes the pose in ~target_frame through tf2; returns a clause for the message."""
        import tf2_geometry_msgs
        import tf2_ros

        target = self.config.target_frame
        try:
            tf = self.tf_buffer.lookup_transform(target, pose.header.frame_id, self._rospy.Time(0),
                                                 self._rospy.Duration(0.5))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as e:
            self._rospy.logwarn("find_can: no transform %s -> %s: %s", pose.header.frame_id, target, e)
            return f"not in {target}: tf2 has no transform from {pose.header.frame_id}"
        out = tf2_geometry_msgs.do_transform_pose(pose, tf)
        out.header.stamp = pose.header.stamp
        self.target_pub.publish(out)
        p = out.pose.position
        return f"in {target}: ({p.x:.3f}, {p.y:.3f}, {p.z:.3f}) m"


def main(argv=None) -> int:
    """Entry point of ``rosrun example_pcl find_can``; returns the exit code."""
    import rospy

    from example_pcl.pcd import read_pcd

    rospy.init_node("find_can", argv=sys.argv if argv is None else argv)
    try:
        config = FindCanConfig.from_params(rospy.get_param)
        if not os.path.isfile(config.pcd_file):
            raise PerceptionError(f"PCD file '{config.pcd_file}' does not exist (set ~pcd_file, or generate a scene "
                                  "with `rosrun example_pcl make_scene OUT.pcd`)")
        cloud = read_pcd(config.pcd_file)
        node = FindCanNode(config, cloud.points)
    except PerceptionError as e:
        rospy.logfatal("find_can: %s", e)
        return 1
    rospy.loginfo("find_can: %s", config.describe())
    rospy.loginfo("find_can: scene %s (%s points), topics %s", config.pcd_file,
                  "x".join(str(s) for s in cloud.points.shape), " ".join(node.topics().values()))
    rospy.loginfo("find_can: ready. Select a table patch, then `rosservice call %s 0`; modes: %s",
                  node.topics()[SERVICE], describe_modes())
    rospy.spin()
    return 0
