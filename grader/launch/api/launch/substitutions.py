"""``launch.substitutions`` subset (see grader.launch.entities)."""

from grader.launch.entities import (EnvironmentVariable, LaunchConfiguration,  # noqa: F401
                                    PathJoinSubstitution, TextSubstitution, ThisLaunchFileDir)
from grader.launch.entities import missing as _missing


def __getattr__(name: str):
    raise _missing("launch.substitutions", name)
