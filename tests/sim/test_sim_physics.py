"""Exact tests of the pure turtlesim physics against the spec's rules and test vectors (§13).

No ROS here: a synthetic clock drives ticks 16 ms apart, so every number is deterministic.
"""

from __future__ import annotations

import math

import pytest

from grader.sim.canvas import Canvas
from grader.sim.physics import (DEFAULT_PEN, H, PI, W, RotateGoal, Turtle, World, f32, qround,
                                wrap)

T0 = 1_000_000_000  # first tick time (non-zero: a zero ROS time keeps the first-tick guard)
TICK = 16_000_000


class Sim:
    """A World on a synthetic clock that records its log lines."""

    def __init__(self) -> None:
        self.logs: list[tuple[str, str]] = []
        self.world = World(canvas=Canvas(), log=lambda lvl, msg: self.logs.append((lvl, msg)))
        self.now = T0
        self.world.spawn_default(0)
        self.world.tick(self.now)  # the skipped first tick

    @property
    def t1(self) -> Turtle:
        return self.world.turtles["turtle1"]

    def tick(self, n: int = 1) -> None:
        for _ in range(n):
            self.now += TICK
            assert self.world.tick(self.now)

    def warnings(self) -> list[str]:
        return [m for lvl, m in self.logs if lvl == "warn"]


@pytest.fixture
def sim() -> Sim:
    return Sim()


def drive_ticks(sim: Sim, n: int) -> tuple[float, float, float, float, float]:
    sim.t1.command_velocity(2.0, 0.0, 1.8, False)
    sim.tick(n)
    return sim.t1.pose()


# -- constants and helpers ------------------------------------------------------------------------

def test_world_size_and_start_pose(sim: Sim) -> None:
    assert W == 11.088889122009277 == H
    from grader.contracts.world import WORLD_SIZE_M

    assert abs(W - WORLD_SIZE_M) < 1e-6      # the one world size every other package uses
    assert sim.t1.pose() == (5.544444561004639, 5.544444561004639, 0.0, 0.0, 0.0)
    assert sim.logs == [("info", "Spawning turtle [turtle1] at x=[5.544445], y=[5.544445], "
                                 "theta=[0.000000]")]


def test_wrap_uses_truncated_pi() -> None:
    assert wrap(math.pi) == pytest.approx(-3.14159264641, abs=1e-11)
    assert wrap(math.pi) != -math.pi
    assert wrap(4.0) == pytest.approx(-2.2831853, abs=1e-12)
    assert wrap(-3.14159265) == -3.14159265
    assert wrap(PI) == -PI  # the range is [-PI, PI)


def test_qround_half_away_from_zero() -> None:
    assert [qround(v) for v in (0.5, 1.5, 2.4999, -0.5, -1.5)] == [1, 2, 2, -1, -2]


def test_first_tick_is_skipped_and_zero_time_keeps_skipping() -> None:
    world = World()
    world.spawn_default(0)
    assert world.tick(0) is False and world.tick(0) is False  # sim time without /clock
    assert world.tick(T0) is False                            # records the start only
    assert world.tick(T0 + TICK) is True


# -- §13 test vectors -----------------------------------------------------------------------------

def test_cmd_vel_once_63_ticks_vector(sim: Sim) -> None:
    x, y, theta, lin, ang = drive_ticks(sim, 63)
    assert (x, y, theta) == (f32(6.602816581726074), f32(6.938989639282227),
                             f32(1.8143999576568604))
    assert x == pytest.approx(6.6028166, abs=1e-7) and y == pytest.approx(6.9389896, abs=1e-7)
    assert theta == pytest.approx(1.8144, abs=1e-6)
    assert (lin, ang) == (2.0, f32(1.8))  # still commanded on the last moving tick


def test_cmd_vel_once_62_ticks_vector(sim: Sim) -> None:
    x, y, theta, _lin, _ang = drive_ticks(sim, 62)
    assert x == pytest.approx(6.6105347, abs=1e-7)
    assert y == pytest.approx(6.9079342, abs=1e-7)
    assert theta == pytest.approx(1.7856, abs=1e-6)


