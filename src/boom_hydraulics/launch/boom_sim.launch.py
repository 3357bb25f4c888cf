"""Launch the boom_sim node with a parameter file (machines with a full ROS 2 install).

ros2 launch boom_hydraulics boom_sim.launch.py
ros2 launch boom_hydraulics boom_sim.launch.py params_file:=/path/to/paper_fig8.yaml
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    default_params = os.path.join(get_package_share_directory("boom_hydraulics"), "config", "default.yaml")
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "params_file", default_value=default_params, description="ROS 2 params YAML for boom_sim"
            ),
            Node(
                package="boom_hydraulics",
                executable="boom_sim",
                name="boom_sim",
                output="screen",
                parameters=[LaunchConfiguration("params_file")],
            ),
        ]
    )
