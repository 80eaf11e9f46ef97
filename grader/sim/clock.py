"""Simulated time: the simulator owns the clock when a scenario runs faster than real time.

With ``--time-scale K`` the simulator no longer follows the wall clock: a steady timer firing
every ``16 ms / K`` of wall time advances simulated time by exactly one tick (16 ms), steps the
physics with that time (so motion per tick is the 1x motion, bit for bit) and publishes it on
``/clock`` (``rosgraph_msgs/msg/Clock``) after the tick's poses. Nodes started with
``use_sim_time:=true`` follow it: their timers, ``create_rate`` and ``get_clock().now()``.

Why no catch-up here (the 1x simulator runs missed timer periods late): a late tick only makes
simulated time advance a little slower; it never merges two ticks into one jump of the clock,
which a student timer faster than the tick could only see as one period.

Holds: a student's process needs wall time to start (Python imports, discovery), which at K x
would cost it K times more simulated time than at 1x. The scenario driver therefore *holds*
the clock while a process starts (service ``~/hold_clock``, ``std_srvs/srv/SetBool``; the
response's ``message`` is the time it holds at and how many ``/clock`` readers are matched, so
the driver can wait for a new node's reader): the clock stops, and keeps being republished,
at the next :func:`hold_point`, one tick after a multiple of 2 s. A node created while the clock
is held sees that time first; rcl fires its timers once at that first ``/clock`` and from then
on on their grid from zero, so a timer whose period divides 2 s (1 s, 0.5 s, 0.1 s...) keeps a
first interval within one tick of its period instead of a random fraction of it.

Lockstep (``--lockstep``): no timer at all. The scenario driver advances time, one tick per
pair of calls: ``~/step_clock`` (16 ms more, published on ``/clock``), then, once every process
has handled that (:mod:`grader.scenario.quiescence`), ``~/step_world`` (the world's step at
that time with the commands taken so far, its poses published), then again once they are
handled. Each node sees the same messages at the same simulated times in every run, however
busy the machine: the same code draws the same path (:mod:`grader.scenario.lockstep`). A
scenario's driver makes both calls over a socket the simulator alone inherits (``--step-fd``,
:mod:`grader.sim.stepchannel`: a DDS call cost ten times its CPU); the two services then only
answer (the driver's probes before the first tick), so no other node can move the clock.

The sim-time run starts at 0 (like Gazebo and ``ros2 bag play --clock``), so a node that kept a
``now()`` from before its first ``/clock`` (which reads 0) is off by seconds, not by decades.
"""

from __future__ import annotations

from typing import Any

from grader.sim.physics import TICK_MS

CLOCK_TOPIC = "/clock"
#: relative to the node that owns the clock (the simulator, or ``grader_clock`` without one)
HOLD_SERVICE = "hold_clock"
#: ``std_srvs/srv/Trigger``: stop the clock at once, for good (the scenario has ended)
STOP_SERVICE = "stop_clock"
#: lockstep (``std_srvs/srv/SetBool``): ``data`` true, simulated time advances one tick, published
#: on ``/clock``; false, only the time is answered (a probe the driver repeats until answered: a
#: request or its reply can be lost while discovery has not matched both ends yet)
STEP_CLOCK_SERVICE = "step_clock"
#: lockstep (``std_srvs/srv/Trigger``): the world's step at that time, its poses published (once
#: per time: called again, it answers the same)
STEP_WORLD_SERVICE = "step_world"
#: node name of the clock publisher of scenarios without a simulator (``sim: false``)
CLOCK_NODE = "grader_clock"
TICK_NS = TICK_MS * 1_000_000
#: holds stop the clock one tick after a multiple of this
HOLD_GRID_NS = 2_000_000_000


