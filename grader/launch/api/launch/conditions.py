"""``launch.conditions`` subset (see grader.launch.entities)."""

from grader.launch.entities import IfCondition, UnlessCondition  # noqa: F401
from grader.launch.entities import unsupported as _unsupported


def __getattr__(name: str):
    raise _unsupported("launch.conditions", name)
