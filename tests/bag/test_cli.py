"""``grader bag info|repair|verify`` and the registration of ``record``/``replay`` (no ROS needed)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest

from grader.bag.msgdefs import DefinitionSource
from grader.bag.writer import BagWriter
from grader.cli import main

from baghelpers import crash

POSE = "turtlesim/msg/Pose"
T0 = 1_700_000_000_000_000_000


def synth(path: Path, hz: float, n: int, abandon: bool = False) -> Path:
    src = DefinitionSource()
    w = BagWriter(path, chunk_size=1024)
    w.add_topic("/turtle1/pose", POSE, src.full_text(POSE), type_hash=src.type_hash(POSE))
    w.add_topic("/spawn/_service_event", "turtlesim/srv/Spawn_Event",
                src.full_text("turtlesim/srv/Spawn_Event"))
    for i in range(n):
        w.write("/turtle1/pose", T0 + int(i * 1e9 / hz), b"\x00\x01\x00\x00" + struct.pack("<5f", *[i] * 5))
    if abandon:
        crash(w)
    else:
        w.close()
    return path


def test_info_json_reports_rates_counts_and_services(tmp_path: Path, capsys) -> None:
    bag = synth(tmp_path / "b", 62.5, 626)
    assert main(["bag", "info", str(bag), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["message_count"] == 626 and info["finalized"] and info["ros_distro"] == "jazzy"
    assert info["duration_s"] == pytest.approx(10.0, abs=1e-6)
    (pose,) = info["topics"]
    assert pose["name"] == "/turtle1/pose" and pose["type"] == POSE and pose["count"] == 626
    assert pose["rate_hz"] == pytest.approx(62.5, abs=1e-6)
    assert pose["period_median_s"] == pytest.approx(0.016, abs=1e-6)
    assert pose["rate_median_hz"] == pytest.approx(62.5, abs=1e-3)
    (srv,) = info["services"]
    assert srv["service"] == "/spawn" and srv["count"] == 0
    assert main(["bag", "info", str(bag)]) == 0
    text = capsys.readouterr().out
    assert "Messages:          626" in text and "Rate: 62.50 Hz (median period 16.00 ms)" in text
    assert "Service: /spawn" in text and "Type: turtlesim/srv/Spawn |" in text


def test_info_and_repair_of_a_crashed_bag(tmp_path: Path, capsys) -> None:
    bag = synth(tmp_path / "c", 100, 400, abandon=True)
    assert main(["bag", "info", str(bag)]) == 0
    text = capsys.readouterr().out
    assert "NOT FINALIZED" in text and "grader bag repair" in text
    assert main(["bag", "repair", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "recovered" in out and (bag / "metadata.yaml").is_file()
    assert main(["bag", "info", str(bag), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["finalized"] and 300 <= info["message_count"] < 400


def test_user_errors_exit_2_without_traceback(tmp_path: Path, capsys) -> None:
    assert main(["bag", "info", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("grader: error: bag") and "Traceback" not in err
    assert main(["bag", "repair", str(tmp_path)]) == 2
    assert "no .mcap file" in capsys.readouterr().err
    bag = synth(tmp_path / "b", 10, 5)
    assert main(["replay", str(bag), "--topics", "/nope"]) == 2
    assert "has no topic /nope" in capsys.readouterr().err
    assert main(["replay", str(bag), "--remap", "/a/b"]) == 2
    assert "OLD:=NEW" in capsys.readouterr().err


def test_subcommands_are_registered(capsys) -> None:
    for argv in (["record", "--help"], ["replay", "--help"], ["bag", "info", "--help"],
                 ["bag", "repair", "--help"], ["bag", "verify", "--help"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 0
    out = capsys.readouterr().out
    for flag in ("--regex", "--all", "--rate", "--remap", "--loop", "--start-offset", "--clock",
                 "--json", "--no-backup"):
        assert flag in out


def test_replay_says_where_else_a_bag_opens(tmp_path: Path, capsys) -> None:
    """Nothing after the start offset: nothing published, but it says how to look at the bag
    (Foxglove, the report's player, ros2 bag play)."""
    bag = synth(tmp_path / "b", 10, 5)
    assert main(["replay", str(bag), "--start-offset", "3600"]) == 0
    err = capsys.readouterr().err
    assert "Foxglove" in err and f"ros2 bag play {bag}" in err and "report.html#replay=" in err
    assert "nothing to publish" in err