def hold_point(now_ns: int) -> int:
    """The first time >= ``now_ns`` that is one tick after a multiple of ``HOLD_GRID_NS``
    (a tick time when ``now_ns`` is one: the grid of 2 s holds 125 ticks)."""
    k = -(-(now_ns - TICK_NS) // HOLD_GRID_NS)       # ceil
    return max(k, 0) * HOLD_GRID_NS + TICK_NS


class SimClock:
    """Simulated time of one node: advances a tick per :meth:`tick`, held on request.

    Pure state plus two ROS endpoints made by :meth:`attach` (publisher and hold service), so the
    hold rule is testable without ROS.
    """

    def __init__(self, time_scale: float) -> None:
        if not time_scale >= 1.0:
            raise ValueError(f"time scale must be >= 1, got {time_scale}")
        self.time_scale = float(time_scale)
        self.now_ns = 0
        self.held = False
        self.hold_at: int | None = None
        self.requests = 0          # hold/stop requests served (the driver compares with its own)
        self._pub: Any = None
        self._msg: Any = None

    @property
    def period_s(self) -> float:
        """Wall-clock period of the tick timer."""
        return TICK_MS / 1000.0 / self.time_scale

    def tick(self) -> int | None:
        """Advance one tick; the new time, or None while held."""
        if self.held:
            return None
        self.now_ns += TICK_NS
        if self.hold_at is not None and self.now_ns >= self.hold_at:
            self.held = True
        return self.now_ns

    def stop(self) -> int:
        """No tick after this one: the scenario ended. Its shutdown takes wall time, which must
        not become K times more simulated time (a turtle stopping, nodes timing out)."""
        self.held = True
        return self.now_ns

    def hold(self, on: bool) -> int:
        """Start (``on``) or end a hold; returns the time the clock holds at (or runs from)."""
        if not on:
            self.held = False
            self.hold_at = None
            return self.now_ns
        if self.held:
            return self.now_ns
        if self.hold_at is None:
            self.hold_at = hold_point(self.now_ns)
            self.held = self.now_ns == self.hold_at
        return self.hold_at

    # -- ROS wiring ---------------------------------------------------------------------------
    def attach(self, node: Any) -> None:
        """Create the ``/clock`` publisher (the ROS clock QoS: best effort, depth 1) and the
        node's ``~/hold_clock`` service."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: PLC0415 - rclpy.qos: ROS, imported where it is used (this module loads in processes that never use it)
        from rosgraph_msgs.msg import Clock  # noqa: PLC0415 - rosgraph_msgs.msg: ROS, imported where it is used (this module loads in processes that never use it)
        from std_srvs.srv import SetBool, Trigger  # noqa: PLC0415 - std_srvs.srv: ROS, imported where it is used (this module loads in processes that never use it)

        self._msg = Clock()
        self._pub = node.create_publisher(Clock, CLOCK_TOPIC,
                                          QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        node.create_service(SetBool, f"~/{HOLD_SERVICE}", self._on_hold)
        node.create_service(Trigger, f"~/{STOP_SERVICE}", self._on_stop)

    def _on_hold(self, req: Any, res: Any) -> Any:
        """``message``: "<time it holds at (or runs from), ns> <matched /clock readers>": the
        driver asks again while holding until a starting node's reader is matched."""
        self.requests += 1
        res.message = f"{self.hold(bool(req.data))} {self.readers()}"
        res.success = True
        return res

    def _on_stop(self, _req: Any, res: Any) -> Any:
        """``message``: "<time it stopped at, ns> <hold/stop requests served, this one included>"."""
        self.requests += 1
        res.message = f"{self.stop()} {self.requests}"
        res.success = True
        return res

    def readers(self) -> int:
        """``/clock`` readers matched by the publisher."""
        return int(self._pub.get_subscription_count())

    def publish(self) -> None:
        stamp = self._msg.clock
        stamp.sec, stamp.nanosec = divmod(self.now_ns, 1_000_000_000)
        self._pub.publish(self._msg)


def make_clock_node(context: Any, time_scale: float) -> Any:
    """The clock of a scenario without a simulator: node ``grader_clock`` publishing ``/clock``
    (same ticks, same holds), nothing else."""
    from rclpy.clock import Clock, ClockType  # noqa: PLC0415 - rclpy.clock: ROS, imported where it is used (this module loads in processes that never use it)
    from rclpy.node import Node  # noqa: PLC0415 - rclpy.node: ROS, imported where it is used (this module loads in processes that never use it)

    node = Node(CLOCK_NODE, context=context, start_parameter_services=False)
    clock = SimClock(time_scale)
    clock.attach(node)

    def on_tick() -> None:
        clock.tick()
        clock.publish()

    node.sim_clock = clock  # type: ignore[attr-defined]  # (grader_clock keeps it on its node)
    node.create_timer(clock.period_s, on_tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
    return node
