"""Launch boom_sim, and robot_state_publisher for TF where it is installed.

ros2 launch boom_hydraulics boom_sim.launch.py
ros2 launch boom_hydraulics boom_sim.launch.py namespace:=crane1 use_sim_time:=true
ros2 launch boom_hydraulics boom_sim.launch.py params_file:=/path/to/my.yaml record:=true rviz:=true

Arguments (``--show-args``): namespace, use_sim_time, params_file, record (default false),
record_folder (default $ROS_HOME/boom_hydraulics/bags), robot_state_publisher (auto, true,
false) and rviz. They are defined in boom_hydraulics.ros.launch_arguments.
"""

import os

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from boom_hydraulics.model import config
from boom_hydraulics.model.robot_description import urdf
from boom_hydraulics.ros.launch_arguments import ARGUMENTS, plan


def _installed(package: str) -> bool:
    try:
        get_package_share_directory(package)
    except PackageNotFoundError:
        return False
    return True


def _start(context, *_args, **_kwargs):
    share = get_package_share_directory("boom_hydraulics")
    values = {a.name: LaunchConfiguration(a.name).perform(context) for a in ARGUMENTS}
    p = plan(
        values,
        os.path.join(share, "config", "default.yaml"),
        state_publisher_installed=_installed("robot_state_publisher"),
        rviz_installed=_installed("rviz2"),
    )
    sim_time = p.sim_parameters["use_sim_time"]
    actions = [
        Node(
            package="boom_hydraulics",
            executable="boom_sim",
            name="boom_sim",
            namespace=p.namespace,
            output="screen",
            parameters=[p.params_file, p.sim_parameters],
        )
    ]
    if p.state_publisher:
        # its ros2_control tag names boom_sim's topics in the namespace (as the node's own description does)
        prefix = f"/{p.namespace}" if p.namespace else ""
        description = urdf(config.load(p.params_file), f"{prefix}/joint_commands", f"{prefix}/joint_states")
        actions.append(
            Node(
                package="robot_state_publisher",
                executable="robot_state_publisher",
                namespace=p.namespace,
                output="screen",
                parameters=[{"robot_description": description, "use_sim_time": sim_time}],
            )
        )
    if p.rviz:
        actions.append(
            Node(
                package="rviz2",
                executable="rviz2",
                namespace=p.namespace,
                arguments=["-d", os.path.join(share, "rviz", "boom_crane.rviz")],
                parameters=[{"use_sim_time": sim_time}],
            )
        )
    return actions


def generate_launch_description() -> LaunchDescription:
    declared = [DeclareLaunchArgument(a.name, default_value=a.default(), description=a.description) for a in ARGUMENTS]
    return LaunchDescription([*declared, OpaqueFunction(function=_start)])
