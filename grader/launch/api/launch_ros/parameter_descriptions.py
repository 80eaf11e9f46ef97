"""``launch_ros.parameter_descriptions`` subset: ``ParameterValue`` (see grader.launch.entities)."""

from grader.launch.entities import ParameterValue  # noqa: F401
from grader.launch.entities import missing as _missing


def __getattr__(name: str):
    raise _missing("launch_ros.parameter_descriptions", name)
