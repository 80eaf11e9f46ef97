"""``launch_ros.substitutions`` subset: ``FindPackageShare`` (see grader.launch.entities)."""

from grader.launch.entities import FindPackageShare  # noqa: F401
from grader.launch.entities import unsupported as _unsupported


def __getattr__(name: str):
    raise _unsupported("launch_ros.substitutions", name)
