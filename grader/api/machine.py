"""The machine the grader runs on, as ``grader doctor`` (and Gradescope's image build) report it.

The doctor is a front-end: it prints. What it prints comes from here: which ROS is in use
(:func:`ros_info`), whether rclpy's executor busy-loop fix is in place (:func:`executor_state`),
the CPUs and memory the grader is given (:func:`describe_allotment`), each protection of student
code probed for real (:func:`protections`, :func:`sandbox_mode`, :func:`require_complete`) and the
two self-tests (:func:`live_selftest`, :func:`sandbox_selftest`: processes started for real, in
``grader.scenario.selftest``). Each returns data or raises :class:`grader.errors.GraderError`;
none prints.
"""

from __future__ import annotations

import sys

from grader import rclpy_fix
from grader.rosenv import ros_info
from grader.sandbox import sandbox_mode
from grader.sandbox.allotment import describe as describe_allotment
from grader.sandbox.probe import Protection, protections
from grader.sandbox.scenario import require_complete
from grader.scenario.selftest import live_selftest, sandbox_selftest

__all__ = ["Protection", "describe_allotment", "executor_state", "live_selftest", "protections", "require_complete",
           "ros_info", "sandbox_mode", "sandbox_selftest"]


def executor_state(python: str = sys.executable) -> tuple[str, str]:
    """rclpy's executor in ``python``: ``("fixed" | "busy" | ..., the sentence the doctor prints)``
    (the busy-loop fix of :mod:`grader.rclpy_fix`)."""
    return rclpy_fix.state(python)
