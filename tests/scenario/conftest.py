"""Fixtures of the scenario tests."""

from __future__ import annotations

from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def pacing_build(tmp_path_factory):
    """A real colcon build of ``ws_pacing``: nodes paced by ROS timers, by the wall clock, and
    a chaotic controller (the time-scale and lockstep tests)."""
    from grader.workspace import build_workspace

    build = build_workspace(HERE / "ws_pacing", cache_dir=tmp_path_factory.mktemp("cache"))
    assert build.ok, build.failed
    return build
