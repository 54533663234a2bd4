"""example_pcl: find a can on a table in a Kinect point cloud (ROS 1, Python over PCL/Eigen)."""
