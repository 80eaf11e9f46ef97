"""Hostile student code in a real scenario: each attack is contained and each limit reported.

Every test runs ``run_scenario`` for real (unshare namespaces, cgroups, bubblewrap, the
recorder) with ``hostile.py`` as the student's processes, then checks the files it must not
touch (snapshots), the lines it printed, the scenario record and the bag's events, and that no
process it started is alive afterwards.
"""

from __future__ import annotations

import json
import socket
from pathlib import Path

import pytest

from sandboxhelpers import events, log, processes_with, require_protections, run_hostile, snapshot

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_writes_reads_network_detach_and_flood_are_contained(tmp_path, fake_build, world, token, monkeypatch) -> None:
    require_protections("filesystem", "network", "processes", "unprivileged user", "kill all")
    monkeypatch.setenv("INSTRUCTOR_API_TOKEN", "s3cret")          # the caller's environment
    monkeypatch.setenv("GRADER_SANDBOX_OUTPUT_MB", "1")
    out = tmp_path / "batch" / "me" / "scenarios" / "hostile"
    server = socket.socket()
    server.bind(("127.0.0.1", 0))                                  # a service on the host's loopback
    server.listen()
    before = snapshot(world)
    bag_dir = out / "bag"
    targets = [str(world / "batch" / "classmate" / "result.json"), str(world / "batch" / "grades.csv"),
               str(world / "rubric" / "lab.yaml"), str(world / "batch"), str(out), str(bag_dir),
               str(fake_build / "lib" / "hostile" / "hostile.py")]
    secrets = [str(world / "rubric" / "lab.yaml"), str(world / "fixtures" / "reference" / "expected.yaml"),
               str(world / "cache"), str(REPO / "rubrics"), str(REPO / "grader" / "__init__.py"),
               str(out), str(Path.home() / ".cache"), "/etc/shadow"]
    try:
        record = run_hostile(fake_build, out, {
            "writer": ["hostile.py", "writer", *targets],
            "reader": ["hostile.py", "reader", *secrets],
            "net": ["hostile.py", "net", f"127.0.0.1:{server.getsockname()[1]}", "1.1.1.1:53"],
            "detacher": ["hostile.py", "detach", token],
            "flooder": ["hostile.py", "flood", "8"],
        }, wait_s=5.0)
    finally:
        server.close()

    # nothing outside the scenario's output folder changed, and nothing of the bag was touched
    assert snapshot(world) == before
    written = log(out, "writer")
    assert "WRITE-OK" not in written, written
    assert written.count("WRITE-DENIED") == 3 * len(targets), written
    assert (fake_build / "lib" / "hostile" / "hostile.py").exists()
    assert not list(out.rglob("pwned*")) and not list(world.rglob("*pwned*"))

    read = log(out, "reader")
    assert "READ-OK" not in read, read
    env_keys = json.loads(next(ln for ln in read.splitlines() if ln.startswith("ENV "))[4:])
    assert "INSTRUCTOR_API_TOKEN" not in env_keys and "ROS_DOMAIN_ID" in env_keys
    assert "uid=65534" in read and "cwd=/sandbox" in read
    assert read.count("SCRATCH-OK") == 3, read                     # its own scratch is writable

    reached = log(out, "net")
    assert "NET-OK" not in reached and reached.count("NET-DENIED") == 2, reached

    # the detached daemon lived during the scenario and died with it
    assert "DETACHED" in log(out, "detacher")
    assert processes_with(token) == []
    assert record["sandbox"]["left_running"] == 0

    flood = log(out, "flooder")
    assert len(flood) < 1.1 * 2**20 and "[grader] stdout cut" in flood
    assert "discarded after the 1 MiB limit" in flood
    assert "FLOOD-DONE" in log(out, "flooder", "stderr")         # it was never blocked
    assert any(h["limit"] == "output" and h["process"] == "flooder" for h in record["sandbox"]["limits_hit"])
    assert any("flooder: stdout cut at 1 MiB" in line for line in record["limits_hit"])
    hits = [e for e in events(out) if e["event"] == "limit_hit"]
    assert any(e["limit"] == "output" and e["process"] == "flooder" for e in hits), hits
    on_disk = json.loads((out / "scenario.json").read_text())
    assert on_disk["sandbox"]["missing"] == [] and on_disk["limits_hit"] == record["limits_hit"]


@pytest.mark.slow
def test_memory_hog_and_fork_bomb_hit_the_scenario_limits(tmp_path, fake_build, token, monkeypatch) -> None:
    require_protections("memory limit", "process limit", "kill all")
    monkeypatch.setenv("GRADER_SANDBOX_PIDS", "64")
    out = tmp_path / "out"
    # the hog alone stays under the per-process address-space limit; the scenario's memory does not
    record = run_hostile(fake_build, out, {"hog": ["hostile.py", "hog", "1024"], "bomb": ["hostile.py", "bomb", token]},
                         wait_s=5.0, memory_mb=300)
    limits = {h["limit"]: h for h in record["sandbox"]["limits_hit"]}
    assert "memory" in limits and "300 MiB" in limits["memory"]["detail"], record["sandbox"]
    assert "processes" in limits and "64 processes" in limits["processes"]["detail"], record["sandbox"]
    assert "HOG-DONE" not in log(out, "hog")
    assert record["processes"]["hog"]["exited_early"]                 # killed by the kernel, not by us
    assert "refused=" in log(out, "bomb") and "refused=0" not in log(out, "bomb")
    hits = {e["limit"] for e in events(out) if e["event"] == "limit_hit"}
    assert {"memory", "processes"} <= hits
    assert processes_with(token) == []
    assert record["sandbox"]["counters"]["pids_peak"] <= 64
