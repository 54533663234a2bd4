"""Arrays -> ROS messages (and poses back): every pose and marker find_can publishes is built here.

PointCloud2 builders live in example_pcl.conversions (``xyz_to_cloud``, ``array_to_cloud``).
Transforms are 4x4 float64 ``T_frame_from_object`` (example_pcl.transforms); lengths in metres.
Message classes import without a master, so all of this is testable without one.
"""
import dataclasses

from geometry_msgs.msg import Pose, PoseArray, PoseStamped, Transform, TransformStamped, Vector3
from shape_msgs.msg import SolidPrimitive
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from example_pcl import transforms
from example_pcl.msg import Can as CanMsg
from example_pcl.msg import CanArray

CAN_NS = "can"  # the namespace of can_marker's single marker
CANS_NS = "can_markers"  # the namespace of can_markers' markers, one id per can
LABELS_NS = "can_labels"  # can_tracker's text labels, marker id = track id as the cylinders'
TABLE_NS = "table"  # can_tracker's table marker


def header(frame_id, stamp=None):
    """std_msgs/Header in frame_id, stamped when a stamp (rospy.Time) is given."""
    msg = Header(frame_id=frame_id)
    if stamp is not None:
        msg.stamp = stamp
    return msg


def pose(T):
    """geometry_msgs/Pose of a 4x4 transform: its translation (m) and rotation (x, y, z, w)."""
    translation, q = transforms.to_translation_quaternion_xyzw(T)
    msg = Pose()
    p, o = msg.position, msg.orientation
    p.x, p.y, p.z = (float(v) for v in translation)
    o.x, o.y, o.z, o.w = (float(v) for v in q)
    return msg


def matrix_from_pose(pose_msg):
    """4x4 float64 of a geometry_msgs/Pose (the inverse of pose)."""
    p, q = pose_msg.position, pose_msg.orientation
    return transforms.from_translation_quaternion_xyzw((p.x, p.y, p.z), (q.x, q.y, q.z, q.w))


def matrix_from_transform(transform_msg):
    """4x4 float64 of a geometry_msgs/Transform (e.g. tf2's lookup_transform(...).transform)."""
    t, q = transform_msg.translation, transform_msg.rotation
    return transforms.from_translation_quaternion_xyzw((t.x, t.y, t.z), (q.x, q.y, q.z, q.w))


def transform_stamped(T_parent_from_child, parent, child, stamp=None):
    """geometry_msgs/TransformStamped parent -> child of a 4x4 transform (the inverse of
    matrix_from_transform), e.g. for a tf2 broadcaster."""
    p = pose(T_parent_from_child)
    transform = Transform(rotation=p.orientation)
    transform.translation.x, transform.translation.y, transform.translation.z = p.position.x, p.position.y, p.position.z
    return TransformStamped(header=header(parent, stamp), child_frame_id=child, transform=transform)


def pose_message(T, frame_id, stamp=None):
    """geometry_msgs/PoseStamped of a 4x4 transform (the pose of a frame in frame_id)."""
    return PoseStamped(header=header(frame_id, stamp), pose=pose(T))


def pose_array(Ts, frame_id, stamp=None):
    """geometry_msgs/PoseArray of 4x4 transforms, in frame_id (empty for none)."""
    return PoseArray(header=header(frame_id, stamp), poses=[pose(T) for T in Ts])


def can_marker(T_sensor_from_can, radius, height, frame_id, stamp=None, ns=CAN_NS, marker_id=0):
    """visualization_msgs/Marker: a CYLINDER of the can (radius, height in m; T_sensor_from_can's
    origin the base centre, z the axis), posed half a height above the base along the axis, as
    Marker poses give a cylinder's centre."""
    centre = transforms.as_transform(T_sensor_from_can).copy()
    centre[:3, 3] += 0.5 * height * centre[:3, 2]
    marker = Marker(header=header(frame_id, stamp), ns=ns, id=marker_id, type=Marker.CYLINDER, action=Marker.ADD,
                    pose=pose(centre))
    marker.scale.x = marker.scale.y = 2.0 * radius
    marker.scale.z = height
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = 0.1, 0.8, 1.0, 0.6
    return marker


def delete_marker(frame_id, ns=CAN_NS, marker_id=0, stamp=None):
    """visualization_msgs/Marker deleting one marker (by default can_marker's: a new plane forgets the can)."""
    return Marker(header=header(frame_id, stamp), ns=ns, id=marker_id, action=Marker.DELETE)


def delete_all_marker(frame_id, stamp=None):
    """visualization_msgs/Marker deleting every marker of its topic (a DELETEALL)."""
    return Marker(header=header(frame_id, stamp), action=Marker.DELETEALL)


def can_poses(cans, frame_id, stamp=None):
    """geometry_msgs/PoseArray of the cans' poses (example_pcl.can.Can: origin the base centre,
    z the axis), in frame_id; empty for none."""
    return pose_array([c.T_sensor_from_can for c in cans], frame_id, stamp)


def can_markers(cans, frame_id, stamp=None):
    """visualization_msgs/MarkerArray of the cans (example_pcl.can.Can): a DELETEALL, so no marker
    of an earlier search stays, then one CYLINDER of each can's own radius and height (namespace
    CANS_NS, ids 0, 1, ... in the order given)."""
    markers = [delete_all_marker(frame_id, stamp)]
    markers += [can_marker(c.T_sensor_from_can, c.radius, c.height, frame_id, stamp, ns=CANS_NS, marker_id=i)
                for i, c in enumerate(cans)]
    return MarkerArray(markers=markers)


