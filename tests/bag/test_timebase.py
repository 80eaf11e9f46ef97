"""Bags of faster-than-real-time runs read in simulated seconds, through their recorded /clock.

Real bags written with the grader's writer (wall-clock log and publish times, as the recorder
writes them), real analyzers on them; no ROS.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from grader import analyze
from grader.analyze._common import rosout_lines, stdout_lines
from grader.bag.frames import load_frames
from grader.bag.msgdefs import DefinitionSource
from grader.bag.timebase import TIME_SCALE_KEY, TIMEBASE, TimeMap, time_map
from grader.bag.writer import BagWriter
from grader.errors import GraderError

W0 = 1_700_000_000.0          # wall clock (epoch s) when the simulated clock started
K = 4.0
TICK = 0.016
SRC = DefinitionSource()


@pytest.fixture(scope="module")
def ts():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def sim_to_wall(sim: float) -> float:
    return W0 + sim / K


def write_sim_bag(path: Path, ts, *, scale: float | None = K, clock: bool = True, seconds: float = 6.0) -> Path:
    """A bag as a 4x run records it: /clock every tick, a 30 Hz ROS-timer publisher (fires on
    the first tick at or after each 1/30 s of simulated time), a log line each simulated second
    on /rosout and in ROS console format on /grader/stdout, all stamped with the wall clock."""
    Clock, Time = ts.types["rosgraph_msgs/msg/Clock"], ts.types["builtin_interfaces/msg/Time"]
    Twist, Vector3 = ts.types["geometry_msgs/msg/Twist"], ts.types["geometry_msgs/msg/Vector3"]
    Log, String = ts.types["rcl_interfaces/msg/Log"], ts.types["std_msgs/msg/String"]
    ns = lambda t: int(round(t * 1e9))  # noqa: E731
    custom = {TIME_SCALE_KEY: repr(scale)} if scale else None
    with BagWriter(path, custom_data=custom) as w:
        for name, typ in (("/clock", "rosgraph_msgs/msg/Clock"), ("/turtle1/cmd_vel", "geometry_msgs/msg/Twist"),
                          ("/rosout", "rcl_interfaces/msg/Log"), ("/grader/stdout", "std_msgs/msg/String")):
            w.add_topic(name, typ, SRC.full_text(typ))
        next_cmd, next_log = 1 / 30, 1.0
        for k in range(1, int(seconds / TICK) + 1):
            sim = round(k * TICK, 6)
            wall = sim_to_wall(sim)
            if clock:
                sec, nsec = divmod(ns(sim), 1_000_000_000)
                w.write("/clock", ns(wall) + 300_000, bytes(ts.serialize_cdr(Clock(Time(sec, nsec)),
                                                                             "rosgraph_msgs/msg/Clock")), ns(wall))
            if sim >= next_cmd - 1e-9:      # the node's timer runs right after this /clock
                next_cmd += 1 / 30
                twist = Twist(Vector3(1.0, 0, 0), Vector3(0, 0, 0.5))
                w.write("/turtle1/cmd_vel", ns(wall) + 900_000,
                        bytes(ts.serialize_cdr(twist, "geometry_msgs/msg/Twist")), ns(wall) + 500_000)
            if sim >= next_log - 1e-9:
                next_log += 1.0
                stamp = wall + 0.0002
                sec, nsec = divmod(ns(stamp), 1_000_000_000)
                log = Log(Time(sec, nsec), 20, "simple_subscriber", f"value {sim:.3f}", "n.py", "cb", 1)
                w.write("/rosout", ns(wall) + 2_000_000, bytes(ts.serialize_cdr(log, "rcl_interfaces/msg/Log")),
                        ns(stamp))
                line = json.dumps({"process": "sub", "stream": "stderr",
                                   "line": f"[INFO] [{stamp:.9f}] [simple_subscriber]: value {sim:.3f}"})
                w.write("/grader/stdout", ns(wall) + 40_000_000,
                        bytes(ts.serialize_cdr(String(line), "std_msgs/msg/String")), ns(wall) + 40_000_000)
    return path


def test_time_map_interpolates_between_ticks_and_extrapolates_at_the_scale() -> None:
    tm = TimeMap(np.array([10.0, 10.004, 10.008, 10.012]), np.array([1.0, 1.016, 1.016, 1.032]), K)
    assert tm([10.002])[0] == pytest.approx(1.008)          # half a tick
    assert tm([10.006])[0] == pytest.approx(1.016)          # the clock was held
    assert tm([9.0])[0] == pytest.approx(1.0 - 4.0)         # before the first /clock: slope K
    assert tm([10.112])[0] == pytest.approx(1.032 + 0.4)
    assert np.isnan(tm([np.nan])[0])


def test_time_map_ignores_a_clock_going_back() -> None:
    import pandas as pd

    clock = pd.DataFrame({"pub_t": [1.0, 1.004, 1.008], "clock.sec": [5, 1, 5],
                          "clock.nanosec": [0, 0, 16_000_000]}, index=pd.Index([1.0, 1.004, 1.008], name="t"))
    tm = time_map(clock, K)
    assert list(tm.sim) == [5.0, 5.0, 5.016]


def test_bag_on_simulated_time_is_read_in_simulated_seconds(tmp_path: Path, ts) -> None:
    bag = write_sim_bag(tmp_path / "bag", ts)
    frames = load_frames(bag)
    assert isinstance(frames[TIMEBASE], TimeMap)
    cmd = frames["/turtle1/cmd_vel"]
    # receive and send times of each command land within the tick that triggered it
    ticks = np.ceil(np.arange(1, len(cmd) + 1) / 30 / TICK - 1e-6) * TICK
    assert cmd.index.to_numpy() == pytest.approx(ticks + 0.0009 * K, abs=5e-6)
    assert cmd["pub_t"].to_numpy() == pytest.approx(ticks + 0.0005 * K, abs=5e-6)
    # the analyzer measures the node's ROS timer: 30 Hz, not 120 Hz
    rate = analyze.run("publish_rate", frames, {"topic": "/turtle1/cmd_vel", "expected_hz": 30.0})
    assert rate.status == "pass" and rate.value == pytest.approx(30.0, rel=0.01)
    # wall-clock stamps inside messages follow: /rosout stamps and console stamps
    logs = rosout_lines(frames)
    seconds = np.ceil(np.arange(1, 7) / TICK - 1e-6) * TICK     # first tick of each second
    assert logs["time"].to_numpy() == pytest.approx(seconds + 0.0002 * K, abs=5e-6)
    out = stdout_lines(frames)
    assert out["time"].to_numpy() == pytest.approx(logs["time"].to_numpy(), abs=5e-6)
    assert list(out["logger"]) == ["simple_subscriber"] * 6


def test_scale_one_reads_wall_clock_and_a_missing_clock_is_an_error(tmp_path: Path, ts) -> None:
    bag = write_sim_bag(tmp_path / "bag", ts)
    raw = load_frames(bag, time_scale=1.0)
    assert TIMEBASE not in raw
    assert raw["/turtle1/cmd_vel"].index[0] == pytest.approx(sim_to_wall(0.048) + 0.0009)
    rate = analyze.run("publish_rate", raw, {"topic": "/turtle1/cmd_vel", "expected_hz": 30.0})
    assert rate.value == pytest.approx(120.0, rel=0.01)     # what ignoring /clock would grade
    # a bag that says it ran on simulated time but lost its clock cannot be read right
    no_clock = write_sim_bag(tmp_path / "noclock", ts, clock=False)
    with pytest.raises(GraderError, match=r"recorded on simulated time \(4x\).*no /clock"):
        load_frames(no_clock)
    # the topic selection does not need to name /clock
    only = load_frames(bag, ["/turtle1/cmd_vel"])
    assert only["/turtle1/cmd_vel"].index[0] == pytest.approx(0.048 + 0.0036, abs=5e-6)
