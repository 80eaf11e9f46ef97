"""The grader's stand-in for ROS 2's ``launch`` package (see grader.launch.entities)."""

from grader.launch.entities import LaunchDescription  # noqa: F401
from grader.launch.entities import missing as _missing

from . import actions, conditions, launch_description_sources, substitutions  # noqa: F401


def __getattr__(name: str):
    raise _missing("launch", name)
