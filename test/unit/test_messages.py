"""Tests of example_pcl.messages: arrays -> poses and markers (message classes, no master)."""
import numpy as np
import pytest
from geometry_msgs.msg import Pose, Transform
from numpy.testing import assert_allclose
from visualization_msgs.msg import Marker

from example_pcl import geometry, messages, transforms
from example_pcl.can import Can


def a_can(T, radius=0.033, height=0.122):
    return Can(T_sensor_from_can=T, radius=radius, height=height, rms_error=0.001, arc_coverage=3.0, n_points=500,
               n_fit_points=400, center_plane=np.zeros(2))


def test_pose_message_is_the_transform():
    """pose_message carries the transform's origin and rotation in the given frame."""
    T = geometry.plane_frame((0.0, -0.62, -0.78), (0.1, 0.2, 1.0))
    msg = messages.pose_message(T, "world")
    p, q = msg.pose.position, msg.pose.orientation
    assert msg.header.frame_id == "world"
    assert_allclose(transforms.from_translation_quaternion_xyzw((p.x, p.y, p.z), (q.x, q.y, q.z, q.w)), T,
                    atol=1e-12)


def test_pose_round_trips_through_pose_and_transform_messages():
    """matrix_from_pose(pose(T)) is T; a geometry_msgs/Transform with the same numbers gives T too;
    the stamp given is the header's."""
    import rospy

    T = geometry.plane_frame((0.3, -0.5, -0.8), (-0.4, 0.2, 1.7))
    assert_allclose(messages.matrix_from_pose(messages.pose(T)), T, atol=1e-12)
    tf = Transform()
    tf.translation.x, tf.translation.y, tf.translation.z = T[:3, 3]
    o = messages.pose(T).orientation
    tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w = o.x, o.y, o.z, o.w
    assert_allclose(messages.matrix_from_transform(tf), T, atol=1e-12)
    assert messages.pose_message(T, "map", rospy.Time(12, 5)).header.stamp == rospy.Time(12, 5)
    assert isinstance(messages.pose(T), Pose)


def test_marker_is_a_cylinder_centred_half_a_height_up():
    """can_marker is a CYLINDER of the can's diameter and height whose pose is the cylinder's centre."""
    T = geometry.plane_frame((0.0, -0.62, -0.78), (0.0, 0.0, 1.0))
    marker = messages.can_marker(T, 0.033, 0.122, "world")
    assert marker.type == Marker.CYLINDER and marker.action == Marker.ADD
    assert (marker.scale.x, marker.scale.y, marker.scale.z) == (0.066, 0.066, 0.122)
    p = marker.pose.position
    assert_allclose([p.x, p.y, p.z], T[:3, 3] + 0.061 * T[:3, 2], atol=1e-12)
    assert marker.header.frame_id == "world" and marker.color.a > 0
    assert_allclose(messages.matrix_from_pose(marker.pose)[:3, :3], T[:3, :3], atol=1e-12)
    assert (marker.ns, marker.id) == (messages.CAN_NS, 0)


def test_delete_markers():
    """delete_marker deletes can_marker's marker (same ns and id); delete_all_marker is a DELETEALL."""
    delete = messages.delete_marker("world")
    added = messages.can_marker(np.eye(4), 0.03, 0.1, "world")
    assert delete.action == Marker.DELETE and (delete.ns, delete.id) == (added.ns, added.id)
    assert delete.header.frame_id == "world"
    clear = messages.delete_all_marker("cam")
    assert clear.action == Marker.DELETEALL and clear.header.frame_id == "cam"


def test_delete_markers_carry_the_stamp_given():
    """A DELETE or DELETEALL sent for a cloud carries that cloud's stamp (rviz orders by it)."""
    import rospy

    stamp = rospy.Time(12, 34)
    assert messages.delete_marker("world", stamp=stamp).header.stamp == stamp
    assert messages.delete_all_marker("cam", stamp).header.stamp == stamp
    assert messages.can_markers([], "cam", stamp).markers[0].header.stamp == stamp


@pytest.mark.parametrize("n", [0, 1, 3])
def test_can_poses_and_markers_one_per_can(n):
    """can_poses holds each can's pose in order; can_markers a DELETEALL then one CYLINDER per can
    of that can's own radius and height, ids 0..n-1; both stamped and in the frame given."""
    import rospy

    stamp = rospy.Time(3, 0)
    cans = [a_can(geometry.plane_frame((0.0, -0.6, -0.8), (0.1 * i, 0.0, 1.0)), radius=0.03 + 0.01 * i,
                  height=0.1 + 0.02 * i) for i in range(n)]
    poses = messages.can_poses(cans, "cam", stamp)
    assert poses.header.frame_id == "cam" and poses.header.stamp == stamp and len(poses.poses) == n
    for pose, can in zip(poses.poses, cans):
        assert_allclose(messages.matrix_from_pose(pose), can.T_sensor_from_can, atol=1e-12)
    markers = messages.can_markers(cans, "cam", stamp).markers
    assert len(markers) == n + 1 and markers[0].action == Marker.DELETEALL and markers[0].header.frame_id == "cam"
    for i, (marker, can) in enumerate(zip(markers[1:], cans)):
        assert (marker.type, marker.action, marker.ns, marker.id) == (Marker.CYLINDER, Marker.ADD, messages.CANS_NS, i)
        assert marker.scale.x == pytest.approx(2 * can.radius) and marker.scale.z == pytest.approx(can.height)
        assert marker.header.stamp == stamp
