"""The ROS 2 layer, the only one importing rclpy: node, parameters, messages, replay, demo."""
