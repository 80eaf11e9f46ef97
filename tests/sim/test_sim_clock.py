"""The simulator's own clock (--time-scale): 16 ms per tick, /clock after every tick, holds.

The pure rules first (no ROS), then one live simulator at 4x: identical motion per tick (the
spec's test vector, tick by tick, from a real bag), /clock stepping 16 ms per pose, the hold
service, and simulated time running faster than the wall clock.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from grader.sim.clock import HOLD_GRID_NS, TICK_NS, SimClock, hold_point
from grader.sim.physics import World


def test_hold_point_is_one_tick_after_a_multiple_of_two_seconds() -> None:
    assert HOLD_GRID_NS % TICK_NS == 0 or (HOLD_GRID_NS + TICK_NS) % TICK_NS == 0
    assert hold_point(0) == TICK_NS
    assert hold_point(TICK_NS) == TICK_NS
    assert hold_point(2 * TICK_NS) == HOLD_GRID_NS + TICK_NS
    assert hold_point(HOLD_GRID_NS + TICK_NS) == HOLD_GRID_NS + TICK_NS
    assert hold_point(5 * HOLD_GRID_NS) == 5 * HOLD_GRID_NS + TICK_NS
    for now in range(0, 10 * HOLD_GRID_NS, 7 * TICK_NS):    # always a tick time, never behind
        at = hold_point(now)
        assert at >= now and at % TICK_NS == 0 and at - now < HOLD_GRID_NS + TICK_NS


def test_sim_clock_ticks_holds_at_the_point_and_runs_again() -> None:
    clock = SimClock(4.0)
    assert clock.period_s == pytest.approx(0.004)
    assert [clock.tick() for _ in range(3)] == [TICK_NS, 2 * TICK_NS, 3 * TICK_NS]
    at = clock.hold(True)
    assert at == HOLD_GRID_NS + TICK_NS and not clock.held
    assert clock.hold(True) == at                        # asking again changes nothing
    times = [clock.tick() for _ in range(200)]
    assert times[-1] is None and max(t for t in times if t is not None) == at
    assert clock.now_ns == at and clock.held
    assert clock.hold(True) == at
    assert clock.hold(False) == at
    assert clock.tick() == at + TICK_NS
    with pytest.raises(ValueError):
        SimClock(0.5)


def pure_poses(ticks: int) -> list[tuple]:
    """turtle1 after each tick of a 2.0 m/s, 1.8 rad/s command given before the first one."""
    world = World()
    world.spawn_default(0)
    world.tick(TICK_NS)
    world.turtles["turtle1"].command_velocity(2.0, 0.0, 1.8, False)
    out = []
    for k in range(2, ticks + 2):
        world.tick(k * TICK_NS)
        out.append(world.turtles["turtle1"].pose())
    return out


def test_sim_at_4x_moves_exactly_as_at_1x_per_tick(ros_graph, tmp_path: Path) -> None:
    """One cmd_vel at 4x: the bag holds the spec's 63 moving ticks, each pose equal to the pure
    physics', one /clock 16 ms later per pose, and simulated time runs faster than wall time."""
    from geometry_msgs.msg import Twist
    from std_srvs.srv import SetBool

    from grader.bag.frames import load_frames
    from grader.bag.recorder import recorder_argv, wait_ready
    from grader.runner import ProcessSpec
    from grader.sim import sim_argv
    from grader.testing.ros import rclpy_node, spin_until

    rec = ros_graph.start(ProcessSpec("recorder", recorder_argv(
        tmp_path / "bag", ["/turtle1/pose", "/clock", "/turtle1/cmd_vel"], extra=["--time-scale", "4.0"])))
    wait_ready(rec.stdout_path, 30, rec)
    ros_graph.start(ProcessSpec("sim", sim_argv(time_scale=4.0)))
    with rclpy_node(ros_graph.domain_id) as (node, executor):
        hold = node.create_client(SetBool, "/turtlesim/hold_clock")
        assert hold.wait_for_service(timeout_sec=20)

        def call(on: bool) -> list[int]:
            future = hold.call_async(SetBool.Request(data=on))
            assert spin_until(executor, future.done, 10)
            return [int(v) for v in future.result().message.split()]

        at, _readers = call(True)        # hold, so the command lands before a known tick
        pub = node.create_publisher(Twist, "/turtle1/cmd_vel", 10)
        assert spin_until(executor, lambda: pub.get_subscription_count() >= 2, 20)   # sim + recorder
        time.sleep(at / 1e9 / 4 + 0.5)   # the clock reaches the hold point and stays there
        held_at, _ = call(True)
        assert held_at == at
        msg = Twist()
        msg.linear.x, msg.angular.z = 2.0, 1.8
        pub.publish(msg)
        time.sleep(0.3)
        call(False)
        time.sleep(2.0)                  # 8 s of simulated time: the command has long timed out
    rec.stop()
    frames = load_frames(tmp_path / "bag", time_scale=1.0)        # the raw wall-clock record
    pose, clock = frames["/turtle1/pose"], frames["/clock"]
    sim = clock["clock.sec"].to_numpy() + clock["clock.nanosec"].to_numpy() * 1e-9
    steps = np.round(np.diff(sim), 6)
    assert set(steps) <= {0.0, 0.016}, set(steps)               # one tick per /clock, or held
    assert (steps == 0).sum() > 10                               # the hold republished its time
    moving = pose[pose["linear_velocity"] > 0]
    assert len(moving) == 63                                     # exactly, not 62..64 as at 1x
    got = [tuple(float(v) for v in row) for row in
           moving[["x", "y", "theta", "linear_velocity", "angular_velocity"]].to_numpy(np.float32)]
    assert got == [tuple(float(v) for v in p) for p in pure_poses(63)]
    assert (got[-1][0], got[-1][1]) == pytest.approx((6.6028166, 6.9389896), abs=1e-6)
    # the poses published after the hold: one per tick, and faster than the wall clock
    running = (sim > at / 1e9)
    wall = clock["pub_t"].to_numpy()[running]
    assert len(pose[pose.index > wall[0]]) == pytest.approx(len(wall), abs=3)
    speed = (sim[running][-1] - sim[running][0]) / (wall[-1] - wall[0])
    assert speed > 2.0, f"simulated time ran only {speed:.2f}x the wall clock"
