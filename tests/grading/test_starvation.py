"""A recording made while the machine starved the scenario is made again (pure: fake records)."""

from __future__ import annotations

import json
from pathlib import Path

from grader.contracts.scenario_record import ScenarioRecord
from grader.grading import starvation
from grader.grading.starvation import record_unstarved, starved


def R(fields: dict) -> ScenarioRecord:
    """A record of ``fields`` (the pipeline passes records as the model, never as dicts)."""
    return ScenarioRecord.parse({"scenario": "sc", **fields}, "test record")


def rec(share: float | None) -> ScenarioRecord:
    return R({"errors": [], "cpu_wait": {} if share is None else {"turtlesim": {"wait_share": share},
                                                                   "controller": {"wait_share": 3.0}}})


def test_the_simulator_is_the_probe() -> None:
    assert starved(rec(0.2)) is None                       # a student's node spinning a core is its own business
    assert "1.02 s per second" in starved(rec(1.02))
    assert starved(rec(None)) is None                      # no probe in the record: nothing to judge by
    # no simulator (a replay into a subscriber): the grader's scenario process is the probe
    assert "scenario process waited 1.70 s" in starved(R({"cpu_wait": {"scenario": {"wait_share": 1.7},
                                                                         "subscriber": {"wait_share": 0.1}}}))
    assert starved(R({"cpu_wait": {"scenario": {"wait_share": 1.2}}})) is None
    assert starved(R({"cpu_wait": {"turtlesim": {"wait_share": 0.2}, "scenario": {"wait_share": 0.9}}})) is None


def test_a_timing_verdict_at_k_times_real_time_has_a_k_th_of_the_limits() -> None:
    """A stall of the same wall length is K times as long in simulated time at K x: the first_nodes
    greeting_timer fixture (correct) at 4x, its simulator waiting 0.43 s per second, sent two
    commands 1.16 s of simulated time apart and failed turtlesim's 1 s command timeout. The
    recording itself is kept (a pass on it stands); a timing item's lost points are judged
    against a K-th of the limits."""
    def at_scale(record: ScenarioRecord) -> starvation.Starvation | None:
        return starvation.starvation(record, scale=starvation.recorded_scale(record))

    at_4x = rec(0.434).amended({"time_scale": {"used": 4.0, "requested": 4.0}})
    assert starved(at_4x) is None and at_scale(rec(0.434)) is None      # the recording; a 1x one
    assert "waited 0.43 s per second for a CPU (at most 0.125 at 4x: 0.5 at 1x)" in at_scale(at_4x).reason
    assert at_scale(rec(0.1).amended({"time_scale": {"used": 4.0}})) is None
    assert at_scale(rec(0.434).amended({"time_scale": {"used": 1.0, "requested": 4.0, "fallback": "x"}})) is None
    quota = R({"cpu_wait": {"turtlesim": {"wait_share": 0.05}}, "time_scale": {"used": 4.0},
               "cpu_quota": {"cpus": 2.0, "throttled_s": 3.0, "wall_s": 30.0}})     # 0.1 s per s
    assert "(at most 0.0625 at 4x: 0.25 at 1x)" in at_scale(quota).reason
    assert starved(quota) is None
    own = at_4x.amended({"cpu_wait": {"turtlesim": {"wait_share": 0.434}, "node": {"cpu_s": 9.0, "alive_s": 10.0}}})
    assert at_scale(own).own                                            # its own loop: as measured


def test_a_starved_recording_is_made_again_until_one_is_not(tmp_path: Path) -> None:
    shares = iter([1.1, 0.9, 0.15])
    folder = tmp_path / "sc"
    made: list[float] = []

    def once() -> ScenarioRecord:
        folder.mkdir(parents=True, exist_ok=True)
        share = next(shares)
        made.append(share)
        rec(share).write(folder / "scenario.json")
        return rec(share)

    record = record_unstarved(once, folder, pause=lambda s: None)
    assert made == [1.1, 0.9, 0.15] and record.errors == []
    assert record.starved is not None
    assert record.starved["starved"] == 2 and record.starved["kept"] == "not starved"
    assert json.loads((folder / "scenario.json").read_text())["starved"]["recordings"] == 3


def test_starved_every_time_keeps_the_last_and_says_so(tmp_path: Path) -> None:
    record = record_unstarved(lambda: rec(2.0), tmp_path / "sc", pause=lambda s: None)
    assert record.starved is not None
    assert record.starved["starved"] == 1 + starvation.RETRIES and record.starved["kept"] == "starved"
    assert "the grading machine was too busy" in record.errors[0] and not record.starved["own"]
    assert "is not charged for them" in record.errors[0]


def busy(share: float, student_cpu_s: float, alive_s: float = 10.0) -> ScenarioRecord:
    return R({"errors": [], "cpu_wait": {"turtlesim": {"wait_share": share},
                                         "server": {"cpu_s": student_cpu_s, "alive_s": alive_s}}})


def test_a_loop_that_never_sleeps_starves_its_own_recording() -> None:
    # the student's server took 0.95 CPU s per s: the starved simulator is its own doing
    own = starvation.starvation(busy(1.4, 9.5))
    assert own is not None and own.own and "own processes used 0.95 CPU s per second" in own.reason
    # the Lab 3 reference's nodes take a few hundredths of a CPU: the machine starved it
    machine = starvation.starvation(busy(1.4, 0.5))
    assert machine is not None and not machine.own
    assert starvation.starvation(busy(0.2, 9.5)) is None       # a busy student on a quiet machine: not starved
    # a student held at its sandbox's CPU quota is its own doing too
    held = busy(1.4, 0.1).amended({"sandbox": {"counters": {"cpu_throttled_s": 4.2}}})
    assert starvation.starvation(held).own