def test_cmd_vel_times_out_after_one_second(sim: Sim) -> None:
    final = drive_ticks(sim, 63)
    sim.tick(1)
    after = sim.t1.pose()
    assert after[:3] == final[:3]           # stopped exactly after 63 integrated ticks
    assert after[3:] == (0.0, 0.0)          # pose velocities drop to 0
    sim.tick(50)
    assert sim.t1.pose() == after           # and it stays there, still publishing


def test_held_turtles_take_teleports_and_commands_but_do_not_move(sim: Sim) -> None:
    """The grader's hold (``World.held``, ``~/hold_turtles``): while held a teleport applies and
    commands are kept, nothing moves, the pose shows zero velocities; released, the turtle drives
    with the last command exactly as if it had just arrived."""
    sim.world.held = True
    sim.t1.teleport_absolute(2.0, 7.0, 2.1)
    sim.tick(1)
    placed = sim.t1.pose()
    assert placed == (f32(2.0), f32(7.0), f32(2.1), 0.0, 0.0)
    sim.t1.command_velocity(2.0, 0.0, 1.8, False)       # e.g. a controller for the old goal
    sim.t1.command_velocity(1.0, 0.0, -0.5, False)      # ... then for the new one
    sim.tick(20)
    assert sim.t1.pose() == placed
    sim.world.held = False
    sim.tick(1)
    x, y, theta, lin, ang = sim.t1.pose()
    assert (lin, ang) == (1.0, f32(-0.5))
    assert theta == pytest.approx(2.1 - 0.5 * 0.016, abs=1e-6)
    assert math.hypot(x - 2.0, y - 7.0) == pytest.approx(0.016, abs=1e-6)


def test_timeout_is_strictly_greater_than_one_second() -> None:
    world = World()
    world.spawn_default(0)
    world.tick(T0)
    turtle = world.turtles["turtle1"]
    turtle.command_velocity(1.0, 0.0, 0.0, False)
    world.tick(T0 + TICK)                         # stamps the command at this tick
    world.tick(T0 + TICK + 1_000_000_000)         # exactly 1 s later: still moving
    assert turtle.pose()[3] == 1.0
    world.tick(T0 + TICK + 1_000_000_001)         # 1 ns more: stopped
    assert turtle.pose()[3] == 0.0


def rotate_run(sim: Sim, theta: float) -> tuple[RotateGoal, list[float], int]:
    goal = RotateGoal(theta=f32(theta))
    assert sim.t1.accept_goal(goal) is None
    feedback: list[float] = []
    for tick in range(1, 500):
        sim.tick()
        if sim.t1.feedback is not None:
            feedback.append(f32(sim.t1.feedback))
        if sim.t1.finished is not None:
            assert sim.t1.finished == (goal, "succeeded")
            return goal, feedback, tick
    raise AssertionError("rotate goal never finished")


def test_rotate_absolute_vector(sim: Sim) -> None:
    goal, feedback, ticks = rotate_run(sim, 1.57)
    assert len(feedback) == 98 and ticks == 98
    assert feedback[:2] == [1.5700000524520874, 1.5540000200271606]
    assert feedback[-2:] == [0.03400003910064697, 0.018000006675720215]
    assert f32(goal.delta) == -1.5520000457763672
    assert sim.t1.pose() == (5.544444561004639, 5.544444561004639, f32(1.552), 0.0, 0.0)
    assert ("info", "Rotation goal completed successfully") in sim.logs


def test_rotate_absolute_drives_with_unit_angular_velocity(sim: Sim) -> None:
    sim.t1.accept_goal(RotateGoal(theta=f32(-1.0)))
    sim.tick(5)
    assert sim.t1.pose()[3:] == (0.0, -1.0)  # shortest way is clockwise
    assert sim.t1.feedback is not None and sim.t1.feedback < 0


