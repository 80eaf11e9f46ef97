"""Includes params_remap.launch.py with an argument, and starts a second talker 1 s later."""
import os

from launch import LaunchDescription
from launch.actions import IncludeLaunchDescription, TimerAction
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch_ros.actions import Node


def generate_launch_description():
    here = os.path.dirname(__file__)
    return LaunchDescription([
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(here, "params_remap.launch.py")),
            launch_arguments={"greeting": "included"}.items(),
        ),
        TimerAction(period=1.0, actions=[
            Node(package="launch_demo", executable="talker", name="late",
                 parameters=[{"greeting": "later", "repeat": 7}]),
        ]),
    ])
