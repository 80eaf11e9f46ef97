"""``launch.launch_description_sources`` subset (see grader.launch.entities)."""

from grader.launch.entities import PythonLaunchDescriptionSource  # noqa: F401
from grader.launch.entities import unsupported as _unsupported


def __getattr__(name: str):
    raise _unsupported("launch.launch_description_sources", name)
