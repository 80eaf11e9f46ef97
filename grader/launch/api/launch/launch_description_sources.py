"""``launch.launch_description_sources`` subset (see grader.launch.entities)."""

from grader.launch.entities import PythonLaunchDescriptionSource  # noqa: F401
from grader.launch.entities import missing as _missing


def __getattr__(name: str):
    raise _missing("launch.launch_description_sources", name)
