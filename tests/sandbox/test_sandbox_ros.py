"""A sandboxed rclpy node in a real scenario: it and the (unsandboxed) simulator, recorder and
driver share the scenario's loopback, its messages are recorded, and Ctrl-C reaches it."""

from __future__ import annotations

import json

import pytest

from sandboxhelpers import events, log, require_protections, run_hostile


@pytest.mark.slow
@pytest.mark.ros
def test_sandboxed_publisher_is_recorded_and_stops_cleanly(tmp_path, fake_build) -> None:
    require_protections("filesystem", "network", "graceful stop")
    out = tmp_path / "out"
    record = run_hostile(fake_build, out, {"talker": ["talker.py"]}, wait_s=4.0, sim=True)
    assert record["errors"] == [], record["errors"]
    from grader.bag.frames import load_frames

    frames = load_frames(out / "bag")
    chatter = frames["/student_chatter"]
    assert len(chatter) >= 20, len(chatter)                      # 20 Hz for ~4 s, from inside the sandbox
    assert len(frames["/turtle1/pose"]) > 100
    started = next(e for e in events(out) if e["event"] == "node_started")
    first = chatter.index[0] - started["wall"]
    assert first < 5.0, f"first sandboxed message {first:.2f} s after start"
    graph = [e for e in events(out) if e["event"] == "graph"][-1]
    assert any("sandboxed_talker" in n for n in graph["publishers"].get("/student_chatter", []))
    out_log = log(out, "talker")
    assert "first pose after" in out_log                            # the simulator reached it too
    assert "clean shutdown" in out_log, out_log + log(out, "talker", "stderr")
    proc = record["processes"]["talker"]
    assert proc["returncode"] == 0 and not proc["killed"], proc
    assert "SHM" not in log(out, "talker", "stderr")                # no shared-memory errors in its log
    assert json.loads((out / "scenario.json").read_text())["sandbox"]["missing"] == []
