"""A node with a namespace, a dict and a YAML parameter file, and a remapping; its greeting is a
launch argument."""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("greeting", default_value="hello"),
        Node(
            package="launch_demo",
            executable="talker",
            name="greeter",
            namespace="lab",
            parameters=[{"greeting": LaunchConfiguration("greeting")},
                        PathJoinSubstitution([FindPackageShare("launch_demo"), "config", "talker.yaml"])],
            remappings=[("chatter", "/announcements")],
            output="screen",
        ),
    ])
