"""Arrays -> ROS messages (and poses back): every pose and marker find_can publishes is built here.

PointCloud2 builders live in example_pcl.conversions (``xyz_to_cloud``, ``array_to_cloud``).
Transforms are 4x4 float64 ``T_frame_from_object`` (example_pcl.transforms); lengths in metres.
Message classes import without a master, so all of this is testable without one.
"""
from geometry_msgs.msg import Pose, PoseArray, PoseStamped, Vector3
from shape_msgs.msg import SolidPrimitive
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from example_pcl import transforms
from example_pcl.msg import Can as CanMsg
from example_pcl.msg import CanArray

CAN_NS = "can"  # the namespace of can_marker's single marker
CANS_NS = "can_markers"  # the namespace of can_markers' markers, one id per can


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
                  base_seen=bool(can.base_seen), shape=cylinder_primitive(can.radius, can.height))


def can_array(cans, frame_id, stamp=None):
    """example_pcl/CanArray of the cans (example_pcl.can.Can) of one search, ids 0, 1, ... in order."""
    return CanArray(header=header(frame_id, stamp), cans=[can_message(c, i) for i, c in enumerate(cans)])
