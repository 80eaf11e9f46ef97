from launch import LaunchDescription
from launch.actions import GroupAction
from launch_ros.actions import Node


def generate_launch_description():
    return LaunchDescription([
        GroupAction([Node(package="launch_demo", executable="talker")]),
    ])