def test_rotate_goal_ignores_command_timeout(sim: Sim) -> None:
    _goal, _fb, ticks = rotate_run(sim, 3.0)  # ~3 s of rotation > the 1 s command timeout
    assert ticks > 150


def test_rotate_preemption_aborts_previous_goal(sim: Sim) -> None:
    first = RotateGoal(theta=f32(3.0))
    sim.t1.accept_goal(first)
    sim.tick(10)
    second = RotateGoal(theta=f32(0.0))
    assert sim.t1.accept_goal(second) is first  # caller reports ABORTED with first.delta
    assert f32(first.delta) == f32(wrap(f32(0.0 - 0.144)))
    assert second.start == sim.t1.orient and second.delta == 0.0
    assert sim.warnings() == ["Rotation goal received before a previous goal finished. "
                              "Aborting previous goal"]
    sim.tick(1)
    assert sim.t1.pose()[4] == -1.0  # now heading back towards 0


def test_rotate_cancel_stops_without_feedback(sim: Sim) -> None:
    goal = RotateGoal(theta=f32(2.0))
    sim.t1.accept_goal(goal)
    sim.tick(20)
    delta_before = goal.delta
    goal.cancel_requested = True
    sim.tick(1)
    assert sim.t1.finished == (goal, "canceled")
    assert sim.t1.feedback is None
    assert goal.delta == delta_before
    assert sim.t1.pose()[3:] == (0.0, 0.0)
    assert ("info", "Rotation goal canceled") in sim.logs


def test_cmd_vel_aborts_rotate_goal_and_keeps_velocity(sim: Sim) -> None:
    goal = RotateGoal(theta=f32(2.0))
    sim.t1.accept_goal(goal)
    sim.tick(5)
    assert sim.t1.command_velocity(1.0, 0.0, 0.0, False) is goal
    assert sim.t1.goal is None
    assert sim.warnings() == ["Velocity command received during rotation goal. Aborting goal"]
    sim.tick(1)
    assert sim.t1.pose()[3:] == (1.0, 0.0)


def test_teleport_does_not_stop_rotate_goal(sim: Sim) -> None:
    goal = RotateGoal(theta=f32(1.0))
    sim.t1.accept_goal(goal)
    sim.tick(10)
    sim.t1.teleport_absolute(2.0, 2.0, 0.5)
    sim.tick(1)
    assert sim.t1.goal is goal
    # delta stays relative to the heading at acceptance (0): start - current
    assert f32(goal.delta) == f32(wrap(f32(0.0 - 0.5)))


# -- walls ----------------------------------------------------------------------------------------

def test_wall_clamps_warns_and_keeps_velocity(sim: Sim) -> None:
    sim.t1.teleport_absolute(W - 0.01, 5.0, 0.0)
    sim.tick(1)
    sim.t1.command_velocity(2.0, 0.0, 0.0, False)
    sim.tick(3)
    x, y, _theta, lin, _ang = sim.t1.pose()
    assert x == f32(W) and lin == 2.0            # pinned at the wall, still commanded
    warnings = sim.warnings()
    assert len(warnings) == 3                    # one per tick while pushing
    # internal coordinates: x beyond W, y measured down from the top edge
    assert warnings[0] == ("Oh no! I hit the wall! (Clamping from [x=%f, y=%f])"
                           % (W - 0.01 + 0.032, W - f32(5.0)))
    assert "y=6.088889" in warnings[0]


def test_wall_bottom_prints_screen_y_above_height(sim: Sim) -> None:
    sim.t1.teleport_absolute(3.0, 0.01, -math.pi / 2)
    sim.t1.command_velocity(1.0, 0.0, 0.0, False)
    sim.tick(2)
    assert sim.t1.pose()[1] == 0.0
    y_printed = float(sim.warnings()[0].split("y=")[1].rstrip("])"))
    assert y_printed > 11.088889


def test_wall_slides_along_with_tangential_motion(sim: Sim) -> None:
    sim.t1.teleport_absolute(W, 5.0, math.pi / 4)
    sim.t1.command_velocity(2.0, 0.0, 0.0, False)
    sim.tick(10)
    x, y, *_ = sim.t1.pose()
    assert x == f32(W) and y > 5.2


