"""``launch.conditions`` subset (see grader.launch.entities)."""

from grader.launch.entities import IfCondition, UnlessCondition  # noqa: F401
from grader.launch.entities import missing as _missing


def __getattr__(name: str):
    raise _missing("launch.conditions", name)