def test_own_starvation_is_not_recorded_again(tmp_path: Path) -> None:
    made: list[int] = []

    def once() -> ScenarioRecord:
        made.append(1)
        return busy(1.6, 9.8)

    record = record_unstarved(once, tmp_path / "sc", pause=lambda s: None)
    assert record.starved is not None and len(made) == 1 and record.starved["own"]
    assert "own processes kept the CPUs busy" in record.errors[0]


def test_a_cpu_quota_that_held_the_grader_back_starves_the_recording() -> None:
    quota = {"cpu_wait": {"turtlesim": {"wait_share": 0.1}},
             "cpu_quota": {"cpus": 0.5, "throttled_s": 12.0, "wall_s": 30.0}}
    found = starvation.starvation(R(quota))
    assert found is not None and not found.own and "CPU quota (0.5 CPU)" in found.reason
    assert starvation.starvation(R({**quota, "cpu_quota": {"cpus": 0.5, "throttled_s": 3.0, "wall_s": 30.0}})) is None
    # under 0.5 CPU the student's share is of the half CPU: 0.45 CPU s per s is the whole quota
    own = {**quota, "cpu_wait": {"turtlesim": {"wait_share": 1.0}, "server": {"cpu_s": 4.5, "alive_s": 10.0}}}
    assert starvation.starvation(R(own)).own


def test_an_exact_lockstep_run_is_a_measurement_however_slow_the_machine() -> None:
    starved_machine = {"cpu_wait": {"turtlesim": {"wait_share": 1.3}},
                       "cpu_quota": {"cpus": 0.5, "throttled_s": 100.0, "wall_s": 120.0}}
    exact = {**starved_machine, "lockstep": {"used": True, "quiet_timeouts": 0}}
    assert starvation.starvation(R(exact)) is None
    # a tick that went on without quiet, or a run that fell back to the wall clock, is not exact
    assert starvation.starvation(R({**starved_machine, "lockstep": {"used": True, "quiet_timeouts": 2}})) is not None
    assert starvation.starvation(R({**starved_machine, "lockstep": {"used": False, "fallback": "x"}})) is not None


def test_a_run_on_simulated_time_the_machine_starves_goes_again_at_1x(tmp_path: Path, monkeypatch) -> None:
    """At 4x every process wakes four times as often per wall second, so a loaded machine starves
    it sooner (make test: Lab 3's no_wrap controller scenario, starved at 4x in its recording and
    its re-run, had an ``error`` item). Such a run is recorded at 1x, and the record says why; a
    run the student's own loop starved, or one not starved, stays at 4x."""
    from grader.grading import timescale
    from grader.grading.timescale import run_at_scale, too_busy_for
    from grader.scenario import resolve
    from grader.scenario.model import Scenario

    assert too_busy_for(rec(0.2), 4.0) is None
    assert too_busy_for(busy(1.4, 9.5), 4.0) is None                 # the student's own busy loop
    assert too_busy_for(rec(0.54), 4.0).startswith("the grading machine was too busy for 4x (the simulator waited")
    scales: list[float] = []

    def fake_run(run, folder):                   # the 4x recording starved, the 1x one not
        scales.append(run.time_scale)
        folder.mkdir(parents=True, exist_ok=True)
        record = rec(0.9 if run.time_scale > 1 else 0.1)
        if run.time_scale > 1:
            record = record.amended({"time_scale": {"used": run.time_scale}})
        record.write(folder / "scenario.json")
        return record

    monkeypatch.setattr(timescale, "run_scenario", fake_run)      # where the batch calls it
    run = resolve("sc", Scenario.model_validate({"steps": [{"id": "s", "wait": 1.0}]}), None)
    record = run_at_scale(run, tmp_path / "sc", 4.0, None)
    assert scales == [4.0, 1.0]
    ts = json.loads((tmp_path / "sc" / "scenario.json").read_text())["time_scale"]
    assert ts["used"] == 1.0 and ts["requested"] == 4.0 and "too busy for 4x" in ts["fallback"], ts
    assert record.time_scale is not None and record.time_scale.to_json() == ts


def test_after_one_run_too_busy_for_4x_the_retries_run_at_1x(tmp_path: Path, monkeypatch) -> None:
    """The starvation retries of a scenario the machine was too busy to run at 4x go at 1x at
    once (not 4x, starved, then 1x, every attempt), and every record says why it is at 1x."""
    from grader.grading import timescale
    from grader.grading.timescale import ScaledRecording
    from grader.scenario import resolve
    from grader.scenario.model import Scenario

    scales: list[float] = []

    def fake_run(run, folder):                   # everything starved: the machine is saturated
        scales.append(run.time_scale)
        folder.mkdir(parents=True, exist_ok=True)
        record = rec(0.9)
        if run.time_scale > 1:
            record = record.amended({"time_scale": {"used": run.time_scale}})
        record.write(folder / "scenario.json")
        return record

    monkeypatch.setattr(timescale, "run_scenario", fake_run)      # where the batch calls it
    folder = tmp_path / "sc"
    run = resolve("sc", Scenario.model_validate({"steps": [{"id": "s", "wait": 1.0}]}), None)
    record = record_unstarved(ScaledRecording(run, folder, 4.0, None), folder, pause=lambda s: None)
    assert scales == [4.0, 1.0, 1.0, 1.0], scales
    assert record.starved is not None and record.starved["starved"] == 1 + starvation.RETRIES
    saved = json.loads((folder / "scenario.json").read_text())["time_scale"]
    assert saved["used"] == 1.0 and "too busy for 4x" in saved["fallback"], saved
