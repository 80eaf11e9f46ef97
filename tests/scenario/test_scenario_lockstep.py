"""Lockstep simulated time (``lockstep: true``): the same code draws the same path in every run.

Unit tests for the pieces (quiescence from /proc, the stepwise time map, the model's rules, a
repeated scenario that a lockstep run settles at once); live tests run real scenario children
with a chaotic controller (``ws_pacing``'s ``chaser_node``: no angle wrap, a target circling
the canvas) twice, once with CPU burners beside it, and require the simulator's own records of
the turtle's poses to be byte for byte the same.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest
from pydantic import ValidationError

from grader.bag.timebase import TimeMap
from grader.contracts.scenario_record import ScenarioRecord
from grader.grading.repeat import lockstep_record_exact, repeated_finding, run_until_settled
from grader.scenario.model import Scenario
from grader.scenario.quiescence import Quiescence, descendants

HERE = Path(__file__).resolve().parent


# -- quiescence ------------------------------------------------------------------------------------

def test_a_sleeping_process_is_quiet_and_a_busy_one_is_not() -> None:
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.3)                       # both started (the interpreter's start-up is busy)
        quiet = Quiescence([sleeper.pid])
        assert quiet.wait(timeout_s=2.0) and quiet.timeouts == 0
        noisy = Quiescence([busy.pid])
        t0 = time.monotonic()
        assert not noisy.wait(timeout_s=0.3)
        assert noisy.timeouts == 1 and time.monotonic() - t0 >= 0.3
    finally:
        for p in (sleeper, busy):
            p.kill()
            p.wait()


def test_a_scan_finds_the_thread_awake_first_where_it_was_last() -> None:
    """A scan stops at the first thread awake, the one found the scan before read first: it
    finds the busy loop among sleeping threads wherever it is listed, and none in a quiet tree."""
    from grader.scenario.quiescence import TaskFiles, first_awake, threads

    sleeper = subprocess.Popen([sys.executable, "-c", "import threading, time\n"
                                "for _ in range(8): threading.Thread(target=time.sleep, args=(30,)).start()\n"
                                "time.sleep(30)\n"])
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    files = TaskFiles()
    try:
        deadline = time.monotonic() + 20
        while len(threads([sleeper.pid])) < 9 and time.monotonic() < deadline:
            time.sleep(0.05)                  # its threads started (a loaded machine is slow to)
        time.sleep(0.3)
        asleep = threads([sleeper.pid])
        assert len(asleep) == 9 and first_awake(asleep, files) is None
        assert first_awake(asleep, files, hint=asleep[3]) is None
        both = asleep + threads([busy.pid])
        found = first_awake(both, files, hint=asleep[0])
        assert found is not None and found[0] == busy.pid
        assert first_awake(both, files, hint=found) == found
    finally:
        files.close()
        for p in (sleeper, busy):
            p.kill()
            p.wait()


def test_a_starved_thread_is_waited_for_and_a_busy_one_is_not() -> None:
    """A thread that cannot get a CPU (here: SCHED_IDLE beside a busy thread on the same core) is
    not "busy": the wait goes on past its limit, to ``STARVED_CAP`` times it, while the tree has
    run less than ``CPU_SHARE`` of the limit on a CPU. A busy loop on a core of its own ends the
    wait at the limit."""
    from grader.scenario.quiescence import STARVED_CAP

    pin = "import os\nos.sched_setaffinity(0, {0})\n"
    burner = subprocess.Popen([sys.executable, "-c", pin + "while True: pass\n"])
    starved = subprocess.Popen([sys.executable, "-c", pin + "os.sched_setscheduler(0, os.SCHED_IDLE, "
                                "os.sched_param(0))\nwhile True: pass\n"])
    try:
        time.sleep(0.5)
        waits = Quiescence([starved.pid])
        t0 = time.monotonic()
        assert not waits.wait(timeout_s=0.2)
        took = time.monotonic() - t0
        assert took >= 0.2 * STARVED_CAP * 0.9 and waits.timeouts == 1 and waits.starved_s > 1.0, took
        # on any core, ahead of the machine's other work where it may (root): at load 20 a plain
        # busy loop got so little CPU that the cap ended its wait too
        free = subprocess.Popen([sys.executable, "-c", "import os\ntry:\n    os.nice(-10)\nexcept OSError:\n"
                                 "    pass\nwhile True: pass\n"])
        time.sleep(0.5)
        busy = Quiescence([free.pid])
        t0 = time.monotonic()
        assert not busy.wait(timeout_s=0.2)
        took = time.monotonic() - t0          # its CPU share of the limit, not the cap, ended it
        assert took < 0.2 * STARVED_CAP * 0.8 and busy.starved_s < waits.starved_s, took
        free.kill()
        free.wait()
    finally:
        for p in (burner, starved):
            p.kill()
            p.wait()


def test_a_busy_child_of_a_quiet_process_keeps_the_tree_busy() -> None:
    """A launch file's nodes are children of its process: the tree is waited for, not the root."""
    parent = subprocess.Popen([sys.executable, "-c",
                               "import subprocess, sys, time\n"
                               "subprocess.Popen([sys.executable, '-c', 'while True: pass'])\n"
                               "time.sleep(30)\n"])
    try:
        deadline = time.monotonic() + 20
        while len(descendants([parent.pid])) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)                  # the child started (a loaded machine is slow to)
        time.sleep(0.3)
        assert not Quiescence([parent.pid]).wait(timeout_s=0.3)
    finally:
        subprocess.run(["pkill", "-P", str(parent.pid)], check=False)
        parent.kill()
        parent.wait()


