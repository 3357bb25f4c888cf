"""rosbag2/MCAP bags without ROS: the recorder, readers, recovery of a killed recording."""
