"""The grader's stand-in for ROS 2's ``launch_ros`` package (see grader.launch.entities)."""

from grader.launch.entities import missing as _missing

from . import actions, parameter_descriptions, substitutions  # noqa: F401


def __getattr__(name: str):
    raise _missing("launch_ros", name)
