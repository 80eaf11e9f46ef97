"""Starts a C++ node whose package needs rclcpp (not on the grading machine)."""
from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description():
    return LaunchDescription([
        Node(package="styles_py", executable="py_talker"),
        Node(package="styles_rclcpp", executable="rclcpp_node"),
    ])
