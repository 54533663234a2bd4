// example_pcl/PublishSelectedPoints: rviz's Select tool that also publishes what it selected.
//
// The seed's operator drags a rectangle over the scene in rviz and find_can receives the points on
// `selected_points`. Stock rviz only highlights a selection, so this tool extends rviz::SelectionTool:
// selecting (drag; shift adds, ctrl removes) works exactly as in Select, and every finished selection
// goes out as one sensor_msgs/PointCloud2 (x, y, z float32, metres) in rviz's fixed frame.
#pragma once

#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <rviz/default_plugin/tools/selection_tool.h>

#include <OgreVector3.h>
#include <vector>

namespace rviz
{
class StringProperty;
}

namespace example_pcl
{
class SelectedPointsTool : public rviz::SelectionTool
{
  Q_OBJECT
public:
  SelectedPointsTool();

  void onInitialize() override;
  int processMouseEvent(rviz::ViewportMouseEvent& event) override;
  void update(float wall_dt, float ros_dt) override;

private Q_SLOTS:
  void updateTopic();

private:
  // The points of every point-cloud display in the current selection, in the fixed frame; false while
  // some are not known yet (not rendered since they were selected).
  bool collectSelection(std::vector<Ogre::Vector3>& points) const;
  void publish(const std::vector<Ogre::Vector3>& points);

  ros::NodeHandle nh_;
  ros::Publisher publisher_;
  rviz::StringProperty* topic_property_;
  bool selecting_ = false;
  // Frames left to wait for a finished selection to be rendered: Ogre derives the highlight boxes'
  // world bounds (which getAABBs returns) when it draws them, so the points are read after that.
  int frames_left_ = 0;
};

}  // namespace example_pcl
