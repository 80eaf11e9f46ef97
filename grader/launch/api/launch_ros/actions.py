"""``launch_ros.actions`` subset: ``Node`` (see grader.launch.entities)."""

from grader.launch.entities import Node  # noqa: F401
from grader.launch.entities import missing as _missing


def __getattr__(name: str):
    raise _missing("launch_ros.actions", name)
