"""Pure turtlesim physics (no ROS): turtle state and the exact per-tick update of Jazzy's turtlesim.

Everything here mirrors the C++ ``turtlesim`` 1.8.x code (the behaviour is written down in docs/turtlesim.md)
down to the float32 casts, so that a bag recorded against this simulator carries the same pose
numbers a student would see with the real one.  Keeping it free of rclpy makes every rule unit
testable with synthetic clocks; ``grader.sim.node`` only wires ROS endpoints to these objects.

Coordinates: like the C++ code we store position in *screen* coordinates (``x``, ``ys`` with
``ys = H - y`` pointing down) as doubles, and heading in world sense (CCW positive).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Protocol

if TYPE_CHECKING:  # pragma: no cover - typing only
    from grader.sim.canvas import Canvas

_F32 = struct.Struct("<f")


def f32(value: float) -> float:
    """Round a Python float to the nearest float32 (what a C ``static_cast<float>`` does)."""
    try:
        return _F32.unpack(_F32.pack(value))[0]
    except OverflowError:  # struct refuses what C silently turns into +-inf
        return math.copysign(math.inf, value)


#: the truncated constant of turtle.hpp (``#define PI 3.14159265``), not math.pi
PI = 3.14159265
TWO_PI = 2.0 * PI
#: pixels per meter: height of the turtle images
METER = 45.0
#: canvas size in pixels
CANVAS_PX = 500
#: world width = height in meters: (500 - 1) / 45 computed in float32
W = f32(f32(CANVAS_PX - 1) / f32(METER))
H = W
#: tick interval of the Qt timer (ms) and the fixed simulated time step (interval * 0.001)
TICK_MS = 16
DT = 0.001 * TICK_MS
#: a command stays in force while (now - stamp) <= 1 s
CMD_TIMEOUT_NS = 1_000_000_000
#: rotate_absolute stops when closer than this (rad)
ROTATE_TOLERANCE = 0.02

DEFAULT_PEN = (0xB3, 0xB8, 0xFF)
DEFAULT_PEN_WIDTH = 3
DEFAULT_BACKGROUND = (0x45, 0x56, 0xFF)

WALL_WARNING = "Oh no! I hit the wall! (Clamping from [x=%f, y=%f])"


def wrap(angle: float) -> float:
    """turtlesim's normalizeAngle: into [-PI, PI) with the truncated PI, in double."""
    return angle - TWO_PI * math.floor((angle + PI) / TWO_PI)


def qround(value: float) -> int:
    """Qt 5 ``qRound``: round half away from zero (used by ``QPointF::toPoint``)."""
    if value >= 0.0:
        return int(value + 0.5)
    return int(value - 0.5)


def _fuzzy_equal(a: float, b: float) -> bool:
    """One coordinate of Qt 5 ``QPointF::operator==`` (fuzzy compare, exact near zero)."""
    if a == 0.0 or b == 0.0:
        return abs(a - b) <= 1e-12
    return abs(a - b) * 1e12 <= min(abs(a), abs(b))


LogFn = Callable[[str, str], None]
"""``log(level, message)`` with level in {"debug", "info", "warn", "error"}."""


@dataclass
class RotateGoal:
    """An accepted rotate_absolute goal as the tick loop sees it.

    ``handle`` is opaque here (the node stores its rclpy goal handle and result future);
    ``cancel_requested`` is set by the node when the action server accepted a cancel request.
    """

    theta: float
    handle: Any = None
    start: float = 0.0
    delta: float = 0.0
    cancel_requested: bool = False


@dataclass
class Pen:
    r: int = DEFAULT_PEN[0]
    g: int = DEFAULT_PEN[1]
    b: int = DEFAULT_PEN[2]
    width: int = DEFAULT_PEN_WIDTH


@dataclass
class _Teleport:
    relative: bool
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0
    linear: float = 0.0


