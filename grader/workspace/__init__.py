"""Submission workspaces: staging (source.py), colcon builds with a content cache (build.py)."""

from grader.workspace.build import BuildResult, PackageBuild, build_workspace

__all__ = ["BuildResult", "PackageBuild", "build_workspace"]
