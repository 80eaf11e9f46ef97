"""Submission workspaces: staging (source.py), colcon builds with a content cache (build.py),
the per-package build cache (package_cache.py), executables found and started as ``ros2 run``
does (executables.py), running a rubric's ``module:`` entry point (launch.py).

Imports are lazy: a ``module:`` process starts through ``grader.workspace.launch``, and
importing the build machinery there cost each of them ~65 ms of CPU for nothing (measured:
93 ms for ``import grader.workspace.launch`` against 28 ms for a bare interpreter).
"""

from __future__ import annotations

from typing import Any

__all__ = ["BuildResult", "PackageBuild", "build_workspace"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from grader.workspace import build  # noqa: PLC0415 - at the head it would close a circle: workspace -> workspace.build -> workspace
        return getattr(build, name)
    raise AttributeError(name)
