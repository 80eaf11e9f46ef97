"""``launch_ros.actions`` subset: ``Node`` (see grader.launch.entities)."""

from grader.launch.entities import Node  # noqa: F401
from grader.launch.entities import unsupported as _unsupported


def __getattr__(name: str):
    raise _unsupported("launch_ros.actions", name)