# -- the time map of a lockstep bag ----------------------------------------------------------------

def test_threads_waiting_on_the_lockstep_clock_share_its_ticks() -> None:
    """A step's wait and a stdin line's delay wait on the clock at once: it still advances one
    tick at a time (never two ticks at once, never twice as fast), and each waiter sees every
    tick. Ticking on their own, two waiters spun the stepper's executor from two threads
    ("generator already executing") and ran the clock double speed."""
    import threading

    from grader.scenario.lockstep import Stepper

    stepper = object.__new__(Stepper)          # the tick is the simulator's; here a stand-in
    stepper.now_ns, stepper.ticks = 0, 0
    stepper._ticking, stepper._ticked = threading.Lock(), threading.Condition()
    inside: list[int] = []
    overlaps: list[int] = []

    def tick() -> int:
        inside.append(1)
        if len(inside) > 1:
            overlaps.append(stepper.ticks)
        time.sleep(0.001)
        stepper.now_ns += 16_000_000
        stepper.ticks += 1
        inside.pop()
        return stepper.now_ns

    stepper.tick = tick                        # type: ignore[method-assign]
    seen: dict[str, list[int]] = {"a": [], "b": []}

    def wait(name: str, until_ns: int) -> None:
        while stepper.now_ns < until_ns:
            stepper.advance()
            seen[name].append(stepper.now_ns)

    threads = [threading.Thread(target=wait, args=("a", 100 * 16_000_000)),
               threading.Thread(target=wait, args=("b", 60 * 16_000_000))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert not overlaps
    assert stepper.ticks == 100                # the longer wait's ticks, not the sum of both
    assert seen["b"][-1] >= 60 * 16_000_000 and max(seen["a"]) == 100 * 16_000_000


def _stepper_stand_in(call: Callable[..., str], settle: Callable[[bool], None], cpu: Any) -> Any:
    """A lockstep ``Stepper`` whose simulator answers are ``call`` (the client is ``"clock"`` or
    ``"world"``) and whose quiet waits are ``settle``."""
    import itertools
    import threading

    from grader.scenario.lockstep import Stepper

    stepper = object.__new__(Stepper)
    stepper.now_ns, stepper.ticks, stepper.tick_wall_s, stepper.call_wall_s = 0, 0, 0.0, 0.0
    stepper.tick_cpu_s = stepper.call_cpu_s = 0.0
    stepper._channel = None                    # the DDS path: its calls are ``call``
    stepper._ticking, stepper._ticked = threading.Lock(), threading.Condition()
    stepper._due, stepper._order = [], itertools.count()
    stepper.cpu = cpu
    stepper._clock, stepper._world, stepper._step = "clock", "world", None
    stepper._call, stepper._settle = call, settle
    return stepper


def test_the_step_services_are_probed_until_they_answer_and_nothing_ticks() -> None:
    """Found is not answered: a request or its reply can be lost before discovery has matched
    both ends, and a lost step may have ticked. So the clock is probed (``data: false``, time
    only) and the world asked (once per time) until each answers; a silent one fails in time."""
    from types import SimpleNamespace

    from grader.scenario.lockstep import LockstepError

    lost = {"clock": 3, "world": 1}
    seen: list[tuple[str, object]] = []

    def call(client, request=None, wait_s: float = 0.0) -> str:
        seen.append((client.srv_name, getattr(request, "data", None)))
        if lost[client.srv_name] > 0:
            lost[client.srv_name] -= 1
            raise LockstepError("lost")
        return "0 0"

    stepper = _stepper_stand_in(call, lambda own: None, None)
    stepper._clock, stepper._world = (SimpleNamespace(srv_name=name, wait_for_service=lambda timeout_sec: True)
                                      for name in ("clock", "world"))
    assert stepper.ready(5.0)
    assert seen == [("clock", False)] * 4 + [("world", None)] * 2
    assert stepper.ticks == 0 and stepper.now_ns == 0
    lost["clock"] = 10**6
    start = time.monotonic()
    assert not stepper.ready(0.3) and time.monotonic() - start < 2.0


def test_scheduled_actions_run_at_the_tick_boundary_in_the_ticking_thread() -> None:
    """A scripted stdin line is typed by the thread that ticks, after the first tick that reaches
    its time and before the next one, then the processes are let settle: never from a thread of
    its own some wall time later (where the step's wait ticked on)."""
    import threading
    from collections import Counter

    from grader.scenario.lockstep import CpuBudget

    calls: list[str] = []

    def call(client, request=None) -> str:
        if client == "clock":
            stepper._next = stepper.now_ns + 16_000_000
            calls.append("clock")
            return f"{stepper._next} 0"
        calls.append("world")
        return ""

    def settle(own: bool) -> None:
        if own and calls[-1] != "settled":
            calls.append("settled")

    stepper = _stepper_stand_in(call, settle, CpuBudget(list))
    ran: list[tuple[int, int, int]] = []
    ticker = threading.get_ident()

    def action(name: int) -> None:
        ran.append((name, stepper.now_ns, stepper.ticks))
        calls.append(f"action {name}")
        assert threading.get_ident() == ticker

    stepper.schedule(40_000_000, lambda: action(2))      # due at the third tick (48 ms)
    stepper.schedule(32_000_000, lambda: action(1))      # exactly at the second
    stepper.schedule(48_000_000, lambda: action(3))      # the same tick as 2, after it
    for _ in range(4):
        stepper.tick()
    assert [(n, t) for n, t, _ in ran] == [(1, 32_000_000), (2, 48_000_000), (3, 48_000_000)]
    assert [k for n, _, k in ran] == [1, 2, 2]             # within the tick that reached the time
    i = calls.index("action 2")                             # the world stepped first, settled after
    assert calls[i - 2:i + 3] == ["world", "settled", "action 2", "action 3", "settled"]
    assert Counter(calls)["clock"] == 4 and stepper._due == []


def test_the_cpu_budget_counts_the_waited_processes_cpu_per_simulated_second() -> None:
    """A busy child exceeds the budget, a resting one does not however much wall time passes, and
    a busy child that ended still counts what it used."""
    from grader.scenario.lockstep import MAX_CPU_PER_SIM_S, CpuBudget, LockstepFailed

    burn = "import time\nend = time.process_time() + {s}\nwhile time.process_time() < end: pass\n"
    # the resting child says when its interpreter has started: its start-up CPU (0.03-0.05 s, a
    # sixth of the simulated time below on a busy machine) is not what this test measures
    rest = subprocess.Popen([sys.executable, "-c", "import time; print('up', flush=True); time.sleep(30)"],
                            stdout=subprocess.PIPE, text=True)
    assert rest.stdout is not None and rest.stdout.readline().strip() == "up"
    busy = subprocess.Popen([sys.executable, "-c", burn.format(s=0.8)])
    try:
        resting, flooding = CpuBudget(lambda: [rest.pid]), CpuBudget(lambda: [busy.pid])
        resting.start(0)
        flooding.start(0)
        while busy.poll() is None:             # read while it runs, as the ticks do
            flooding.rate(1)
            time.sleep(0.05)
        # it used 0.8 s of CPU and is gone: what was last seen of it still counts
        sim_ns = int(0.8 / (2 * MAX_CPU_PER_SIM_S) * 1e9)     # 0.8 CPU s in that: twice the budget
        rate = flooding.rate(sim_ns)
        assert rate is not None and rate > MAX_CPU_PER_SIM_S
        with pytest.raises(LockstepFailed, match="CPU seconds per simulated second"):
            flooding.check(sim_ns)
        time.sleep(1.0)                        # wall time passes; the resting child uses no CPU
        resting.check(sim_ns)
        assert (resting.rate(sim_ns) or 0.0) < 0.1 * MAX_CPU_PER_SIM_S
        assert CpuBudget(lambda: [rest.pid]).rate(sim_ns) is None      # not started: no verdict
    finally:
        rest.kill()
        rest.wait()


def test_a_run_is_given_up_only_when_slow_and_busy_by_its_own_nodes() -> None:
    """Slow ticks alone are the machine's load (a correct chaser took 5-8 times its time at load
    14-20) and a busy CPU alone may be an executor that spins on a free machine (chase's correct
    MultiThreadedExecutor, 1.1 CPU s per simulated second in one run, with fast ticks): only both give a
    lockstep run up, as wall_pen's flooding node at load (16-24 times, 2.4-2.8)."""

    from grader.scenario import lockstep

    class Budget(lockstep.CpuBudget):
        def __init__(self, rate: float) -> None:
            super().__init__(list)
            self._rate = rate

        def rate(self, now_ns: int) -> float | None:
            return self._rate

    def run(rate: float, tick_wall_s: float) -> str | None:
        stepper = _stepper_stand_in(lambda client, request=None: f"{stepper.now_ns + lockstep.TICK_NS} 0",
                                    lambda own: None, Budget(rate))
        try:
            for _ in range(2 * lockstep.SLOW_AFTER_TICKS):
                stepper.tick()
                stepper.tick_wall_s = stepper.ticks * tick_wall_s   # as if each tick took that long
        except lockstep.LockstepFailed as exc:
            return str(exc)
        return None

    tick_s = lockstep.TICK_NS / 1e9
    slow, busy = 2 * lockstep.MAX_SLOWDOWN * tick_s, 2 * lockstep.MAX_CPU_PER_SIM_S
    assert run(busy, tick_s) is None                    # busy on a free machine, ticks fast
    assert run(0.3, slow) is None                        # slow ticks, a light graph: the load
    reason = run(busy, slow)
    assert reason is not None and "times their simulated time" in reason and "CPU seconds" in reason
    # slow and busy, but fast enough to end within its waits' own wall limit: an exact run is
    # not given up (wall_pen's flooding node, two gradings side by side: 8.2 times, 3.75 CPU s
    # per simulated second, given up at 8 at its tick 3968 of 4033)
    from grader.scenario.simtime import LOCKSTEP_WALL_FACTOR
    assert run(busy, 0.95 * LOCKSTEP_WALL_FACTOR * tick_s) is None


def test_a_lockstep_bag_maps_each_time_to_the_last_tick_sent() -> None:
    """Interpolated, a pose sent late in a tick (a busy machine) would get a fraction of a tick;
    stepwise it gets the tick's time, whenever within the tick it was sent."""
    wall = np.array([100.0, 100.5, 100.6])
    sim = np.array([0.016, 0.032, 0.048])
    step = TimeMap(wall, sim, 1.0, stepwise=True)
    assert list(step([100.0, 100.1, 100.49, 100.5, 100.59, 100.7])) == pytest.approx(
        [0.016, 0.016, 0.016, 0.032, 0.032, 0.048])
    assert step([99.9])[0] == pytest.approx(0.016 - 0.1)     # before the first tick: wall seconds
    assert TimeMap(wall, sim, 1.0)([100.25])[0] == pytest.approx(0.024)   # interpolated otherwise


# -- the rubric's word -----------------------------------------------------------------------------

@pytest.mark.parametrize("extra,message", [
    ({"sim": False}, "lockstep needs the simulator"),
    ({"real_time": True}, "lockstep and real_time exclude each other"),
])
def test_lockstep_needs_the_simulator_and_simulated_time(extra: dict, message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        Scenario.model_validate({"lockstep": True, "steps": [{"id": "s", "wait": 1.0}], **extra})


def test_an_exact_lockstep_run_settles_a_repeated_scenario_at_once(tmp_path: Path) -> None:
    exact, loose, cut, fell_back = (ScenarioRecord.parse({"scenario": "s", "lockstep": ls, "errors": []}, "record") for ls in (
        {"used": True, "ticks": 10, "quiet_timeouts": 0}, {"used": True, "ticks": 10, "quiet_timeouts": 2},
        {"used": True, "ticks": 10, "quiet_timeouts": 0, "wall_cuts": 1}, {"used": False, "fallback": "wall-clock pacing"}))
    assert lockstep_record_exact(exact)
    assert not any(lockstep_record_exact(r) for r in (loose, cut, fell_back))
    for record, runs in ((exact, 1), (loose, 3), (cut, 3), (fell_back, 3)):
        made: list[int] = []
        run_until_settled(lambda k, _folder, r=record, m=made: m.append(k) or r, tmp_path, "drive", 3,
                          settles=lambda folders: False)
        assert len(made) == runs, record


class _SlowStepper:
    """A lockstep clock whose ticks take 20 ms of wall time each (a very busy machine)."""

    def __init__(self) -> None:
        self.now_ns = 0
        self.wall_cuts = 0

    def settle(self) -> None:
        pass

    def advance(self) -> None:
        time.sleep(0.02)
        self.now_ns += 16_000_000


def test_a_lockstep_wait_cut_short_by_the_wall_is_counted(monkeypatch: pytest.MonkeyPatch) -> None:
    """A wait that ends by its wall-time limit before its simulated time lasted as long as the
    machine's load allowed: the run is not exact, and its record and report say so."""
    from grader.grading.timescale import describe_lockstep
    from grader.scenario import simtime

    monkeypatch.setattr(simtime, "LOCKSTEP_WALL_FACTOR", 0.0)
    monkeypatch.setattr(simtime, "LOCKSTEP_WALL_EXTRA_S", 0.5)
    stepper = _SlowStepper()
    clock = simtime.ScenarioClock(stepper=stepper)
    assert clock.wait_until(lambda: False, 0.016) is False and stepper.wall_cuts == 0   # 1 tick: in time
    assert clock.wait_until(lambda: False, 10.0) is False and stepper.wall_cuts == 1
    assert stepper.now_ns < 16_000_000 + 10 * 10**9
    line = describe_lockstep("ex3_action", {"used": True, "ticks": 9, "quiet_timeouts": 0, "wall_cuts": 1})
    assert "1 wait(s) ended by their wall-time limit" in line and "may differ" in line


def test_an_item_of_a_lockstep_run_says_so() -> None:
    from grader.analyze import Finding

    one = Finding(value=1.0, fraction=1.0, status="pass", feedback="", evidence={})
    assert repeated_finding([one], 3, lockstep=True).decided == {"by": "one lockstep run", "runs": 1, "stable": True}
    assert repeated_finding([one], 1).decided == {"by": "one run", "runs": 1}


# -- live: the same path in every run ---------------------------------------------------------------

def chase_scenario() -> Scenario:
    return Scenario.model_validate({
        "lockstep": True,
        # two lines typed into its stdin (it does not read them): typed at a tick boundary by
        # the thread that ticks, at the same simulated times in every run
        "processes": [{"name": "chaser", "package": "pacers", "executable": "chaser_node",
                       "stdin": [{"line": "one", "delay": 1.0}, {"line": "two", "delay": 0.48}]}],
        # a teleport half-way: the wait for its answer must not tick a different number of
        # times from run to run (it settles first: Stepper.settle)
        "steps": [{"id": "up", "until": {"condition": "subscribed", "topic": "/turtle1/pose"}, "timeout": 10},
                  {"id": "run", "wait": 4},
                  {"id": "jump", "service": {"name": "/turtle1/teleport_absolute",
                                             "type": "turtlesim/srv/TeleportAbsolute",
                                             "request": {"x": 3.0, "y": 3.0, "theta": 0.0}}, "timeout": 2},
                  {"id": "more", "wait": 4}],
        "limits": {"wall_s": 60}})


def _poses(folder: Path) -> tuple[bytes, int]:
    """The simulator's record of /turtle1/pose in the bag: all its CDR bytes, and how many."""
    from grader.bag.reader import open_bag
    from grader.sim.record import record_topic

    topic = record_topic("/turtle1/pose")
    data = [bytes(payload) for _t, *_times, payload in open_bag(folder / "bag", [topic]).iter_messages([topic])]
    return b"".join(data), len(data)


def _events(folder: Path, *names: str) -> list[tuple[float, dict]]:
    """The driver's events of these kinds, at their simulated times in the bag."""
    from grader.grading.analysis import scenario_frames

    events = scenario_frames(folder)["/grader/events"]
    out = []
    for t, data in zip(events.index, events["data"]):
        event = json.loads(data)
        if event["event"] in names:
            out.append((round(float(t), 6), event))
    return out


def _typed(folder: Path) -> list[tuple[float, str]]:
    """The stdin lines the driver typed, at their simulated times in the bag."""
    return [(t, event["line"]) for t, event in _events(folder, "stdin_line")]


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_chaotic_controller_draws_the_same_path_in_lockstep_however_busy(pacing_build, tmp_path: Path) -> None:
    from grader.grading.analysis import scenario_frames
    from grader.grading.timescale import run_at_scale
    from grader.scenario import resolve

    run = resolve("chase", chase_scenario(), pacing_build)
    quiet = run_at_scale(run, tmp_path / "quiet", 1.0, pacing_build).to_json()
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(3)]
    try:
        busy = run_at_scale(run, tmp_path / "busy", 1.0, pacing_build).to_json()
    finally:
        for b in burners:
            b.kill()
            b.wait()
    for record in (quiet, busy):
        assert record["errors"] == [] and record["lockstep"]["used"] is True, record.get("lockstep")
        assert record["lockstep"]["quiet_timeouts"] == 0 and record["lockstep"]["sim_s"] >= 8.0
        # waited for: this scenario process, the simulator, the chaser (and its sandbox's wrapper)
        assert record["lockstep"]["processes"] >= 3, record["lockstep"]
    first, n = _poses(tmp_path / "quiet")
    assert n >= 8 * 62 and _poses(tmp_path / "busy") == (first, n)
    typed = _typed(tmp_path / "quiet")
    assert [line for _t, line in typed] == ["one", "two"] and _typed(tmp_path / "busy") == typed
    assert 0.48 - 0.016 < typed[1][0] - typed[0][0] < 0.48 + 0.016
    # the teleport is answered at the tick it was called: its client was made before the
    # scenario started (steps.prepare); made at the call, the simulator's answer waited for
    # discovery, asleep, while the clock ticked (0 or 4 ticks from run to run in a Lab 3 class)
    for folder in ("quiet", "busy"):
        call, response = _events(tmp_path / folder, "service_call", "service_response")
        assert call[0] == response[0], (folder, call, response)
    # the bag reads in simulated time: a pose every tick, on the tick
    pose = scenario_frames(tmp_path / "quiet")["/turtle1/pose"]
    assert np.allclose(np.diff(pose.index.to_numpy()), 0.016, atol=1e-6)
    saved = json.loads((tmp_path / "quiet" / "scenario.json").read_text())
    assert saved["lockstep"]["ticks"] == quiet["lockstep"]["ticks"]
    # a recording never finalised (the recorder killed before it wrote metadata.yaml) has no
    # metadata to say it was lockstep: the record says so, and the times read the same
    (tmp_path / "quiet" / "bag" / "metadata.yaml").unlink()
    crashed = scenario_frames(tmp_path / "quiet")["/turtle1/pose"]
    assert np.allclose(crashed.index.to_numpy()[:len(pose)], pose.index.to_numpy()[:len(crashed)])


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(400)
def test_a_wall_paced_node_runs_on_the_wall_clock_and_says_why(pacing_build, tmp_path: Path) -> None:
    from grader.grading.timescale import describe_lockstep, run_at_scale
    from grader.scenario import resolve

    scenario = chase_scenario().model_copy(update={"processes": (
        chase_scenario().processes[0].model_copy(update={"package": "sleepers", "executable": "sleep_node"}),)})
    record = run_at_scale(resolve("chase", scenario, pacing_build), tmp_path / "wall", 1.0, pacing_build).to_json()
    ls = record["lockstep"]
    assert ls["used"] is False and "time.sleep()" in ls["fallback"] and "attempt" not in ls
    assert describe_lockstep("chase", ls).startswith("scenario chase ran on the wall clock instead of lockstep")
    saved = json.loads((tmp_path / "wall" / "scenario.json").read_text())
    assert saved["lockstep"]["used"] is False


def test_the_report_says_how_a_lockstep_scenario_ran() -> None:
    from grader.grading.outputs import time_scale_notes

    notes = time_scale_notes({
        "drive": {"clock": "lockstep", "used": True, "ticks": 4033, "quiet_timeouts": 0},
        "north": {"clock": "lockstep", "used": True, "ticks": 1300, "quiet_timeouts": 2},
        "other": {"clock": "lockstep", "used": False, "fallback": "wall-clock pacing in node code (x.py:3: time.sleep())"}})
    assert notes == [
        "scenario drive ran on lockstep simulated time (4033 ticks; every tick quiet: the same code repeats it "
        "exactly, unless a node sends before DDS has matched its peer)",
        "scenario north ran on lockstep simulated time (1300 ticks; 2 tick(s) went on before every process "
        "was quiet, so another run may differ)",
        "scenario other ran on the wall clock instead of lockstep simulated time: wall-clock pacing in node "
        "code (x.py:3: time.sleep())"]
