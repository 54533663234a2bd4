"""find_can: the operator registers a can on a table, step by step, and gets its pose.

``rosrun example_pcl find_can`` (or ``roslaunch example_pcl find_can.launch``) loads a PCD scene, or
with ``~cloud_topic`` takes the newest cloud of a live stream, and waits for the operator: select
a table patch, ``rosservice call process_mode 0`` then ``1``; select a patch on the can's side,
``process_mode 2`` then ``3``; or ``process_mode 4`` for every can with no selection. Topics,
services and params: docs/find_can.md.
"""
import copy
import dataclasses
import os
import sys
import threading
import traceback
from typing import Callable, Optional, Tuple

import numpy as np

from example_pcl import messages, transforms
from example_pcl.can_finder import CanFinder, FinderConfig, Mode, describe_modes
from example_pcl.errors import OncePerKind, PerceptionError
from example_pcl.reconfigure import finder_from_values, param_names
from example_pcl.resources import default_scene_path

SCENE_TOPIC = "kinect_pointcloud"
MODEL_TOPIC = "plane_model"
POSE_TOPIC = "can_pose"
TARGET_POSE_TOPIC = "can_pose_target"
MARKER_TOPIC = "can_marker"
POSES_TOPIC = "can_poses"
MARKERS_TOPIC = "can_markers"
CANS_TOPIC = "cans"
PATCH_TOPIC = "selected_patch"
SELECTED_TOPIC = "selected_points"
CLICKED_TOPIC = "clicked_point"
SERVICE = "process_mode"
MAX_SELECTION_POINTS = 2_000_000  # more is a runaway publisher, not an operator's selection


@dataclasses.dataclass(frozen=True)
class FindCanConfig:
    """The effective configuration of find_can: the scene (pcd_file, or the newest cloud on
    cloud_topic when set), frames (up_frame: mode 4's up prior is its +z axis; "" = no prior), the
    sensor's position in the scene's frame (sensor_origin, m; None = the PCD's VIEWPOINT, or the
    frame's origin for a topic), the patch radius of a clicked point (m) and the FinderConfig."""

    pcd_file: str
    frame_id: str = "world"
    target_frame: str = ""
    up_frame: str = ""
    cloud_topic: str = ""
    sensor_origin: Optional[Tuple[float, float, float]] = None
    patch_radius: float = 0.03
    finder: FinderConfig = FinderConfig()

    @classmethod
    def from_params(cls, get_param: Callable[[str, object], object]) -> "FindCanConfig":
        """Reads the private params through ``get_param(name, default)`` (the finder's tolerances
        under their cfg/FindCan.cfg names); raises PerceptionError for a value that cannot work."""
        try:
            tolerances = {name: get_param("~" + name, None) for name in param_names(FinderConfig())}
            finder, _ = finder_from_values(FinderConfig(), {k: v for k, v in tolerances.items() if v is not None})
            pcd_file = str(get_param("~pcd_file", "") or default_scene_path())
            origin = get_param("~sensor_origin", None)
            if origin not in (None, ""):
                origin = tuple(float(v) for v in origin)
                if len(origin) != 3:
                    raise PerceptionError(f"~sensor_origin must be [x, y, z] (m), got {origin}")
            config = cls(pcd_file=os.path.abspath(os.path.expanduser(pcd_file)),
                         frame_id=str(get_param("~frame_id", cls.frame_id)).strip().lstrip("/"),
                         target_frame=str(get_param("~target_frame", cls.target_frame) or "").strip().lstrip("/"),
                         up_frame=str(get_param("~up_frame", cls.up_frame) or "").strip().lstrip("/"),
                         cloud_topic=str(get_param("~cloud_topic", cls.cloud_topic) or "").strip(),
                         sensor_origin=origin or None,
                         patch_radius=float(get_param("~patch_radius", cls.patch_radius)), finder=finder)
        except (TypeError, ValueError) as e:
            raise PerceptionError(f"bad parameter value: {e}") from None
        if not config.frame_id:
            raise PerceptionError("~frame_id must not be empty")
        if not config.patch_radius > 0:
            raise PerceptionError(f"~patch_radius must be > 0 m, got {config.patch_radius}")
        return config

    def describe(self):
        """One line: every effective value, for the start-up log."""
        f = self.finder
        scene = f"cloud_topic={self.cloud_topic}" if self.cloud_topic else f"pcd_file={self.pcd_file}"
        return (f"{scene} frame_id={self.frame_id} target_frame={self.target_frame or '(none)'} "
                f"up_frame={self.up_frame or '(none)'} sensor_origin={self.sensor_origin or '(from the scene)'} "
                f"z_eps={f.z_eps} m z_threshold={f.z_threshold} m can_radius={f.can_radius} m "
                f"can_height={f.can_height} m patch_radius={self.patch_radius} m r_eps={f.r_eps} m "
                f"max_iterations={f.max_iterations} fit_margin={f.fit_margin} m")


