"""The chapter's pattern: turtlesim started by the launch file, under a name of its own."""
from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description():
    return LaunchDescription([
        Node(package="turtlesim", executable="turtlesim_node", name="sim"),
        Node(package="launch_demo", executable="talker", name="greeter"),
    ])
