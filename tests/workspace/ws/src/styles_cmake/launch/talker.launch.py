"""Not installed by CMakeLists.txt: `ros2 launch styles_cmake talker.launch.py` would not find it."""
from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description():
    return LaunchDescription([Node(package="styles_cmake", executable="cmake_talker")])