# --- the node -------------------------------------------------------------------------------------


def forget_latched(publisher):
    """Drops a latched rospy.Publisher's last message: later subscribers get nothing until the next
    publish. PoseStamped has no 'delete'; re-advertising the topic instead races with subscribers
    reconnecting to the same node URI and can leave them unconnected."""
    impl = getattr(publisher, "impl", None)
    if impl is None:  # a stand-in publisher (tests) keeps no latch
        return
    impl.acquire()  # the lock publish() takes, so a publish in flight is not half undone
    try:
        impl.latch = None
    finally:
        impl.release()


class FindCanNode:
    """Wires ROS to a CanFinder: selections in, one service call per step, results out, latched.

    Every callback takes the same lock, so a step never sees a selection change half-way.
    scene_points: the PCD scene (structured array), or None with ~cloud_topic (the newest cloud).
    """

    def __init__(self, config: FindCanConfig, scene_points=None, viewpoint=(0.0, 0.0, 0.0)):
        import rospy
        import tf2_ros
        from dynamic_reconfigure.server import Server
        from geometry_msgs.msg import PointStamped, PoseArray, PoseStamped
        from sensor_msgs.msg import PointCloud2
        from visualization_msgs.msg import Marker, MarkerArray

        from example_pcl.cfg import FindCanConfig as FindCanReconfigure
        from example_pcl.conversions import array_to_cloud, xyz_view
        from example_pcl.msg import CanArray
        from example_pcl.srv import ProcessMode

        self._rospy = rospy
        self.config = config
        self.lock = threading.Lock()
        self._rejections = OncePerKind(rospy.logwarn, rospy.logdebug)
        self.scene_frame = config.frame_id  # a live cloud's own frame once one is taken
        self.scene_stamp = None  # a live cloud's stamp, which the outputs then carry
        self._newest_cloud = None  # the newest message on ~cloud_topic
        origin = viewpoint if config.sensor_origin is None else config.sensor_origin
        finder_config = dataclasses.replace(config.finder, viewpoint=tuple(float(v) for v in origin))
        xyz = (np.zeros((0, 3), np.float32) if scene_points is None
               else np.ascontiguousarray(xyz_view(scene_points), dtype=np.float32))
        self.finder = CanFinder(xyz, finder_config)
        self.tf_buffer = tf2_ros.Buffer()
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)

        def pub(topic, kind):
            return rospy.Publisher(topic, kind, queue_size=1, latch=True)

        self.scene_pub = pub(SCENE_TOPIC, PointCloud2)
        self.model_pub = pub(MODEL_TOPIC, PointCloud2)
        self.pose_pub = pub(POSE_TOPIC, PoseStamped)
        self.marker_pub = pub(MARKER_TOPIC, Marker)
        self.target_pub = pub(TARGET_POSE_TOPIC, PoseStamped) if config.target_frame else None
        if config.target_frame:
            import tf2_geometry_msgs  # at start-up: a missing module stops the node, not a call half-way

            self._do_transform_pose = tf2_geometry_msgs.do_transform_pose
        self.patch_pub = pub(PATCH_TOPIC, PointCloud2)
        self.poses_pub = pub(POSES_TOPIC, PoseArray)
        self.markers_pub = pub(MARKERS_TOPIC, MarkerArray)
        self.cans_pub = pub(CANS_TOPIC, CanArray)
        if scene_points is not None:
            self.scene_pub.publish(array_to_cloud(scene_points, frame_id=config.frame_id, stamp=rospy.Time.now()))
        self.subscribers = [rospy.Subscriber(SELECTED_TOPIC, PointCloud2, self.on_selected_points, queue_size=2),
                            rospy.Subscriber(CLICKED_TOPIC, PointStamped, self.on_clicked_point, queue_size=2)]
        if config.cloud_topic:
            self.subscribers.append(rospy.Subscriber(config.cloud_topic, PointCloud2, self.on_cloud, queue_size=1,
                                                     buff_size=1 << 24))
        self.service = rospy.Service(SERVICE, ProcessMode, self.on_process_mode)
        self._reconfigure_values = None
        self.reconfigure_server = Server(FindCanReconfigure, self.on_reconfigure)

    def topics(self):
        """The resolved names of the node's topics and service, for the start-up log."""
        resolve = self._rospy.resolve_name
        names = [SCENE_TOPIC, MODEL_TOPIC, POSE_TOPIC, MARKER_TOPIC, POSES_TOPIC, MARKERS_TOPIC, CANS_TOPIC,
                 PATCH_TOPIC, SELECTED_TOPIC, CLICKED_TOPIC, SERVICE] + [self.config.cloud_topic] * bool(
                     self.config.cloud_topic)
        return {name: resolve(name) for name in names}

    # --- configuration and scene ---

    def on_reconfigure(self, values, level):
        """dynamic_reconfigure: the new tolerances apply from the next call (logged); values that
        cannot work are refused with an error and the previous ones kept."""
        with self.lock:
            try:
                config, changes = finder_from_values(self.finder.config, values)
                self.finder.set_config(config)
            except PerceptionError as e:
                self._rospy.logerr("find_can: reconfigure refused, previous values kept: %s", e)
                return self._reconfigure_values or values
            if changes and self._reconfigure_values is not None:
                self._rospy.loginfo("find_can: reconfigured (from the next call): %s", ", ".join(changes))
            self._reconfigure_values = copy.deepcopy(values)
            return values

    def on_cloud(self, msg):
        """~cloud_topic: keeps the newest cloud for the next mode 0 or 4 (checked when taken)."""
        self._newest_cloud = msg  # one reference swap: no lock needed, and a step never waits for it
        if self.scene_stamp is None:
            # Until mode 0 takes a cloud, the operator selects on the stream itself: in its frame.
            self.scene_frame = msg.header.frame_id.lstrip("/") or self.config.frame_id

    def _take_newest_cloud(self):
        """With ~cloud_topic, makes the newest cloud the scene (the selection kept) and republishes
        it on kinect_pointcloud; raises PerceptionError when none arrived or it is unusable."""
        from example_pcl.conversions import cloud_to_xyz, validate_cloud

        msg = self._newest_cloud
        if msg is None:
            raise PerceptionError(f"no cloud on {self._rospy.resolve_name(self.config.cloud_topic)} yet; "
                                  "is the sensor running?")
        validate_cloud(msg)
        self.finder.set_scene(cloud_to_xyz(msg, copy=True))
        self.scene_frame = msg.header.frame_id.lstrip("/") or self.config.frame_id
        self.scene_stamp = msg.header.stamp
        self.scene_pub.publish(msg)

    # --- frames ---

    def _lookup_into_scene(self, frame_id, timeout):
        """The latest tf2 transform (geometry_msgs/Transform) from `frame_id` into ~frame_id, or
        None with tf2's reason when it has none within `timeout` (s)."""
        import tf2_ros

        try:
            return self.tf_buffer.lookup_transform(self.scene_frame, frame_id, self._rospy.Time(0),
                                                   self._rospy.Duration(timeout)).transform, None
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as e:
            return None, str(e)

    def _to_scene_frame(self, frame_id, what):
        """4x4 from `frame_id` into ~frame_id (identity when they match or frame_id is empty);
        raises PerceptionError when tf2 cannot give it."""
        frame_id = (frame_id or "").lstrip("/")
        if not frame_id or frame_id == self.scene_frame:
            return None
        tf, reason = self._lookup_into_scene(frame_id, 0.2)
        if tf is None:
            raise PerceptionError(f"{what} is in frame '{frame_id}', not '{self.scene_frame}', and tf2 has no "
                                  f"transform between them ({reason}); set rviz's fixed frame to "
                                  f"'{self.scene_frame}'")
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
                                  f"'{self.scene_frame}' ({reason}); publish it (e.g. a static transform) "
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
                self._rejections("find_can: selection rejected", e)
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
        self.patch_pub.publish(xyz_to_cloud(pts, frame_id=self.scene_frame, stamp=stamp))

    def on_process_mode(self, request):
        """process_mode: runs the step under the lock, publishes what it found, answers with its message.

        A step that fails answers success=False with the reason; an unexpected error (a bug, a
        missing module) also restores the state from before the call, so nothing is half-changed.
        """
        from example_pcl.srv import ProcessModeResponse

        with self.lock:
            try:
                up = self._up_prior() if request.mode == Mode.FIND_CAN_AUTO else None
            except PerceptionError as e:
                self._rospy.logerr("find_can: mode %s not run: %s", request.mode, e)
                return ProcessModeResponse(success=False, message=str(e))
            saved = copy.copy(self.finder), self.scene_frame, self.scene_stamp
            try:
                return ProcessModeResponse(success=True, message=self._run_mode(request.mode, up))
            except PerceptionError as e:
                if self.config.cloud_topic and request.mode in (Mode.IDENTIFY_PLANE, Mode.FIND_CAN_AUTO):
                    self.finder, self.scene_frame, self.scene_stamp = saved  # the new cloud was not used
                self._rospy.logwarn("find_can: mode %s failed: %s", request.mode, e)
                return ProcessModeResponse(success=False, message=str(e))
            except Exception as e:  # noqa: BLE001 - the service must answer and the node keep its state
                self.finder, self.scene_frame, self.scene_stamp = saved
                self._rospy.logerr("find_can: mode %s: internal error, state restored:\n%s", request.mode,
                                   traceback.format_exc())
                return ProcessModeResponse(success=False, message=f"internal error in mode {request.mode} "
                                           f"({type(e).__name__}: {e}); nothing changed, see find_can's log")

    def _run_mode(self, mode, up):
        """Runs one mode (up: mode 4's prior or None) and publishes its result; returns the message
        or raises PerceptionError."""
        prior = "" if up is None else "; up prior ({:.3f}, {:.3f}, {:.3f}) (+z of {})".format(
            *(up + 0.0), self.config.up_frame)  # + 0.0: no "-0.000"
        if self.config.cloud_topic and mode in (Mode.IDENTIFY_PLANE, Mode.FIND_CAN_AUTO):
            self._take_newest_cloud()
        try:
            result = self.finder.process(mode, up=up)
        except PerceptionError as e:
            if mode == Mode.FIND_CAN_AUTO:  # the search ran and found no can: say so on can_poses
                self._publish_all_cans((), self.scene_frame, self._stamp())
            raise PerceptionError(f"{e}{prior}") from None
        message = self._publish(result) + prior
        self._rospy.loginfo("find_can: mode %d: %s", mode, message)
        return message

    def _stamp(self):
        """The outputs' stamp: the live cloud's, else now."""
        return self.scene_stamp if self.scene_stamp is not None else self._rospy.Time.now()

    def _publish(self, result):
        """Publishes a step's result; returns its message (with the pose in ~target_frame when set)."""
        from example_pcl.conversions import xyz_to_cloud

        frame, stamp = self.scene_frame, self._stamp()
        message = result.message
        if result.mode == Mode.IDENTIFY_PLANE:
            self._forget_can(frame, stamp)
        self.model_pub.publish(xyz_to_cloud(result.model, frame_id=frame, stamp=stamp))
        if result.mode == Mode.FIND_CAN_AUTO:
            self._publish_all_cans(result.cans, frame, stamp)
        if result.can is not None:
            can = result.can
            pose = messages.pose_message(can.T_sensor_from_can, frame, stamp)
            self.pose_pub.publish(pose)
            self.marker_pub.publish(messages.can_marker(can.T_sensor_from_can, can.radius, can.height, frame, stamp))
            if result.mode != Mode.FIND_CAN_AUTO:
                self.cans_pub.publish(messages.can_array([can], frame, stamp))
            message += f" (frame {frame})"
            if self.target_pub is not None:
                message += "; " + self._publish_in_target(pose)
        return message

    def _forget_can(self, frame, stamp):
        """A new table forgets the can: its marker deleted, can_poses, can_markers and cans emptied,
        and can_pose's (can_pose_target's) latched pose dropped, so no new subscriber gets it."""
        self.marker_pub.publish(messages.delete_marker(frame, stamp=stamp))
        self._publish_all_cans((), frame, stamp)
        for pub in (self.pose_pub, self.target_pub):
            if pub is not None:
                forget_latched(pub)

    def _publish_all_cans(self, cans, frame, stamp):
        """Mode 4's can_poses (PoseArray), can_markers (MarkerArray: a DELETEALL, so no marker of an
        earlier search stays, then one cylinder per can) and cans (CanArray, with each can's
        SolidPrimitive); all empty of cans when none was found."""
        self.poses_pub.publish(messages.can_poses(cans, frame, stamp))
        self.markers_pub.publish(messages.can_markers(cans, frame, stamp))
        self.cans_pub.publish(messages.can_array(cans, frame, stamp))

    def _publish_in_target(self, pose):
        """Publishes the pose in ~target_frame through tf2 at its stamp; returns a clause for the message."""
        import tf2_ros

        target = self.config.target_frame
        try:
            tf = self.tf_buffer.lookup_transform(target, pose.header.frame_id, self._lookup_time(),
                                                 self._rospy.Duration(0.5))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as e:
            self._rospy.logwarn("find_can: no transform %s -> %s: %s", pose.header.frame_id, target, e)
            return f"not in {target}: tf2 has no transform from {pose.header.frame_id}"
        out = self._do_transform_pose(pose, tf)
        out.header.stamp = pose.header.stamp
        self.target_pub.publish(out)
        p = out.pose.position
        return f"in {target}: ({p.x:.3f}, {p.y:.3f}, {p.z:.3f}) m"

    def _lookup_time(self):
        """tf2 lookups at the live cloud's stamp; for a PCD scene (no stamp of its own), the latest."""
        return self.scene_stamp if self.scene_stamp is not None else self._rospy.Time(0)


