"""Starts one node of each package style."""
from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description():
    return LaunchDescription([
        Node(package="styles_py", executable="py_talker"),
        Node(package="styles_cmake", executable="cmake_talker"),
        Node(package="styles_mixed", executable="mixed_node"),
        Node(package="styles_cpp", executable="cpp_hello", arguments=["from-launch"]),
    ])
