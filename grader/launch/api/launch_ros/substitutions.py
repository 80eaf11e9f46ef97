"""``launch_ros.substitutions`` subset: ``FindPackageShare`` (see grader.launch.entities)."""

from grader.launch.entities import FindPackageShare  # noqa: F401
from grader.launch.entities import missing as _missing


def __getattr__(name: str):
    raise _missing("launch_ros.substitutions", name)