class Turtle:
    """One turtle: state plus the C++ ``Turtle::update`` step.

    Outputs of the last :meth:`update` are left in attributes so the node can publish without
    building intermediate objects: ``pose_x``, ``pose_y``, ``pose_theta``, ``pose_linear``,
    ``pose_angular`` (doubles; float32 rounding happens when the message is serialised, exactly
    like the C++ assignments to float fields), ``color`` (r, g, b), ``feedback`` (remaining of
    the active goal or None) and ``finished`` ((goal, status) with status in
    {"succeeded", "canceled"} or None).
    """

    __slots__ = ("name", "x", "ys", "orient", "vx", "vy", "w", "last_cmd_ns", "stamp_pending",
                 "pen_on", "pen", "teleports", "goal", "_log", "pose_x", "pose_y", "pose_theta",
                 "pose_linear", "pose_angular", "color", "feedback", "finished", "endpoints")

    def __init__(self, name: str, x: float, y: float, theta: float, now_ns: int,
                 log: LogFn | None = None) -> None:
        self.name = name
        # QPointF(x, height_in_meters_ - y) with float arguments: the subtraction is float32
        self.x = f32(x)
        self.ys = f32(H - f32(y))
        self.orient = f32(theta)
        self.vx = 0.0
        self.vy = 0.0
        self.w = 0.0
        self.last_cmd_ns = now_ns
        self.stamp_pending = False
        self.pen_on = True
        self.pen = Pen()
        self.teleports: list[_Teleport] = []
        self.goal: RotateGoal | None = None
        self._log: LogFn = log or (lambda level, msg: None)
        self.pose_x = self.x
        self.pose_y = H - self.ys
        self.pose_theta = self.orient
        self.pose_linear = 0.0
        self.pose_angular = 0.0
        self.color = (255, 255, 255)
        self.feedback: float | None = None
        self.finished: tuple[RotateGoal, str] | None = None
        self.endpoints: Any = None  # owned by the node (publishers, services, action server)

    # -- inputs (called from ROS callbacks between ticks) ---------------------------------
    def command_velocity(self, linear_x: float, linear_y: float, angular_z: float,
                         holonomic: bool) -> RotateGoal | None:
        """cmd_vel callback. Returns the rotate goal it aborts (caller reports ABORTED).

        The command timestamp is taken at the next tick (``stamp_pending``): the C++ node runs
        its callbacks in ``spin_some`` right before the update, so its stamp is the tick time.
        """
        self.stamp_pending = True
        self.vx = float(linear_x)
        if holonomic:
            self.vy = float(linear_y)
        self.w = float(angular_z)
        aborted = self.goal
        if aborted is not None:
            self._log("warn", "Velocity command received during rotation goal. Aborting goal")
            self.goal = None
        return aborted

    def set_pen(self, r: int, g: int, b: int, width: int, off: int) -> None:
        """set_pen: off keeps the old pen; on builds a new pen (width 0 -> Qt default 1)."""
        self.pen_on = not off
        if off:
            return
        self.pen = Pen(int(r), int(g), int(b), int(width) if width else 1)

    def teleport_absolute(self, x: float, y: float, theta: float) -> None:
        """Queued; applied at the start of the next update."""
        self.teleports.append(_Teleport(False, x=float(x), y=float(y), theta=float(theta)))

    def teleport_relative(self, linear: float, angular: float) -> None:
        """Queued; applied at the start of the next update (rotate first, then move)."""
        self.teleports.append(_Teleport(True, linear=float(linear), theta=float(angular)))

    def accept_goal(self, goal: RotateGoal) -> RotateGoal | None:
        """Make ``goal`` the active rotate goal; returns the preempted goal (to be ABORTED)."""
        previous = self.goal
        if previous is not None:
            self._log("warn", "Rotation goal received before a previous goal finished. "
                              "Aborting previous goal")
        goal.start = self.orient
        goal.delta = 0.0
        self.goal = goal
        return previous

    # -- the tick -------------------------------------------------------------------------
    def update(self, now_ns: int, canvas: "Canvas | None", held: bool = False) -> None:
        """One 16 ms step, in the C++ order: teleports, goal, timeout, integrate, clamp,
        (publish pose + color: left in attributes), draw the trail segment. ``held`` (a grader
        addition, :attr:`World.held`): teleports apply and commands are kept, but the turtle
        does not move: the pose is published where it is, with zero velocities."""
        meter = METER
        pen_on = self.pen_on
        if self.stamp_pending:
            self.last_cmd_ns = now_ns
            self.stamp_pending = False

        # 1. teleport requests, in arrival order
        if self.teleports:
            self._teleport(canvas)
        if held:
            self.pose_x, self.pose_y, self.pose_theta = self.x, H - self.ys, self.orient
            self.pose_linear = self.pose_angular = 0.0
            self.feedback = self.finished = None
            if canvas is not None:
                self.color = canvas.pixel(qround(self.x * meter), qround(self.ys * meter))
            return

        # 2. rotate_absolute goal
        self.feedback = None
        self.finished = None
        if self.goal is not None:
            self._rotate_to_goal(now_ns)

        # 3. command timeout (strictly more than 1 s)
        if now_ns - self.last_cmd_ns > CMD_TIMEOUT_NS:
            self.vx = self.vy = self.w = 0.0

        # 4. integrate: rotate first, then translate along the new heading
        ox, oys = self.x, self.ys
        vx, vy = self.vx, self.vy
        orient = self.orient + self.w * DT
        orient = orient - TWO_PI * math.floor((orient + PI) / TWO_PI)
        self.orient = orient
        c = math.cos(orient)
        s = math.sin(orient)
        x = self.x + (c * vx * DT - s * vy * DT)
        ys = self.ys - (c * vy * DT + s * vx * DT)

        # 5. walls: warn with the internal (screen) coordinates, clamp, keep the velocity
        if x < 0 or x > W or ys < 0 or ys > H:
            self._log("warn", WALL_WARNING % (x, ys))
        x = min(max(x, 0.0), W)
        ys = min(max(ys, 0.0), H)
        self.x = x
        self.ys = ys

        # 6. pose (published by the caller)
        self.pose_x = x
        self.pose_y = H - ys
        self.pose_theta = orient
        self.pose_linear = math.sqrt(vx * vx + vy * vy)
        self.pose_angular = self.w

        # 7. colour under the turtle, read before this tick's segment is drawn
        if canvas is not None:
            self.color = canvas.pixel(qround(x * meter), qround(ys * meter))

        # 8. trail segment
        if pen_on and canvas is not None and not (_fuzzy_equal(x, ox) and _fuzzy_equal(ys, oys)):
            pen = self.pen
            canvas.draw_line(x * meter, ys * meter, ox * meter, oys * meter,
                             pen.r, pen.g, pen.b, pen.width)

    def _teleport(self, canvas: "Canvas | None") -> None:
        """The queued teleports, in arrival order (the pen draws each jump, as turtlesim's does)."""
        for req in self.teleports:
            ox, oys = self.x, self.ys
            if req.relative:
                self.orient += req.theta
                self.x += math.cos(self.orient) * req.linear
                self.ys += -math.sin(self.orient) * req.linear
            else:
                self.x = req.x
                self.ys = max(0.0, H - req.y)
                self.orient = req.theta
            if self.pen_on and canvas is not None:
                pen = self.pen
                canvas.draw_line(self.x * METER, self.ys * METER, ox * METER, oys * METER,
                                 pen.r, pen.g, pen.b, pen.width)
        self.teleports.clear()

    def _rotate_to_goal(self, now_ns: int) -> None:
        """Step the rotate_absolute goal: cancel, finish within ``ROTATE_TOLERANCE``, or turn
        toward it at 1 rad/s (a command: it resets the timeout)."""
        goal = self.goal
        assert goal is not None
        if goal.cancel_requested:
            self._log("info", "Rotation goal canceled")
            self.finished = (goal, "canceled")
            self.goal = None
            self.vx = self.vy = self.w = 0.0
        else:
            theta = wrap(goal.theta)
            o32 = f32(self.orient)
            remaining = wrap(theta - o32)
            goal.delta = wrap(f32(goal.start - self.orient))
            self.feedback = remaining
            if abs(wrap(o32 - theta)) < ROTATE_TOLERANCE:
                self._log("info", "Rotation goal completed successfully")
                self.finished = (goal, "succeeded")
                self.goal = None
                self.vx = self.vy = self.w = 0.0
            else:
                self.vx = self.vy = 0.0
                self.w = -1.0 if remaining < 0.0 else 1.0
                self.last_cmd_ns = now_ns

    # -- views for tests / tools -----------------------------------------------------------
    def pose(self) -> tuple[float, float, float, float, float]:
        """The last published pose as float32 values: (x, y, theta, linear, angular)."""
        return (f32(self.pose_x), f32(self.pose_y), f32(self.pose_theta),
                f32(self.pose_linear), f32(self.pose_angular))

    @property
    def y(self) -> float:
        """World y (up) of the current internal position, in double."""
        return H - self.ys


