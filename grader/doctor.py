"""`grader doctor`: is this machine ready to grade? Prints facts and one pass/fail per check."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

from grader import __version__
from grader.api.machine import (describe_allotment, executor_state, live_selftest, protections, require_complete,
                                ros_info, sandbox_mode, sandbox_selftest)
from grader.errors import GraderError

INTERFACE_PACKAGES = ("turtlesim", "std_msgs", "geometry_msgs", "std_srvs", "action_msgs",
                      "rcl_interfaces", "service_msgs")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("doctor", help="check the ROS 2 environment (exit 0 when ready)")
    p.add_argument("--timeout", type=float, default=20.0, help="self-test time limit in seconds")
    p.set_defaults(func=run)


def _interface_location(pkg: str) -> str | None:
    try:
        mod = importlib.import_module(f"{pkg}.msg") if pkg not in ("std_srvs",) else importlib.import_module(f"{pkg}.srv")
    except ImportError:
        return None
    return str(Path(mod.__file__).resolve().parent.parent)  # type: ignore[arg-type]  # (a package has a file)


def run(args: argparse.Namespace) -> int:
    ok = True
    info = ros_info()
    print(f"grader {__version__}")
    print(f"python   {info['python']} ({sys.executable})")
    mode = {"wheels": "PyPI wheels in this venv", "system": "system install (sourced)",
            "missing": "NOT FOUND"}[info["mode"]]
    print(f"ROS 2    {info['distro']} from {mode}; rclpy {info['rclpy']}; RMW {info['rmw']}")
    executor, sentence = executor_state()
    print(f"{'WARN' if executor == 'busy' else 'executor'} {sentence}")
    print(f"machine  {describe_allotment()}")
    discovery = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE",
                               "SUBNET (default; runs use LOCALHOST, or SUBNET in a scenario's own network namespace)")
    print(f"network  discovery range {discovery}")
    if info["mode"] == "missing":
        print("FAIL rclpy is not importable: run `grader setup` (`make bootstrap` in a checkout), "
              "or source ROS 2 Jazzy.")
        return 1
    print("interfaces:")
    for pkg in INTERFACE_PACKAGES:
        where = _interface_location(pkg)
        ok &= where is not None
        print(f"  {'ok  ' if where else 'FAIL'} {pkg:15} {where or 'not importable (run grader setup / make bootstrap)'}")
    passed, detail = live_selftest(args.timeout)
    ok &= passed
    print(f"{'PASS' if passed else 'FAIL'} live pub/sub self-test between two processes: {detail}")
    ok &= _sandbox_report(args.timeout)
    print("doctor: everything works" if ok else "doctor: problems found (see FAIL lines)")
    return 0 if ok else 1


def _sandbox_report(timeout: float) -> bool:
    """The protections of student code (each probed for real), then a sandboxed node in a real
    scenario. Missing protections are warnings (the grader falls back), not failures, unless
    GRADER_SANDBOX=require."""
    mode = sandbox_mode()
    print(f"sandbox for student code (GRADER_SANDBOX={mode}):")
    for row in protections(enabled=mode != "off"):
        print(f"  {row.line()}")
    try:
        require_complete()
    except GraderError as exc:
        print(f"FAIL {exc}")
        return False
    passed, detail = sandbox_selftest(timeout)
    print(f"{'PASS' if passed else 'FAIL'} sandboxed student node in a scenario: {detail}")
    return passed