def cylinder_primitive(radius, height):
    """shape_msgs/SolidPrimitive CYLINDER of radius and height (m), the form MoveIt's planning scene
    takes. A primitive cylinder is centred on its pose: half a height up the axis from a can's base."""
    shape = SolidPrimitive(type=SolidPrimitive.CYLINDER, dimensions=[0.0, 0.0])
    shape.dimensions[SolidPrimitive.CYLINDER_HEIGHT] = float(height)
    shape.dimensions[SolidPrimitive.CYLINDER_RADIUS] = float(radius)
    return shape


def can_message(can, track_id=0, age=0, confidence=1.0, velocity=(0.0, 0.0, 0.0)):
    """example_pcl/Can of an example_pcl.can.Can: the pose (origin the base centre, z the axis), size,
    fit quality, support and a SolidPrimitive CYLINDER. track_id, age (frames), confidence (0..1)
    and velocity (m/s) are the tracker's; a single search gives id = its rank, age 0, confidence 1."""
    return CanMsg(id=int(track_id), pose=pose(can.T_sensor_from_can), radius=float(can.radius),
                  height=float(can.height), fit_rms=float(can.rms_error), visible_arc=float(can.arc_coverage),
                  n_points=int(can.n_fit_points), age=int(age), confidence=float(confidence),
                  velocity=Vector3(*(float(v) for v in velocity)), support=str(can.support),
                  base_seen=bool(can.base_seen), end_seen=bool(can.end_seen),
                  shape=cylinder_primitive(can.radius, can.height))


def can_array(cans, frame_id, stamp=None):
    """example_pcl/CanArray of the cans (example_pcl.can.Can) of one search, ids 0, 1, ... in order."""
    return CanArray(header=header(frame_id, stamp), cans=[can_message(c, i) for i, c in enumerate(cans)])


# --- tracked cans (can_tracker) -------------------------------------------------------------------


def tracked_can(track):
    """The example_pcl.can.Can a track (example_pcl.tracking.Track) stands for: its last detection
    with the smoothed pose, radius and height."""
    return dataclasses.replace(track.detection, T_sensor_from_can=track.pose, radius=float(track.radius),
                               height=float(track.height))


def track_array(tracks, frame_id, stamp=None):
    """example_pcl/CanArray of tracks (example_pcl.tracking.Track, in frame_id), in the order given:
    id = track id, the smoothed pose and size, the last fit's quality, age, confidence, velocity."""
    return CanArray(header=header(frame_id, stamp),
                    cans=[can_message(tracked_can(t), t.id, t.age, t.confidence, t.velocity) for t in tracks])


def track_poses(tracks, frame_id, stamp=None):
    """geometry_msgs/PoseArray of the tracks' smoothed poses, in the order given (as track_array)."""
    return pose_array([t.pose for t in tracks], frame_id, stamp)


def label_marker(text, position, frame_id, stamp=None, ns=LABELS_NS, marker_id=0, size=0.03):
    """visualization_msgs/Marker: a TEXT_VIEW_FACING label `text` at position (m, frame_id), its
    letters size (m) tall."""
    marker = Marker(header=header(frame_id, stamp), ns=ns, id=marker_id, type=Marker.TEXT_VIEW_FACING,
                    action=Marker.ADD, text=text)
    marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = (float(v) for v in position)
    marker.pose.orientation.w = 1.0
    marker.scale.z = size
    marker.color.r = marker.color.g = marker.color.b = marker.color.a = 1.0
    return marker


def track_markers(tracks, ended_ids, frame_id, stamp=None):
    """visualization_msgs/MarkerArray of tracks: per track a CYLINDER along its axis (namespace
    CANS_NS) and a label "can 3, r 33 mm" above it (LABELS_NS; above a lying can's middle), both
    with marker id = track id, greyed while the track coasts unseen; then a DELETE of both for
    every id in ended_ids."""
    markers = []
    for t in tracks:
        T = t.pose
        cylinder = can_marker(T, t.radius, t.height, frame_id, stamp, ns=CANS_NS, marker_id=t.id)
        if not t.seen:
            cylinder.color.r = cylinder.color.g = cylinder.color.b = 0.6
        # A lying can's pose has x up from the table (tracking.Track.pose).
        top = t.center + (t.radius + 0.03) * T[:3, 0] if t.lying else t.base_center + (t.height + 0.03) * t.axis
        markers += [cylinder, label_marker(f"can {t.id}, r {1e3 * t.radius:.0f} mm", top, frame_id, stamp,
                                           marker_id=t.id)]
    for marker_id in ended_ids:
        for ns in (CANS_NS, LABELS_NS):
            markers.append(delete_marker(frame_id, ns=ns, marker_id=marker_id, stamp=stamp))
    return MarkerArray(markers=markers)


def table_marker(T_frame_from_plane, extent, frame_id, stamp=None, thickness=0.005):
    """visualization_msgs/Marker: the table as a thin CUBE (thickness m) in the plane z = 0 of
    T_frame_from_plane, over extent (x_min, x_max, y_min, y_max) of the plane frame (m)."""
    x0, x1, y0, y1 = extent
    T = transforms.compose(T_frame_from_plane, transforms.from_translation_quaternion_xyzw(
        (0.5 * (x0 + x1), 0.5 * (y0 + y1), -0.5 * thickness), (0.0, 0.0, 0.0, 1.0)))
    marker = Marker(header=header(frame_id, stamp), ns=TABLE_NS, id=0, type=Marker.CUBE, action=Marker.ADD,
                    pose=pose(T))
    marker.scale.x, marker.scale.y, marker.scale.z = max(x1 - x0, 1e-3), max(y1 - y0, 1e-3), thickness
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = 0.8, 0.6, 0.3, 0.5
    return marker
