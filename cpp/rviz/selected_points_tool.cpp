#include "selected_points_tool.hpp"

#include <OgreAxisAlignedBox.h>
#include <pluginlib/class_list_macros.hpp>
#include <rviz/default_plugin/point_cloud_common.h>
#include <rviz/display_context.h>
#include <rviz/properties/string_property.h>
#include <rviz/selection/selection_handler.h>
#include <rviz/selection/selection_manager.h>
#include <rviz/viewport_mouse_event.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include <vector>

namespace example_pcl
{
namespace
{
constexpr int kMaxFramesToWait = 30;  // one second at rviz's 30 Hz
}  // namespace

SelectedPointsTool::SelectedPointsTool()
{
  shortcut_key_ = 'l';
  topic_property_ = new rviz::StringProperty("Topic", "/selected_points",
                                             "sensor_msgs/PointCloud2 topic the selected points are published on.",
                                             getPropertyContainer(), SLOT(updateTopic()), this);
}

void SelectedPointsTool::onInitialize()
{
  rviz::SelectionTool::onInitialize();
  setName("Publish Selection");
  updateTopic();
}

void SelectedPointsTool::updateTopic()
{
  // Latched: a find_can started after the drag still receives the operator's last selection.
  publisher_ = nh_.advertise<sensor_msgs::PointCloud2>(topic_property_->getStdString(), 1, true);
}

int SelectedPointsTool::processMouseEvent(rviz::ViewportMouseEvent& event)
{
  // The same reading of the event as SelectionTool's own (alt moves the camera, a left press starts a
  // rectangle, its release ends it), kept here because the base class keeps its flag private.
  if (event.alt())
    selecting_ = false;
  else if (event.leftDown())
    selecting_ = true;
  const bool finished = selecting_ && event.leftUp();
  const int flags = rviz::SelectionTool::processMouseEvent(event);  // performs the selection on release
  if (finished)
  {
    selecting_ = false;
    frames_left_ = kMaxFramesToWait;
    context_->queueRender();
  }
  return flags;
}

void SelectedPointsTool::update(float wall_dt, float ros_dt)
{
  rviz::SelectionTool::update(wall_dt, ros_dt);
  if (frames_left_ == 0)
    return;
  std::vector<Ogre::Vector3> points;
  if (collectSelection(points))
  {
    frames_left_ = 0;
    publish(points);
  }
  else if (--frames_left_ == 0)
  {
    ROS_WARN("Publish Selection: the selection was not rendered within %d frames; publishing the %zu point(s) "
             "known", kMaxFramesToWait, points.size());
    publish(points);
  }
  else
  {
    context_->queueRender();
  }
}

bool SelectedPointsTool::collectSelection(std::vector<Ogre::Vector3>& points) const
{
  rviz::SelectionManager* selection_manager = context_->getSelectionManager();
  bool complete = true;
  for (const auto& entry : selection_manager->getSelection())
  {
    // Only point clouds: a marker or a pose in the rectangle is not a point of the scene. A cloud's
    // handler gives one box per selected point, centred on it in the fixed frame (rviz's world).
    auto* cloud_handler = dynamic_cast<rviz::PointCloudSelectionHandler*>(selection_manager->getHandler(entry.first));
    if (!cloud_handler)
      continue;
    rviz::V_AABB boxes;
    cloud_handler->getAABBs(entry.second, boxes);
    for (const Ogre::AxisAlignedBox& box : boxes)
    {
      if (box.isFinite())
        points.push_back(box.getCenter());
      else
        complete = false;  // still Ogre's null box: not drawn yet
    }
  }
  return complete;
}

void SelectedPointsTool::publish(const std::vector<Ogre::Vector3>& points)
{
  sensor_msgs::PointCloud2 cloud;
  cloud.header.frame_id = context_->getFixedFrame().toStdString();
  cloud.header.stamp = ros::Time::now();
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  modifier.setPointCloud2FieldsByString(1, "xyz");
  modifier.resize(points.size());
  cloud.is_dense = true;
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
  for (const Ogre::Vector3& p : points)
  {
    *x = p.x;
    *y = p.y;
    *z = p.z;
    ++x, ++y, ++z;
  }
  publisher_.publish(cloud);
  ROS_INFO("Publish Selection: %zu point(s) in frame '%s' on %s", points.size(), cloud.header.frame_id.c_str(),
           publisher_.getTopic().c_str());
}

}  // namespace example_pcl

PLUGINLIB_EXPORT_CLASS(example_pcl::SelectedPointsTool, rviz::Tool)