def test_spawn_outside_is_clamped_and_normalised_on_first_update(sim: Sim) -> None:
    sim.world.spawn("far", 12.0, -1.0, 4.0)
    far = sim.world.turtles["far"]
    assert (far.x, far.orient) == (12.0, 4.0)     # no checks at spawn time
    sim.tick(1)
    assert far.pose()[:3] == (f32(W), 0.0, f32(wrap(4.0)))
    assert sim.warnings() == ["Oh no! I hit the wall! (Clamping from [x=12.000000, y=%f])"
                              % f32(H - f32(-1.0))]


# -- spawn / kill / reset -------------------------------------------------------------------------

def test_spawn_kill_naming(sim: Sim) -> None:
    world = sim.world
    assert world.spawn("", 1.0, 1.0, 0.0) == "turtle2"
    assert world.kill("turtle2") is not None
    assert world.spawn("", 1.0, 1.0, 0.0) == "turtle3"      # counter never decrements
    assert world.spawn("turtle5", 1.0, 1.0, 0.0) == "turtle5"
    assert world.spawn("", 1.0, 1.0, 0.0) == "turtle4"
    assert world.spawn("", 1.0, 1.0, 0.0) == "turtle6"      # skips the taken name
    assert world.spawn("turtle4", 2.0, 2.0, 0.0) == ""      # duplicate: empty name, no turtle
    assert ("error", "A turtle named [turtle4] already exists") in sim.logs
    assert world.turtles["turtle4"].pose()[0] == 1.0
    assert world.kill("nobody") is None
    assert ("error", "Tried to kill turtle [nobody], which does not exist") in sim.logs
    assert ("info", "Spawning turtle [turtle5] at x=[1.000000], y=[1.000000], theta=[0.000000]"
            ) in sim.logs


def test_update_order_is_lexicographic(sim: Sim) -> None:
    for name in ("turtle2", "turtle10", "a"):
        sim.world.spawn(name, 1.0, 1.0, 0.0)
    seen: list[str] = []
    sim.now += TICK
    sim.world.tick(sim.now, lambda t: seen.append(t.name))
    assert seen == ["a", "turtle1", "turtle10", "turtle2"]


def test_reset_restarts_naming_and_clears_trails(sim: Sim) -> None:
    sim.world.spawn("", 2.0, 2.0, 0.0)
    drive_ticks(sim, 30)
    assert sim.world.canvas is not None and sim.world.canvas.rgba[:, :, 3].any()
    sim.logs.clear()
    sim.world.reset(0)
    assert list(sim.world.turtles) == ["turtle1"]
    assert sim.t1.pose() == (5.544444561004639, 5.544444561004639, 0.0, 0.0, 0.0)
    assert not sim.world.canvas.rgba[:, :, 3].any()
    assert [m for _l, m in sim.logs] == [
        "Resetting turtlesim.",
        "Spawning turtle [turtle1] at x=[5.544445], y=[5.544445], theta=[0.000000]"]
    assert sim.world.spawn("", 1.0, 1.0, 0.0) == "turtle2"


def test_clear_keeps_turtles_and_pens(sim: Sim) -> None:
    sim.t1.set_pen(10, 20, 30, 4, 0)
    drive_ticks(sim, 10)
    pose = sim.t1.pose()
    sim.world.clear()
    assert sim.logs[-1] == ("info", "Clearing turtlesim.")
    assert sim.t1.pose() == pose and (sim.t1.pen.r, sim.t1.pen.width) == (10, 4)
    sim.tick(1)
    assert sim.t1.color == (255, 255, 255)


# -- pen, trails and the colour sensor ------------------------------------------------------------

def painted_rows_at_column(canvas: Canvas, column: int) -> list[int]:
    return [int(j) for j in (canvas.rgba[:, column, 3] > 0).nonzero()[0]]


