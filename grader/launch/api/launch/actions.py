"""``launch.actions`` subset (see grader.launch.entities)."""

from grader.launch.entities import (DeclareLaunchArgument, ExecuteProcess,  # noqa: F401
                                    IncludeLaunchDescription, LogInfo, SetEnvironmentVariable,
                                    TimerAction)
from grader.launch.entities import missing as _missing


def __getattr__(name: str):
    raise _missing("launch.actions", name)
