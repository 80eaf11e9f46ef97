"""Shared fixtures: an isolated ROS graph per test, and in-process rclpy contexts on its domain."""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

import pytest

from grader.runner import RosGraph

REPO = Path(__file__).resolve().parent.parent

pytest_plugins = ["grader.testing.bags"]


@pytest.fixture
def ros_graph(tmp_path: Path) -> Iterator[RosGraph]:
    """A RosGraph (own ROS_DOMAIN_ID, localhost discovery) whose processes die with the test."""
    with RosGraph(tmp_path / "graph") as graph:
        yield graph