def test_color_sensor_untouched_canvas_reads_white(sim: Sim) -> None:
    sim.tick(3)
    assert sim.t1.color == (255, 255, 255)


def test_color_sensor_reads_own_trail_in_default_pen(sim: Sim) -> None:
    drive_ticks(sim, 80)
    assert sim.t1.color == DEFAULT_PEN


def test_pen_off_draws_nothing_and_keeps_pen(sim: Sim) -> None:
    sim.t1.set_pen(1, 2, 3, 7, 1)
    assert sim.t1.pen_on is False
    assert (sim.t1.pen.r, sim.t1.pen.g, sim.t1.pen.b, sim.t1.pen.width) == (*DEFAULT_PEN, 3)
    drive_ticks(sim, 40)
    sim.t1.teleport_relative(1.0, 0.0)
    sim.tick(1)
    assert not sim.world.canvas.rgba[:, :, 3].any()
    assert sim.t1.color == (255, 255, 255)


def test_pen_width_zero_means_one_pixel_and_width_is_not_kept(sim: Sim) -> None:
    sim.t1.set_pen(200, 0, 0, 0, 0)
    assert sim.t1.pen.width == 1
    sim.t1.set_pen(200, 0, 0, 9, 0)
    sim.t1.set_pen(0, 200, 0, 0, 0)
    assert sim.t1.pen.width == 1


@pytest.mark.parametrize("width", [1, 3, 5, 8])
def test_trail_width_in_pixels(sim: Sim, width: int) -> None:
    sim.t1.set_pen(255, 0, 0, width, 0)
    sim.t1.command_velocity(2.0, 0.0, 0.0, False)  # straight east along y = const
    sim.tick(20)
    column = round(sim.t1.x * 45.0) - 10
    rows = painted_rows_at_column(sim.world.canvas, column)
    assert len(rows) == width and rows == list(range(rows[0], rows[0] + width))
    assert tuple(sim.world.canvas.rgba[rows[0], column]) == (255, 0, 0, 255)


def test_pen_on_off_over_existing_trail(sim: Sim) -> None:
    sim.t1.set_pen(255, 0, 0, 5, 0)
    sim.t1.teleport_absolute(8.0, 5.544444561004639, 0.0)  # draws a red line to the east
    sim.tick(1)
    assert sim.t1.color == (255, 0, 0)
    sim.t1.set_pen(0, 0, 0, 0, 1)
    sim.t1.teleport_relative(1.0, 0.0)                       # off the line, pen off: no trail
    sim.tick(1)
    assert sim.t1.color == (255, 255, 255)
    sim.t1.teleport_absolute(7.0, 5.544444561004639, 0.0)   # back over the red line
    sim.tick(1)
    assert sim.t1.color == (255, 0, 0)


# -- teleports ------------------------------------------------------------------------------------

def test_teleport_absolute_applies_next_tick_and_keeps_command(sim: Sim) -> None:
    sim.t1.command_velocity(1.0, 0.0, 0.0, False)
    sim.tick(1)
    sim.t1.teleport_absolute(f32(2.5), f32(3.5), f32(0.0))
    assert sim.t1.pose()[0] != f32(2.5)                     # queued, not applied yet
    sim.tick(1)
    x, y, theta, lin, _ = sim.t1.pose()
    assert (x, lin, theta) == (f32(2.5 + 0.016), 1.0, 0.0)  # then integrated in the same tick
    assert y == f32(3.5)


def test_teleport_absolute_above_top_is_silently_limited(sim: Sim) -> None:
    sim.t1.teleport_absolute(3.0, 20.0, 0.0)
    sim.tick(1)
    assert sim.t1.pose()[1] == f32(H)
    assert sim.warnings() == []


def test_teleport_absolute_below_bottom_warns_and_clamps(sim: Sim) -> None:
    sim.t1.teleport_absolute(3.0, -2.0, 0.0)
    sim.tick(1)
    assert sim.t1.pose()[1] == 0.0
    assert len(sim.warnings()) == 1


