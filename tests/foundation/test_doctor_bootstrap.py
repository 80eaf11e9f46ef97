"""`grader doctor` passes here, and a second bootstrap does no work."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from grader.cli import main as grader_main

REPO = Path(__file__).resolve().parents[2]


def test_doctor_passes(capsys) -> None:
    assert grader_main(["doctor"]) == 0
    out = capsys.readouterr().out
    assert "PASS live pub/sub self-test" in out and "ok   turtlesim" in out
    assert "rclpy 7." in out or "rclpy" in out


def test_second_bootstrap_rebuilds_nothing() -> None:
    proc = subprocess.run([sys.executable, "-m", "grader.bootstrap"], cwd=REPO,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "building interface package" not in proc.stdout
    assert "installing Python packages" not in proc.stdout
    assert "ready" in proc.stdout


def test_turtlesim_interfaces_match_jazzy() -> None:
    from turtlesim.action import RotateAbsolute
    from turtlesim.msg import Color, Pose
    from turtlesim.srv import Kill, SetPen, Spawn, TeleportAbsolute, TeleportRelative

    assert list(Pose.get_fields_and_field_types()) == ["x", "y", "theta", "linear_velocity", "angular_velocity"]
    assert Color.get_fields_and_field_types() == {"r": "uint8", "g": "uint8", "b": "uint8"}
    assert Spawn.Request.get_fields_and_field_types() == {"x": "float", "y": "float", "theta": "float", "name": "string"}
    assert Spawn.Response.get_fields_and_field_types() == {"name": "string"}
    assert Kill.Request.get_fields_and_field_types() == {"name": "string"}
    assert list(SetPen.Request.get_fields_and_field_types()) == ["r", "g", "b", "width", "off"]
    assert list(TeleportAbsolute.Request.get_fields_and_field_types()) == ["x", "y", "theta"]
    assert list(TeleportRelative.Request.get_fields_and_field_types()) == ["linear", "angular"]
    assert RotateAbsolute.Goal.get_fields_and_field_types() == {"theta": "float"}
    assert RotateAbsolute.Result.get_fields_and_field_types() == {"delta": "float"}
    assert RotateAbsolute.Feedback.get_fields_and_field_types() == {"remaining": "float"}
