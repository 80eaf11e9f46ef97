"""Fixtures of the bag tests: graphs and the student-style interface package."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

TCI_SRC = Path(__file__).resolve().parent / "data" / "turtle_control_interfaces"


@pytest.fixture
def graph(ros_graph: Any) -> Any:
    """The isolated RosGraph of tests/conftest.py (short name used throughout these tests)."""
    return ros_graph


@pytest.fixture(scope="session")
def tci_prefix() -> Path:
    """The student-style interface package built (once, cached by content) into a prefix."""
    from grader.testing.bags import build_interface_package

    return build_interface_package(TCI_SRC)