def test_teleport_absolute_theta_normalised_at_integration(sim: Sim) -> None:
    sim.t1.teleport_absolute(3.0, 3.0, 4.0)
    sim.tick(1)
    assert sim.t1.pose()[2] == f32(wrap(4.0))


def test_teleport_relative_rotates_then_moves(sim: Sim) -> None:
    x0, y0 = sim.t1.x, sim.t1.y
    sim.t1.teleport_relative(f32(1.0), f32(math.pi / 2))
    sim.tick(1)
    heading = f32(math.pi / 2)
    x, y, theta, *_ = sim.t1.pose()
    assert x == f32(x0 + math.cos(heading))
    assert y == f32(H - (f32(H - y0) + -math.sin(heading)))
    assert y == pytest.approx(y0 + 1.0, abs=1e-6)
    assert theta == heading


def test_teleports_are_applied_in_order_and_draw(sim: Sim) -> None:
    sim.t1.teleport_absolute(2.0, 2.0, 0.0)
    sim.t1.teleport_relative(2.0, 0.0)
    sim.tick(1)
    assert sim.t1.pose()[:2] == (4.0, 2.0)
    canvas = sim.world.canvas
    row = round(45 * (H - 2.0))
    assert tuple(canvas.rgba[row, 135, :3]) == DEFAULT_PEN  # on the second segment (x = 3)


# -- holonomic ------------------------------------------------------------------------------------

def test_non_holonomic_ignores_linear_y(sim: Sim) -> None:
    sim.t1.command_velocity(0.0, 1.0, 0.0, False)
    sim.tick(10)
    assert sim.t1.pose()[:2] == (5.544444561004639, 5.544444561004639)


def test_holonomic_moves_sideways_and_reports_speed_magnitude(sim: Sim) -> None:
    sim.t1.command_velocity(0.0, 1.0, 0.0, True)
    sim.tick(10)
    x, y, _theta, lin, _ = sim.t1.pose()
    assert x == 5.544444561004639 and y == pytest.approx(5.544444561004639 + 0.16, abs=1e-6)
    sim.t1.command_velocity(-3.0, 4.0, 0.0, True)
    sim.tick(1)
    assert sim.t1.pose()[3] == 5.0   # sqrt(vx^2 + vy^2), also when driving backwards


def test_sticky_linear_y_when_holonomic_turned_off(sim: Sim) -> None:
    sim.t1.command_velocity(0.0, 1.0, 0.0, True)
    sim.tick(1)
    sim.t1.command_velocity(1.0, 5.0, 0.0, False)   # vy not overwritten (still 1.0)
    sim.tick(1)
    assert sim.t1.pose()[3] == f32(math.sqrt(2.0))


# -- float32 details that only the exact C++ arithmetic reproduces --------------------------------

def test_spawn_y_goes_through_float32_screen_coordinate() -> None:
    world = World()
    world.spawn("low", 1.0, 0.1, 0.0)
    # C++: QPointF(x, height_in_meters_ - y) subtracts in float; published y = H - ys in double
    assert world.turtles["low"].pose()[1] == 0.10000038146972656 != f32(0.1)


def test_rotate_delta_rounds_to_float32_before_wrapping(sim: Sim) -> None:
    start, current = -0.9357633590698242, 3.0782501697540283
    sim.t1.teleport_absolute(5.0, 5.0, start)
    sim.tick(1)
    goal = RotateGoal(theta=0.0)
    sim.t1.accept_goal(goal)
    sim.t1.teleport_absolute(5.0, 5.0, current)   # teleports keep the goal running
    sim.tick(1)
    assert f32(goal.delta) == 2.269171953201294     # wrap(f32(start - current))
    assert f32(wrap(start - current)) != 2.269171953201294


def test_rotate_tolerance_is_strictly_below_0_02(sim: Sim) -> None:
    goal, feedback, ticks = rotate_run(sim, 1.5745)
    assert ticks == 99 and feedback[-2] == pytest.approx(0.0225, abs=1e-6)  # 0.0225 not enough
    assert abs(feedback[-1]) < 0.02