class WorldListener(Protocol):
    """What the node implements to create/destroy a turtle's ROS endpoints."""

    def turtle_added(self, turtle: Turtle) -> None: ...

    def turtle_removed(self, turtle: Turtle) -> None: ...


@dataclass
class World:
    """All turtles, the auto-name counter and the trail canvas (C++ ``TurtleFrame``).

    ``log`` receives every log line the real node prints (level, text); ``listener`` is told
    about turtles being created (before the "Spawning" line, as in C++) and removed.
    """

    canvas: "Canvas | None" = None
    log: LogFn = field(default=lambda level, msg: None)
    listener: WorldListener | None = None
    turtles: dict[str, Turtle] = field(default_factory=dict)
    id_counter: int = 0
    started: bool = False
    ticks: int = 0
    #: a grader addition: while held, turtles take teleports and commands but do not move (the
    #: scenario driver holds them while it hands a placed turtle's new goal over, so a student's
    #: controller cannot steer for the old goal in the meantime; see grader.scenario.steps)
    held: bool = False
    _order: list[Turtle] = field(default_factory=list)

    def ordered(self) -> list[Turtle]:
        """Turtles in std::map order (lexicographic by name): the per-tick update order."""
        return self._order

    def _reorder(self) -> None:
        self._order = [self.turtles[n] for n in sorted(self.turtles)]

    def spawn(self, name: str, x: float, y: float, theta: float, now_ns: int = 0) -> str:
        """Spawn service semantics; returns the turtle's name, or "" if the name is taken."""
        real_name = name
        if not real_name:
            while True:
                self.id_counter += 1
                real_name = f"turtle{self.id_counter}"
                if real_name not in self.turtles:
                    break
        elif real_name in self.turtles:
            self.log("error", f"A turtle named [{name}] already exists")
            return ""
        turtle = Turtle(real_name, x, y, theta, now_ns, self.log)
        self.turtles[real_name] = turtle
        self._reorder()
        if self.listener is not None:
            try:
                self.listener.turtle_added(turtle)
            except Exception:
                del self.turtles[real_name]  # e.g. a name that is no valid ROS name
                self._reorder()
                raise
        self.log("info", "Spawning turtle [%s] at x=[%f], y=[%f], theta=[%f]"
                 % (real_name, f32(x), f32(y), f32(theta)))
        return real_name

    def spawn_default(self, now_ns: int = 0) -> str:
        """The first turtle, at the centre (width_in_meters_ / 2.0)."""
        return self.spawn("", W / 2.0, H / 2.0, 0.0, now_ns)

    def kill(self, name: str) -> Turtle | None:
        """Kill service semantics; returns the removed turtle (None + ERROR if unknown)."""
        turtle = self.turtles.pop(name, None)
        if turtle is None:
            self.log("error", f"Tried to kill turtle [{name}], which does not exist")
            return None
        self._reorder()
        if self.listener is not None:
            self.listener.turtle_removed(turtle)
        return turtle

    def clear(self) -> None:
        """clear service: wipe the trails (turtles, pens and poses untouched)."""
        self.log("info", "Clearing turtlesim.")
        if self.canvas is not None:
            self.canvas.clear()

    def reset(self, now_ns: int = 0) -> list[Turtle]:
        """reset service: remove all turtles, counter to 0, new turtle1, wipe trails.

        Returns the removed turtles (so the node can finish their active goals).
        """
        self.log("info", "Resetting turtlesim.")
        removed = list(self._order)
        self.turtles.clear()
        self._order = []
        if self.listener is not None:
            for turtle in removed:
                self.listener.turtle_removed(turtle)
        self.id_counter = 0
        self.spawn_default(now_ns)
        if self.canvas is not None:
            self.canvas.clear()
        return removed

    def tick(self, now_ns: int, on_updated: Callable[[Turtle], None] | None = None) -> bool:
        """One timer tick. The first tick only records that time has started (C++ stores a
        timestamp and returns; a zero ROS time, e.g. sim time without /clock, keeps skipping).
        Returns True if turtles were updated."""
        if not self.started:
            if now_ns != 0:
                self.started = True
            return False
        canvas = self.canvas
        for turtle in self._order:
            turtle.update(now_ns, canvas, self.held)
            if on_updated is not None:
                on_updated(turtle)
        self.ticks += 1
        return True
