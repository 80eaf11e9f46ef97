"""Scenarios on simulated time (--time-scale): faster, identical motion, and back to 1x when a
node is paced by the wall clock (static scan before the run, watchdog during it).

The live tests run real scenario children (simulator or grader_clock, recorder, driver) and, for
the fallbacks, a real colcon build of ``ws_pacing``: one package whose nodes publish /ticks at
2 Hz from a ROS timer or from the timeout of ``spin_once``, one that paces with ``time.sleep``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from grader.grading.timescale import pacing_reason, run_at_scale, scan_source
from grader.scenario import resolve, run_scenario
from grader.scenario.model import Scenario
from grader.scenario.runspec import RateExpectation
from grader.scenario.watchdog import RateWatchdog, off_rate, rate

HERE = Path(__file__).resolve().parent
TICKS = RateExpectation(topic="/ticks", expected_hz=2.0, rel_tol=0.3)


# -- the static scan -------------------------------------------------------------------------------

@pytest.mark.parametrize("source,found", [
    ("import time\ntime.sleep(0.5)\n", [(2, "time.sleep()")]),
    ("import time as t\nx = t.monotonic()\n", [(2, "time.monotonic()")]),
    ("from time import sleep as nap, perf_counter\nnap(1)\nperf_counter()\n",
     [(2, "time.sleep()"), (3, "time.perf_counter()")]),
    ("from datetime import datetime\nstart = datetime.now()\n", [(2, "datetime.datetime.now()")]),
    ("import datetime\nd = datetime.datetime.utcnow()\n", [(2, "datetime.datetime.utcnow()")]),
    ("import threading\nthreading.Timer(1.0, print).start()\n", [(2, "threading.Timer()")]),
    ("from rclpy.clock import Clock, ClockType\nc = Clock(clock_type=ClockType.STEADY_TIME)\n",
     [(2, "ClockType.STEADY_TIME")]),
    # an executor that cannot keep pace with /clock (ros2/rclpy issue 1452), however imported
    ("from rclpy.executors import MultiThreadedExecutor\nex = MultiThreadedExecutor(num_threads=4)\n",
     [(2, "rclpy.executors.MultiThreadedExecutor()")]),
    ("import rclpy.executors\nex = rclpy.executors.MultiThreadedExecutor()\n",
     [(2, "rclpy.executors.MultiThreadedExecutor()")]),
    ("from rclpy.executors import SingleThreadedExecutor\nex = SingleThreadedExecutor()\n", []),
    # ROS time and unrelated names are fine
    ("def sleep():\n    pass\nsleep()\nself.get_clock().now()\nrate = node.create_rate(30)\n", []),
    ("import time\nprint(time.strftime('%H'))\n", []),
    ("this is not python (", []),
])
def test_scan_finds_wall_clock_pacing(source: str, found: list) -> None:
    assert scan_source(source) == found


def test_pacing_reason_names_the_file_and_why(tmp_path: Path, monkeypatch) -> None:
    """The reason says where and why: wall-clock pacing and a MultiThreadedExecutor are separate
    reasons, each with its first file:line. The executor is a reason only on an rclpy whose
    MultiThreadedExecutor busy-loops (ros2/rclpy#1452): the grader's own environment, which
    ``make bootstrap`` fixed, runs it faster than real time."""
    from types import SimpleNamespace

    from grader.grading import timescale

    from grader.rosenv import PY_SITE

    src = tmp_path / "src" / "server_pkg"
    src.mkdir(parents=True)
    (src / "package.xml").write_text("<package><name>server_pkg</name></package>")
    site = tmp_path / "install" / "server_pkg" / PY_SITE / "server_pkg"
    site.mkdir(parents=True)
    (site / "server.py").write_text("from rclpy.executors import MultiThreadedExecutor\n\n"
                                    "def main():\n    MultiThreadedExecutor().spin()\n")
    build = SimpleNamespace(root=str(tmp_path), install=str(tmp_path / "install"),
                            packages={"server_pkg": SimpleNamespace(status="built")})
    run = SimpleNamespace(scenario=Scenario.model_validate(
        {"processes": [{"name": "server", "package": "server_pkg", "executable": "server"}],
         "steps": [{"id": "s", "wait": 1.0}]}))
    timescale.executor_busy_loops.cache_clear()
    assert not timescale.executor_busy_loops(), "this environment's rclpy still busy-loops: make bootstrap fixes it"
    assert pacing_reason(build, run) is None
    monkeypatch.setattr(timescale, "executor_busy_loops", lambda: True)     # an unfixed rclpy 7.1.6
    reason = pacing_reason(build, run)
    assert reason.startswith("server_pkg/server.py:4: rclpy.executors.MultiThreadedExecutor(): ")
    assert "whole CPU core" in reason and "wall-clock" not in reason
    assert pacing_reason(build, run, lockstep=True) is None     # in lockstep it rests between ticks
    (site / "server.py").write_text((site / "server.py").read_text() + "import time\ntime.sleep(1)\n")
    reason = pacing_reason(build, run)
    assert reason.startswith("wall-clock pacing in node code (server_pkg/server.py:6: time.sleep())")
    assert "; server_pkg/server.py:4: rclpy.executors.MultiThreadedExecutor(): " in reason
    # a node installed as a script (CMake install(PROGRAMS)), not as a module, is scanned too
    (site / "server.py").write_text("def main():\n    pass\n")
    script = tmp_path / "install" / "server_pkg" / "lib" / "server_pkg" / "paced_node"
    script.parent.mkdir(parents=True)
    script.write_text("#!/usr/bin/env python3\nimport time\n\ntime.sleep(0.1)\n")
    script.chmod(0o755)
    reason = pacing_reason(build, run)
    assert reason.startswith("wall-clock pacing in node code (lib/server_pkg/paced_node:4: time.sleep())"), reason


# -- the watchdog's rule ----------------------------------------------------------------------------

def test_watchdog_rule_on_sim_wall_and_woken_nodes() -> None:
    ticks = [2.0 + 0.5 * i for i in range(12)]
    walls = [100 + t / 4 for t in ticks]
    assert rate(ticks, 2.5) == pytest.approx(2.0)
    assert off_rate(TICKS, ticks, walls) is None                      # ROS timer: 2 Hz simulated
    slow = [2.0 + 2.0 * i for i in range(4)]                          # time.sleep at 4x
    assert "0.5 Hz of simulated time (2 Hz of wall time)" in off_rate(TICKS, slow, [100 + t / 4 for t in slow])
    fast = [2.0 + 0.016 * i for i in range(200)]                     # woken by every /clock
    assert "62.5 Hz of simulated time" in off_rate(TICKS, fast, [100 + t / 4 for t in fast])
    paused = ticks + [20.0 + 0.5 * i for i in range(10)]             # a pause between bursts
    assert off_rate(TICKS, paused, paused) is None
    assert rate([1.0, 9.0], 2.5) == 0.0 and off_rate(TICKS, [1.0, 9.0], [1.0, 3.0]) is not None


class _Graph:
    """Stands in for the driver's node: who publishes /clock."""

    def __init__(self, *publishers: str) -> None:
        self.publishers = publishers

    def get_publishers_info_by_topic(self, topic: str) -> list:
        class Info:
            def __init__(self, name: str) -> None:
                self.node_name = name
        return [Info(n) for n in self.publishers]


def test_watchdog_flags_a_quiet_advertised_topic_and_a_foreign_clock() -> None:
    dog = RateWatchdog((TICKS,), clock_owner="turtlesim")
    assert dog.verdict(_Graph("turtlesim"), 5.0, lambda t: True) is None     # first seen now
    assert dog.verdict(_Graph("turtlesim"), 6.0, lambda t: True) is None     # 2 periods: not yet
    assert "only 0 message(s) arrived in 3 s" in dog.verdict(_Graph("turtlesim"), 8.0, lambda t: True)
    quiet = RateWatchdog((TICKS,), clock_owner="turtlesim")
    assert quiet.verdict(_Graph("turtlesim"), 30.0, lambda t: False) is None  # nobody advertises it
    assert "student_clock published /clock" in dog.verdict(_Graph("turtlesim", "student_clock"), 9.0)


def test_busy_process_tree_is_flagged_an_idle_one_is_not(tmp_path: Path) -> None:
    """CPU of a process tree (a sandbox wrapper and the node inside count as one), real processes;
    a busy loop sharing its CPU with another (as on a loaded machine: half a core) is flagged by
    the time it waits to run, an idle process is not, however loaded."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from grader.scenario.watchdog import BUSY_WINDOW_S

    loop = tmp_path / "loop.py"               # ends by itself (SIGALRM) whatever happens to the test
    loop.write_text("import signal\nsignal.alarm(20)\nwhile True:\n    pass\n")
    wrapper = tmp_path / "wrapper.py"         # the busy loop is a grandchild, as a node in a sandbox
    wrapper.write_text(f"import subprocess, sys\nsubprocess.run([sys.executable, {str(loop)!r}])\n")
    cpu = min(os.sched_getaffinity(0))
    pinned = {"preexec_fn": lambda: os.sched_setaffinity(0, {cpu})}
    busy = subprocess.Popen([sys.executable, str(wrapper)], start_new_session=True)
    shared = subprocess.Popen([sys.executable, str(wrapper)], start_new_session=True, **pinned)
    burner = subprocess.Popen([sys.executable, str(loop)], **pinned)
    idle = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(20)"], **pinned)
    try:
        dog = RateWatchdog((), clock_owner="turtlesim")
        time.sleep(0.5)
        procs = {"idle": idle.pid, "busy": busy.pid, "shared": shared.pid}
        for name, pid in procs.items():
            assert dog.busy({name: pid}) is None                   # baselines
        time.sleep(BUSY_WINDOW_S + 0.5)
        assert dog.busy({"idle": idle.pid}) is None
        reason = dog.busy({"busy": busy.pid})
        # a whole core on a free machine; on a busy one (a test session beside it) the share it
        # gets may fall under BUSY_SHARE, and its thread runnable all the time says it instead
        assert reason and reason.startswith(("busy used", "a thread of busy was running")), reason
        assert "cannot keep pace" in reason
        # at most ~half a core beside the burner, but runnable all the time
        reason = dog.busy({"shared": shared.pid})
        assert reason and reason.startswith("a thread of shared was running or waiting for a CPU"), reason
    finally:
        for p in (busy, shared):
            os.killpg(p.pid, signal.SIGKILL)                          # the group: the loop too
        for p in (burner, idle):
            p.kill()
        for p in (busy, shared, burner, idle):
            p.wait()


# -- live scenarios --------------------------------------------------------------------------------

DRIVE = {"steps": [
    {"id": "go", "publish": {"topic": "/turtle1/cmd_vel", "type": "geometry_msgs/msg/Twist",
                             "msg": {"linear": {"x": 2.0}, "angular": {"z": 1.8}}},
     "until": {"condition": "messages", "topic": "/turtle1/cmd_vel", "count": 1}, "timeout": 5},
    {"id": "coast", "wait": 6},
    {"id": "pen", "service": {"name": "/turtle1/set_pen", "request": {"r": 255, "g": 0, "b": 0, "width": 5,
                                                                      "off": 0}},
     "until": "service_done", "timeout": 10},
], "limits": {"wall_s": 60}}


@pytest.mark.ros
@pytest.mark.timeout(180)
def test_drive_scenario_at_4x_records_clock_and_the_1x_motion(tmp_path: Path) -> None:
    from grader.bag.frames import load_bag_meta, load_frames
    from grader.bag.timebase import TIME_SCALE_KEY
    from grader.bag.reader import open_bag

    run = resolve("drive", Scenario.model_validate(DRIVE), None).model_copy(update={"time_scale": 4.0})
    record = run_scenario(run, tmp_path / "drive").to_json()
    assert record["errors"] == [], record
    assert record["time_scale"]["used"] == 4.0 and "fallback" not in record["time_scale"]
    # step limits are simulated seconds: the 6 s coast lasts 6 s of simulated time
    assert [s["ended_by"] for s in record["steps"]] == ["condition", "done", "condition"]
    assert record["steps"][1]["duration_s"] == pytest.approx(6.0, abs=0.05)
    bag = tmp_path / "drive" / "bag"
    assert open_bag(bag).metadata.custom_data[TIME_SCALE_KEY] == "4.0"
    assert load_bag_meta(bag).counts["/clock"] > 400
    frames = load_frames(bag)                   # in simulated seconds
    pose = frames["/turtle1/pose"]
    moving = pose[pose["linear_velocity"] > 0]
    assert len(moving) == 63                    # the spec's vector, exactly (1x: 62..64)
    assert (moving["x"].iloc[-1], moving["y"].iloc[-1]) == pytest.approx((6.6028166, 6.9389896), abs=1e-6)
    # 62.5 poses per simulated second, as at 1x
    span = pose.index[-1] - pose.index[0]
    assert len(pose) / span == pytest.approx(62.5, rel=0.03)
    # ~4x faster: simulated time against the wall clock the simulator sent it at
    raw = load_frames(bag, time_scale=1.0)["/clock"]
    sim = raw["clock.sec"].to_numpy() + raw["clock.nanosec"].to_numpy() * 1e-9
    wall = raw["pub_t"].to_numpy()
    speed = (sim[-1] - sim[0]) / (wall[-1] - wall[0])
    assert speed > 2.5, f"simulated time ran {speed:.2f}x the wall clock"
    events = [json.loads(d) for d in frames["/grader/events"]["data"]]
    # the last event: the turtles held still at the scenario's end, before the shutdown
    assert events[0]["event"] == "scenario_start" and [e["event"] for e in events[-2:]] == ["scenario_end", "turtles_held"]


def ticks_scenario(package: str, executable: str) -> Scenario:
    return Scenario.model_validate({
        "sim": False,
        "processes": [{"name": "talker", "package": package, "executable": executable}],
        "steps": [{"id": "up", "until": {"condition": "advertised", "topic": "/ticks"}, "timeout": 10},
                  {"id": "run", "wait": 6}],
        "limits": {"wall_s": 60}})




@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(400)
def test_ros_timer_node_runs_at_4x_and_keeps_its_rate(pacing_build, tmp_path: Path) -> None:
    from grader.grading.analysis import scenario_frames

    run = resolve("ticks", ticks_scenario("pacers", "timer_node"), pacing_build)
    assert pacing_reason(pacing_build, run) is None
    record = run_at_scale(run, tmp_path / "ticks", 4.0, pacing_build, (TICKS,)).to_json()
    assert record["errors"] == []
    assert record["time_scale"] == {**record["time_scale"], "requested": 4.0, "used": 4.0}
    assert "fallback" not in record["time_scale"]
    saved = json.loads((tmp_path / "ticks" / "scenario.json").read_text())
    assert saved["time_scale"]["used"] == 4.0         # a regrade reads the bag in simulated time
    ticks = scenario_frames(tmp_path / "ticks")["/ticks"]
    assert len(ticks) >= 11                           # 6 s of simulated time at 2 Hz
    assert np.median(np.diff(ticks.index.to_numpy())) == pytest.approx(0.5, abs=0.02)


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(400)
def test_sleep_paced_node_is_found_by_the_scan_and_runs_at_1x(pacing_build, tmp_path: Path) -> None:
    run = resolve("ticks", ticks_scenario("sleepers", "sleep_node"), pacing_build)
    reason = pacing_reason(pacing_build, run)
    assert reason and "sleepers/sleep_node.py:" in reason and "time.sleep()" in reason
    record = run_at_scale(run, tmp_path / "ticks", 4.0, pacing_build, (TICKS,)).to_json()
    assert record["errors"] == []
    ts = record["time_scale"]
    assert ts["requested"] == 4.0 and ts["used"] == 1.0 and ts["fallback"] == reason
    assert "attempt_wall_s" not in ts                 # never tried faster
    saved = json.loads((tmp_path / "ticks" / "scenario.json").read_text())
    assert saved["time_scale"]["used"] == 1.0
    assert not (tmp_path / "ticks" / "bag" / "metadata.yaml").read_text().count("time_scale")


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(400)
def test_wall_paced_node_the_scan_misses_is_caught_at_run_time(pacing_build, tmp_path: Path) -> None:
    """spin_once(timeout_sec=0.5) paces by the wall clock (and wakes on every /clock): the scan
    cannot see it, the watchdog does, and the scenario is recorded again at 1x."""
    from grader.grading.analysis import scenario_frames

    run = resolve("ticks", ticks_scenario("pacers", "spin_node"), pacing_build)
    assert pacing_reason(pacing_build, run) is None
    record = run_at_scale(run, tmp_path / "ticks", 4.0, pacing_build, (TICKS,)).to_json()
    assert record["errors"] == []
    ts = record["time_scale"]
    assert ts["used"] == 1.0 and "/ticks was published at" in ts["fallback"], ts
    assert ts["attempt_wall_s"] > 0
    ticks = scenario_frames(tmp_path / "ticks")["/ticks"]       # the 1x recording: 2 Hz
    assert np.median(np.diff(ticks.index.to_numpy())) == pytest.approx(0.5, abs=0.05)


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.timeout(400)
def test_a_node_using_the_clock_service_sends_the_run_back_to_1x(pacing_build, tmp_path: Path) -> None:
    """The clock owner counts the hold requests it serves; any beyond the driver's own means a
    student node reached for simulated time itself."""
    run = resolve("ticks", ticks_scenario("pacers", "meddler"), pacing_build)
    record = run_at_scale(run, tmp_path / "ticks", 4.0, pacing_build, (TICKS,)).to_json()
    assert record["errors"] == []
    ts = record["time_scale"]
    assert ts["used"] == 1.0 and "held or stopped the simulated clock" in ts["fallback"], ts


def test_at_1x_a_step_limit_does_not_pay_for_a_process_start_up() -> None:
    """At 1x the clock runs on, but scenario time (what step limits count) leaves out the time
    held while a student process starts: at load 29 the Lab 3 client needed 9.5 s to come up
    and its 10 s step timed out before its first stdin line (ex3.client_rejected "not checked"
    in one run of three). Nested holds count once; sleep_until waits on scenario time."""
    import time

    from grader.scenario.simtime import ScenarioClock

    clock = ScenarioClock(1.0)
    t0, w0 = clock.now(), time.monotonic()
    with clock.held():
        with clock.held():
            time.sleep(0.3)
        assert clock.now() - t0 < 0.05              # standing still while held
    held_wall = time.monotonic() - w0               # the hold, and the moment before it
    time.sleep(0.1)
    # bounds from the wall time measured around the sleeps, so a loaded machine cannot fail it:
    # nested holds count once (counted twice, held_s would be about twice held_wall)
    assert 0.3 <= clock.held_s <= held_wall
    ran = clock.now() - t0
    assert 0.1 <= ran and abs(ran - (time.monotonic() - w0 - clock.held_s)) < 0.05
    start = time.monotonic()
    target = clock.now() + 0.2
    clock.sleep_until(target)
    assert time.monotonic() - start >= 0.18 and clock.now() >= target
