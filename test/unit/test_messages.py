"""Tests of example_pcl.messages: arrays -> poses and markers (message classes, no master)."""
import dataclasses

import numpy as np
import pytest
import rospy
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


def test_can_message_carries_support_and_what_was_seen():
    """support, base_seen and end_seen reach the message as the Can has them."""
    T = np.eye(4)
    can = Can(T_sensor_from_can=T, radius=0.03, height=0.1, rms_error=0.001, arc_coverage=2.0, n_points=300,
              n_fit_points=250, center_plane=np.zeros(2), support="can", base_seen=False, end_seen=False)
    msg = messages.can_message(can, track_id=2)
    assert (msg.id, msg.support, msg.base_seen, msg.end_seen) == (2, "can", False, False)
    seen = messages.can_message(dataclasses.replace(can, base_seen=True, end_seen=True))
    assert (seen.base_seen, seen.end_seen) == (True, True)


def _track(track_id, seen=True):
    from example_pcl.tracking import Track

    T = np.eye(4)
    T[:3, 3] = (0.1 * track_id, 0.0, 1.0)
    can = Can(T_sensor_from_can=T, radius=0.033, height=0.12, rms_error=0.001, arc_coverage=3.0, n_points=400,
              n_fit_points=350, center_plane=np.zeros(2))
    return Track(id=track_id, base_center=T[:3, 3].copy(), velocity=np.array([0.01, 0.0, 0.0]), axis=T[:3, 2].copy(),
                 radius=0.0334, height=0.121, detection=can, age=4, missed=0 if seen else 2, confidence=0.9)


def test_track_messages_carry_the_track_ids_and_smoothed_values():
    """CanArray and PoseArray in the tracks' order; id, age, confidence, velocity and the smoothed size."""
    tracks = [_track(3), _track(7)]
    array, poses = messages.track_array(tracks, "base_link"), messages.track_poses(tracks, "base_link")
    assert [c.id for c in array.cans] == [3, 7] and len(poses.poses) == 2
    c = array.cans[0]
    assert (c.radius, c.height, c.age, c.n_points) == (0.0334, 0.121, 4, 350)
    assert c.confidence == pytest.approx(0.9) and c.velocity.x == pytest.approx(0.01)
    assert c.pose.position.x == pytest.approx(0.3) and poses.poses[1].position.x == pytest.approx(0.7)


def test_track_markers_use_the_track_id_and_delete_ended_tracks():
    """A cylinder and a label per track with marker id = track id; a DELETE of both per ended id."""
    stamp = rospy.Time(5)
    markers = messages.track_markers([_track(3), _track(4, seen=False)], [1], "base_link", stamp).markers
    cylinders = [m for m in markers if m.ns == messages.CANS_NS and m.action == Marker.ADD]
    labels = [m for m in markers if m.ns == messages.LABELS_NS and m.action == Marker.ADD]
    assert [m.id for m in cylinders] == [3, 4] and all(m.type == Marker.CYLINDER for m in cylinders)
    assert [m.text for m in labels] == ["can 3, r 33 mm", "can 4, r 33 mm"]
    assert cylinders[1].color.r == cylinders[1].color.g  # a coasting track is grey
    deletes = [(m.ns, m.id, m.header.stamp) for m in markers if m.action == Marker.DELETE]
    assert deletes == [(messages.CANS_NS, 1, stamp), (messages.LABELS_NS, 1, stamp)]


def test_table_marker_spans_the_extent_in_the_plane():
    """A thin CUBE centred on the extent's middle, in the plane z = 0 (its top face)."""
    T = np.eye(4)
    T[:3, 3] = (0.0, 0.0, 1.0)
    m = messages.table_marker(T, (-0.2, 0.4, -0.1, 0.1), "camera")
    assert m.type == Marker.CUBE and (m.scale.x, m.scale.y) == pytest.approx((0.6, 0.2))
    assert (m.pose.position.x, m.pose.position.y, m.pose.position.z) == pytest.approx((0.1, 0.0, 1.0 - m.scale.z / 2))


def test_transform_stamped_round_trips_through_matrix_from_transform():
    """transform_stamped(T, parent, child, stamp) names parent and child, carries the stamp, and
    matrix_from_transform gives T back."""
    import rospy

    T = transforms.from_translation_quaternion_xyzw((0.1, -0.2, 0.3), (0.0, 0.6, 0.0, 0.8))
    msg = messages.transform_stamped(T, "base_link", "camera", rospy.Time(7))
    assert (msg.header.frame_id, msg.child_frame_id, msg.header.stamp) == ("base_link", "camera", rospy.Time(7))
    assert_allclose(messages.matrix_from_transform(msg.transform), T, atol=1e-12)
