"""``launch.substitutions`` subset (see grader.launch.entities)."""

from grader.launch.entities import (EnvironmentVariable, LaunchConfiguration,  # noqa: F401
                                    PathJoinSubstitution, TextSubstitution, ThisLaunchFileDir)
from grader.launch.entities import unsupported as _unsupported


def __getattr__(name: str):
    raise _unsupported("launch.substitutions", name)