def main(argv=None) -> int:
    """Entry point of ``rosrun example_pcl find_can``; returns the exit code."""
    import rospy

    from example_pcl.pcd import read_pcd

    rospy.init_node("find_can", argv=sys.argv if argv is None else argv)
    try:
        config = FindCanConfig.from_params(rospy.get_param)
        if config.cloud_topic:
            node = FindCanNode(config)
            scene = f"the newest cloud on {rospy.resolve_name(config.cloud_topic)} at each mode 0 and 4"
        else:
            if not os.path.isfile(config.pcd_file):
                raise PerceptionError(f"PCD file '{config.pcd_file}' does not exist (set ~pcd_file, or generate a "
                                      "scene with `rosrun example_pcl make_scene OUT.pcd`)")
            cloud = read_pcd(config.pcd_file)
            # PCD's VIEWPOINT records where the sensor was: normals turn toward it.
            node = FindCanNode(config, cloud.points, viewpoint=cloud.origin)
            scene = f"{config.pcd_file} ({'x'.join(str(s) for s in cloud.points.shape)} points)"
    except PerceptionError as e:
        rospy.logfatal("find_can: %s", e)
        return 1
    rospy.loginfo("find_can: %s", config.describe())
    rospy.loginfo("find_can: scene %s, sensor at %s m; topics %s", scene, node.finder.config.viewpoint,
                  " ".join(node.topics().values()))
    rospy.loginfo("find_can: ready. Select a table patch, then `rosservice call %s 0`; modes: %s",
                  node.topics()[SERVICE], describe_modes())
    rospy.spin()
    return 0
