"""A recording made while the machine starved the scenario is made again (pure: fake records)."""

from __future__ import annotations

import json
from pathlib import Path

from grader.grading import starvation
from grader.grading.starvation import record_unstarved, starved


def rec(share: float | None) -> dict:
    return {"errors": [], "cpu_wait": {} if share is None else {"turtlesim": {"wait_share": share},
                                                                 "controller": {"wait_share": 3.0}}}


def test_the_simulator_is_the_probe() -> None:
    assert starved(rec(0.2)) is None                       # a student's node spinning a core is its own business
    assert "1.02 s per second" in starved(rec(1.02))
    assert starved(rec(None)) is None                      # no probe in the record: nothing to judge by
    # no simulator (a replay into a subscriber): the grader's scenario process is the probe
    assert "scenario process waited 1.70 s" in starved({"cpu_wait": {"scenario": {"wait_share": 1.7},
                                                                       "subscriber": {"wait_share": 0.1}}})
    assert starved({"cpu_wait": {"scenario": {"wait_share": 1.2}}}) is None
    assert starved({"cpu_wait": {"turtlesim": {"wait_share": 0.2}, "scenario": {"wait_share": 0.9}}}) is None


def test_a_starved_recording_is_made_again_until_one_is_not(tmp_path: Path) -> None:
    shares = iter([1.1, 0.9, 0.15])
    folder = tmp_path / "sc"
    made: list[float] = []

    def once() -> dict:
        folder.mkdir(parents=True, exist_ok=True)
        share = next(shares)
        made.append(share)
        (folder / "scenario.json").write_text(json.dumps(rec(share)))
        return rec(share)

    record = record_unstarved(once, folder, pause=lambda s: None)
    assert made == [1.1, 0.9, 0.15] and record["errors"] == []
    assert record["starved"]["starved"] == 2 and record["starved"]["kept"] == "not starved"
    assert json.loads((folder / "scenario.json").read_text())["starved"]["recordings"] == 3


def test_starved_every_time_keeps_the_last_and_says_so(tmp_path: Path) -> None:
    record = record_unstarved(lambda: rec(2.0), tmp_path / "sc", pause=lambda s: None)
    assert record["starved"]["starved"] == 1 + starvation.RETRIES and record["starved"]["kept"] == "starved"
    assert "grade this submission again when the machine is quiet" in record["errors"][0]
    # a server whose loop never sleeps starves the simulator itself: the problem says so too
    assert "or this submission's own processes kept the CPUs busy" in record["errors"][0]
