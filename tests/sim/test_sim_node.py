"""Live tests of the turtlesim node: one real sim process shared by the module, real clients.

Each test drives its own spawned turtle so tests do not disturb each other; the tests that
reset or stop the simulator come last in this file.  Exact numbers come from the pure physics
module (tested exactly in test_sim_physics.py); here we check the ROS wiring and allow one tick
of timer jitter where the spec does.
"""

from __future__ import annotations

import math
import os
import signal
import time
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest

from grader.runner import ProcessSpec, RosGraph
from grader.sim import SAVE_CANVAS_SERVICE, sim_argv
from grader.sim.canvas import read_png
from grader.sim.physics import DEFAULT_BACKGROUND, DEFAULT_PEN, H, W, RotateGoal, World, f32
from grader.testing.ros import rclpy_node, spin_until

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

rclpy = pytest.importorskip("rclpy")

from action_msgs.msg import GoalStatus  # noqa: E402
from geometry_msgs.msg import Twist  # noqa: E402
from rcl_interfaces.msg import Log, Parameter, ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import DescribeParameters, ListParameters, SetParameters  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile,  # noqa: E402
                       ReliabilityPolicy)
from service_msgs.msg import ServiceEventInfo  # noqa: E402
from std_srvs.srv import Empty  # noqa: E402
from turtlesim.action import RotateAbsolute  # noqa: E402
from turtlesim.msg import Color, Pose  # noqa: E402
from turtlesim.srv import Kill, SetPen, Spawn, TeleportAbsolute, TeleportRelative  # noqa: E402

QOS7 = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=7, reliability=ReliabilityPolicy.RELIABLE)
#: deep reader queues so a busy test process never drops a pose it wants to compare
DEEP = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=500,
                  reliability=ReliabilityPolicy.RELIABLE)
ROSOUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
CENTER = 5.544444561004639


class Client:
    """One in-process rclpy node talking to the sim: service calls, pose/colour/rosout taps."""

    def __init__(self, node: Any, executor: Any) -> None:
        self.node = node
        self.executor = executor
        self.rosout: list[Log] = []
        self.poses: dict[str, list[Pose]] = {}
        self.colors: dict[str, list[Color]] = {}
        self.sent: dict[int, int] = {}      # id(message) -> its writer's source timestamp (ns)
        self._clients: dict[str, Any] = {}
        self._pubs: dict[str, Any] = {}
        self._subs: dict[str, list[Any]] = {}
        self.spawned: list[str] = []
        node.create_subscription(Log, "/rosout", self.rosout.append, ROSOUT_QOS)

    def spin_until(self, predicate: Callable[[], bool], timeout: float = 10.0) -> bool:
        return spin_until(self.executor, predicate, timeout, step=0.01)

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def call(self, srv_type: Any, name: str, request: Any, timeout: float = 10.0) -> Any:
        client = self._clients.get(name)
        if client is None:
            client = self._clients[name] = self.node.create_client(srv_type, name)
        assert self.spin_until(client.service_is_ready, timeout), f"{name} not available"
        future = client.call_async(request)
        assert self.spin_until(future.done, timeout), f"{name} did not answer"
        return future.result()

    def watch(self, turtle: str) -> None:
        """Record /<turtle>/pose and /<turtle>/color_sensor."""
        if turtle in self.poses:
            return
        self.poses[turtle] = []
        self.colors[turtle] = []

        def keeper(into: list) -> Callable[[Any, Any], None]:
            def keep(msg: Any, info: Any) -> None:
                self.sent[id(msg)] = info["source_timestamp"]
                into.append(msg)
            return keep

        self._subs[turtle] = [
            self.node.create_subscription(Pose, f"/{turtle}/pose", keeper(self.poses[turtle]), DEEP),
            self.node.create_subscription(Color, f"/{turtle}/color_sensor", keeper(self.colors[turtle]), DEEP)]
        assert self.spin_until(lambda: len(self.poses[turtle]) > 2 and self.colors[turtle])

    def kill_spawned(self) -> None:
        """Kill the turtles this test spawned and stop listening to them (keeps load low)."""
        for turtle in self.spawned:
            for sub in self._subs.pop(turtle, []):
                self.node.destroy_subscription(sub)
            self.poses.pop(turtle, None)
            self.colors.pop(turtle, None)
            pub = self._pubs.pop(turtle, None)
            if pub is not None:
                self.node.destroy_publisher(pub)
            self.call(Kill, "/kill", Kill.Request(name=turtle))
        self.spawned.clear()

    def spawn(self, name: str, x: float = CENTER, y: float = CENTER, theta: float = 0.0) -> str:
        got = self.call(Spawn, "/spawn", Spawn.Request(x=x, y=y, theta=theta, name=name)).name
        if got:
            self.spawned.append(got)
            self.watch(got)
        return got

    def cmd_vel(self, turtle: str, lx: float = 0.0, az: float = 0.0, ly: float = 0.0) -> None:
        pub = self._pubs.get(turtle)
        if pub is None:
            pub = self._pubs[turtle] = self.node.create_publisher(Twist, f"/{turtle}/cmd_vel", QOS7)
            assert self.spin_until(lambda: pub.get_subscription_count() > 0)
        msg = Twist()
        msg.linear.x, msg.linear.y, msg.angular.z = lx, ly, az
        pub.publish(msg)

    def settle(self, turtle: str, timeout: float = 5.0) -> Pose:
        """Wait for motion that was just commanded to start and then stop (zero velocity for
        a few ticks); returns the last pose."""
        poses = self.poses[turtle]
        start = len(poses)

        def moved() -> bool:
            return any(p.linear_velocity or p.angular_velocity for p in poses[start:])

        def still() -> bool:
            tail = poses[-5:]
            return len(tail) == 5 and all(p.linear_velocity == 0.0 and p.angular_velocity == 0.0
                                          for p in tail)
        assert self.spin_until(moved, timeout), f"{turtle} never started moving"
        assert self.spin_until(still, timeout), f"{turtle} never stopped"
        return poses[-1]

    def _fresh(self, received: list) -> Any:
        """The third message of ``received`` its writer sent after this call: earlier requests
        are reflected. Counting arrivals is not enough: beside ``make demo`` a backlog of poses
        sent before a teleport was still queued in the reader once the teleport had been
        answered, and three "new" poses all showed the turtle where it had been."""
        since = time.time_ns()

        def after() -> list:
            return [m for m in received if self.sent.get(id(m), 0) > since]
        assert self.spin_until(lambda: len(after()) >= 3)
        return after()[2]

    def fresh_pose(self, turtle: str) -> Pose:
        """A pose published after this call (so earlier requests are reflected)."""
        return self._fresh(self.poses[turtle])

    def fresh_color(self, turtle: str) -> tuple[int, int, int]:
        c = self._fresh(self.colors[turtle])
        return (c.r, c.g, c.b)

    def logs(self, level: int | None = None, contains: str = "") -> list[str]:
        return [m.msg for m in self.rosout if m.name == "turtlesim"
                and (level is None or m.level == level) and contains in m.msg]


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RosGraph]:
    with RosGraph(tmp_path_factory.mktemp("sim_graph")) as g:
        yield g


@pytest.fixture(scope="module")
def canvas_png(graph: RosGraph) -> Path:
    return graph.workdir / "canvas.png"


@pytest.fixture(scope="module")
def sim(graph: RosGraph, canvas_png: Path) -> Any:
    return graph.start(ProcessSpec(name="sim", argv=sim_argv(canvas_out=canvas_png)))


@pytest.fixture(scope="module")
def shared_client(graph: RosGraph, sim: Any) -> Iterator[Client]:
    with rclpy_node(graph.domain_id, "sim_test_client") as (node, executor):
        c = Client(node, executor)
        c.watch("turtle1")
        yield c


@pytest.fixture
def client(shared_client: Client) -> Iterator[Client]:
    """The shared client; turtles a test spawns are killed after it."""
    yield shared_client
    if shared_client.spawned:
        shared_client.kill_spawned()


def simulate(world_setup: Callable[[World], None], ticks: int, turtle: str) -> list[tuple]:
    """Poses (float32 tuples) of ``turtle`` after each of ``ticks`` pure-physics ticks."""
    world = World()
    world.spawn_default(0)
    world_setup(world)
    now = 1_000_000_000
    world.tick(now)
    out = []
    for _ in range(ticks):
        now += 16_000_000
        world.tick(now)
        out.append(world.turtles[turtle].pose())
    return out


def as_tuple(p: Pose) -> tuple:
    return (p.x, p.y, p.theta, p.linear_velocity, p.angular_velocity)


# -- startup, parameters, graph -------------------------------------------------------------

def test_startup_pose_color_and_logs(client: Client) -> None:
    pose = client.poses["turtle1"][-1]
    assert as_tuple(pose) == (CENTER, CENTER, 0.0, 0.0, 0.0)
    assert client.fresh_color("turtle1") == (255, 255, 255)
    assert client.spin_until(lambda: len(client.logs(Log.INFO)) >= 2)
    assert client.logs(Log.INFO, "Starting turtlesim") == [
        "Starting turtlesim with node name /turtlesim"]
    assert "Spawning turtle [turtle1] at x=[5.544445], y=[5.544445], theta=[0.000000]" \
        in client.logs(Log.INFO)


def test_pose_rate_is_62_5_hz(client: Client) -> None:
    stamps: list[float] = []
    sub = client.node.create_subscription(Pose, "/turtle1/pose",
                                          lambda _m: stamps.append(time.monotonic()), DEEP)
    try:
        client.spin_for(3.0)
    finally:
        client.node.destroy_subscription(sub)
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    assert 60.0 < rate < 65.0


def test_parameters_match_jazzy(client: Client) -> None:
    names = client.call(ListParameters, "/turtlesim/list_parameters",
                        ListParameters.Request()).result.names
    assert sorted(names) == [
        "background_b", "background_g", "background_r", "holonomic",
        "qos_overrides./parameter_events.publisher.depth",
        "qos_overrides./parameter_events.publisher.durability",
        "qos_overrides./parameter_events.publisher.history",
        "qos_overrides./parameter_events.publisher.reliability",
        "start_type_description_service", "use_sim_time"]
    desc = client.call(DescribeParameters, "/turtlesim/describe_parameters",
                       DescribeParameters.Request(names=["background_r", "holonomic",
                                                         "qos_overrides./parameter_events."
                                                         "publisher.depth"])).descriptors
    assert desc[0].description == "Red channel of the background color"
    rng = desc[0].integer_range[0]
    assert (rng.from_value, rng.to_value, rng.step) == (0, 255, 1)
    assert desc[1].description == "If true, then turtles will be holonomic"
    assert desc[2].read_only is True


def set_param(client: Client, name: str, value: ParameterValue) -> bool:
    req = SetParameters.Request(parameters=[Parameter(name=name, value=value)])
    return client.call(SetParameters, "/turtlesim/set_parameters", req).results[0].successful


def test_background_range_is_enforced(client: Client) -> None:
    assert not set_param(client, "background_r",
                         ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=300))
    assert not set_param(client, "holonomic",
                         ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=1))
    assert set_param(client, "background_g",
                     ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=86))


def test_topic_qos_and_introspection_topics(client: Client) -> None:
    infos = client.node.get_publishers_info_by_topic("/turtle1/pose")
    assert len(infos) == 1
    qos = infos[0].qos_profile
    assert qos.reliability == ReliabilityPolicy.RELIABLE and qos.durability == \
        DurabilityPolicy.VOLATILE
    topics = dict(client.node.get_topic_names_and_types())
    for srv in ("/spawn", "/kill", "/clear", "/reset", "/turtle1/set_pen",
                "/turtle1/teleport_absolute", "/turtle1/teleport_relative"):
        assert f"{srv}/_service_event" in topics, srv
    assert topics["/turtle1/teleport_absolute/_service_event"] == [
        "turtlesim/srv/TeleportAbsolute_Event"]


# -- motion ---------------------------------------------------------------------------------------

def test_cmd_vel_once_matches_vector_within_one_tick(client: Client) -> None:
    client.spawn("vec")
    client.cmd_vel("vec", 2.0, 1.8)
    final = client.settle("vec")
    moving = [p for p in client.poses["vec"] if p.linear_velocity > 0]
    expected = simulate(lambda w: (w.spawn("vec", CENTER, CENTER, 0.0),
                                   w.turtles["vec"].command_velocity(2.0, 0.0, 1.8, False)),
                        64, "vec")
    assert len(moving) in (62, 63, 64)
    assert (final.x, final.y, final.theta) == expected[len(moving) - 1][:3]
    if len(moving) == 63:
        assert final.x == pytest.approx(6.6028166, abs=1e-6)
        assert final.y == pytest.approx(6.9389896, abs=1e-6)
    # the live trajectory equals the pure one tick by tick
    assert [as_tuple(p) for p in moving] == expected[:len(moving)]
    assert client.fresh_color("vec") == DEFAULT_PEN


def test_wall_clamps_and_warns_on_rosout(client: Client) -> None:
    client.spawn("wall", 10.9, 5.0, 0.0)
    client.cmd_vel("wall", 2.0)
    assert client.spin_until(lambda: client.poses["wall"][-1].x == f32(W))
    pinned = client.fresh_pose("wall")
    assert pinned.x == f32(W) and pinned.linear_velocity == 2.0  # velocity not zeroed
    assert client.spin_until(lambda: len(client.logs(Log.WARN, "Oh no! I hit the wall!")) >= 3)
    warning = client.logs(Log.WARN, "Oh no! I hit the wall!")[0]
    assert warning.startswith("Oh no! I hit the wall! (Clamping from [x=")
    x_printed = float(warning.split("[x=")[1].split(",")[0])
    assert W < x_printed < W + 0.033                           # one 2 m/s step past the wall
    assert warning.endswith(", y=%f])" % f32(H - f32(5.0)))  # internal screen y = 6.088889
    client.settle("wall")


def test_set_pen_teleports_and_color_sensor(client: Client) -> None:
    client.spawn("pen", 2.0, 2.0, 0.0)
    events: list[Any] = []
    sub = client.node.create_subscription(TeleportAbsolute.Event, "/pen/teleport_absolute/_service_event",
                                          events.append, 10)
    # the events are volatile: call only once DDS has matched the simulator's event writer
    assert client.spin_until(lambda: sub.get_publisher_count() >= 1)
    client.call(SetPen, "/pen/set_pen", SetPen.Request(r=255, g=0, b=0, width=5, off=0))
    client.call(TeleportAbsolute, "/pen/teleport_absolute", TeleportAbsolute.Request(x=4.0, y=2.0))
    assert (client.fresh_pose("pen").x, client.fresh_color("pen")) == (4.0, (255, 0, 0))
    client.call(SetPen, "/pen/set_pen", SetPen.Request(off=1))
    client.call(TeleportRelative, "/pen/teleport_relative",
                TeleportRelative.Request(linear=1.0, angular=0.0))
    assert client.fresh_pose("pen").x == 5.0
    assert client.fresh_color("pen") == (255, 255, 255)       # pen off: nothing drawn
    client.call(TeleportAbsolute, "/pen/teleport_absolute", TeleportAbsolute.Request(x=3.0, y=2.0))
    assert client.fresh_color("pen") == (255, 0, 0)           # pen off, over the red trail
    client.call(TeleportRelative, "/pen/teleport_relative",
                TeleportRelative.Request(linear=1.0, angular=f32(math.pi / 2)))
    pose = client.fresh_pose("pen")
    assert pose.theta == f32(math.pi / 2) and pose.y == pytest.approx(3.0, abs=1e-6)
    client.call(TeleportAbsolute, "/pen/teleport_absolute",
                TeleportAbsolute.Request(x=3.0, y=20.0, theta=0.0))
    assert client.fresh_pose("pen").y == f32(H)               # silently limited to the top
    # service introspection: requests (with contents) are on <service>/_service_event
    assert client.spin_until(lambda: len(events) >= 6)
    requests = [e for e in events if e.info.event_type == ServiceEventInfo.REQUEST_RECEIVED]
    assert [(r.request[0].x, r.request[0].y) for r in requests][:2] == [(4.0, 2.0), (3.0, 2.0)]


def test_holonomic_parameter(client: Client) -> None:
    client.spawn("holo")
    client.cmd_vel("holo", 0.0, 0.0, ly=1.0)
    client.spin_for(0.5)
    assert {(p.x, p.y) for p in client.poses["holo"]} == {(CENTER, CENTER)}  # y ignored
    on = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=True)
    off = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=False)
    assert set_param(client, "holonomic", on)
    try:
        client.cmd_vel("holo", 0.0, 0.0, ly=1.0)
        pose = client.settle("holo")
        assert pose.x == CENTER and pose.y == pytest.approx(CENTER + 1.0, abs=0.05)
    finally:
        assert set_param(client, "holonomic", off)


# -- rotate_absolute -----------------------------------------------------------------------------

class Goal:
    """A rotate_absolute goal sent through a real ActionClient."""

    def __init__(self, client: Client, action: ActionClient, theta: float) -> None:
        self.client = client
        self.feedback: list[float] = []
        future = action.send_goal_async(RotateAbsolute.Goal(theta=theta),
                                         feedback_callback=self._on_feedback)
        assert client.spin_until(future.done)
        self.handle = future.result()
        assert self.handle.accepted
        self.result_future = self.handle.get_result_async()

    def _on_feedback(self, msg: Any) -> None:
        self.feedback.append(msg.feedback.remaining)

    def result(self, timeout: float = 10.0) -> tuple[int, float]:
        assert self.client.spin_until(self.result_future.done, timeout)
        res = self.result_future.result()
        return res.status, res.result.delta


def action_client(client: Client, turtle: str) -> ActionClient:
    action = ActionClient(client.node, RotateAbsolute, f"/{turtle}/rotate_absolute",
                          feedback_sub_qos_profile=DEEP)
    assert action.wait_for_server(timeout_sec=10.0)
    return action


def feedback_matched(client: Client, action: ActionClient, turtle: str) -> int:
    """Goals to the turtle's own heading (it does not move; one feedback, then success) until
    one's feedback arrives; returns how many were sent. Answered goal requests prove only that
    the simulator knows this client's writers: DDS matches each side of a pair on its own, and
    in a fresh clone's make test a goal sent at once lost its first 8 feedback messages to the
    simulator's feedback writer not having matched this client's reader yet."""
    for sent in range(1, 21):
        warm = Goal(client, action, client.fresh_pose(turtle).theta)
        assert warm.result()[0] == GoalStatus.STATUS_SUCCEEDED
        if client.spin_until(lambda w=warm: bool(w.feedback), 1.0):
            return sent
    raise AssertionError("no feedback from 20 goals")


def test_rotate_absolute_live_vector(client: Client) -> None:
    client.spawn("rot")
    done = "Rotation goal completed successfully"
    before = len(client.logs(Log.INFO, done))
    action = action_client(client, "rot")
    warmups = feedback_matched(client, action, "rot")
    goal = Goal(client, action, 1.57)
    status, delta = goal.result()
    assert status == GoalStatus.STATUS_SUCCEEDED
    assert delta == -1.5520000457763672
    # the same goal in the pure physics gives the feedback sequence the client must have seen
    world = World()
    world.spawn("rot", CENTER, CENTER, 0.0)
    world.turtles["rot"].accept_goal(RotateGoal(theta=f32(1.57)))
    world.tick(1)
    expected = []
    for k in range(98):
        world.tick(2 + k)
        expected.append(f32(world.turtles["rot"].feedback))
    assert len(goal.feedback) == 98 and goal.feedback == expected
    assert client.fresh_pose("rot").theta == f32(1.552)
    assert client.spin_until(lambda: len(client.logs(Log.INFO, done)) >= before + warmups + 1)


def test_rotate_preempt_cancel_and_cmd_vel_abort(client: Client) -> None:
    client.spawn("act")
    action = action_client(client, "act")
    first = Goal(client, action, 3.0)
    client.spin_for(0.3)
    second = Goal(client, action, -1.0)
    status, delta = first.result()
    assert status == GoalStatus.STATUS_ABORTED and delta < -0.1   # CCW so far: negative delta
    assert client.spin_until(lambda: "Rotation goal received before a previous goal finished. "
                             "Aborting previous goal" in client.logs(Log.WARN))
    client.spin_for(0.2)
    cancel = second.handle.cancel_goal_async()
    assert client.spin_until(cancel.done)
    assert len(cancel.result().goals_canceling) == 1
    status, _ = second.result()
    assert status == GoalStatus.STATUS_CANCELED
    assert client.fresh_pose("act").angular_velocity == 0.0       # stops immediately
    assert "Rotation goal canceled" in client.logs(Log.INFO)
    third = Goal(client, action, 2.5)
    client.spin_for(0.2)
    client.cmd_vel("act", 1.0)
    status, _ = third.result()
    assert status == GoalStatus.STATUS_ABORTED
    assert client.spin_until(lambda: "Velocity command received during rotation goal. "
                             "Aborting goal" in client.logs(Log.WARN))
    pose = client.fresh_pose("act")
    assert (pose.linear_velocity, pose.angular_velocity) == (1.0, 0.0)  # the command wins
    client.settle("act")


# -- the canvas PNG ------------------------------------------------------------------------------

@pytest.mark.slow
def test_circle_png_shows_default_pen_on_default_background(client: Client,
                                                            canvas_png: Path) -> None:
    client.spawn("circle", 2.8, 8.2, 0.0)
    deadline = time.monotonic() + 4.0
    while time.monotonic() < deadline:                       # 4 Hz, > one full circle
        client.cmd_vel("circle", 2.0, 1.8)
        client.spin_for(0.25)
    client.settle("circle")
    client.call(Empty, SAVE_CANVAS_SERVICE, Empty.Request())
    img = read_png(canvas_png)
    assert img.shape == (500, 500, 3)
    assert tuple(img[5, 5]) == DEFAULT_BACKGROUND               # untouched corner
    trail = [p for p in client.poses["circle"] if p.linear_velocity > 0]
    assert len(trail) > 200
    end = client.poses["circle"][-1]
    away = [p for p in trail[:200:5] if math.hypot(p.x - end.x, p.y - end.y) > 0.4]
    assert len(away) > 20                                     # not under the turtle marker
    on_trail = [tuple(img[round(45 * (H - p.y)), round(45 * p.x)]) for p in away]
    assert set(on_trail) == {DEFAULT_PEN}
    centre = (2.8, 8.2 + 2.0 / 1.8)                             # circle centre (radius 1.11 m)
    assert tuple(img[round(45 * (H - centre[1])), round(45 * centre[0])]) == DEFAULT_BACKGROUND


# -- reset and shutdown (keep these last: they end the shared simulator's state) ----------------

def test_spawn_kill_reset_naming_live(client: Client) -> None:
    assert client.spawn("turtle1") == ""                        # duplicate name
    assert client.spin_until(lambda: "A turtle named [turtle1] already exists"
                             in client.logs(Log.ERROR))
    client.spawn("doomed")
    auto = client.call(Spawn, "/spawn", Spawn.Request(x=1.0, y=1.0)).name
    assert auto == "turtle2"
    client.call(Kill, "/kill", Kill.Request(name="turtle2"))
    assert client.spin_until(lambda: client.node.count_publishers("/turtle2/pose") == 0)
    assert client.call(Spawn, "/spawn", Spawn.Request(x=1.0, y=1.0)).name == "turtle3"
    assert client.call(Spawn, "/spawn", Spawn.Request(name="bad name")).name == ""
    assert client.spin_until(lambda: any(m.startswith("Failed to spawn turtle [bad name]")
                                         for m in client.logs(Log.ERROR)))
    client.call(Kill, "/kill", Kill.Request(name="nobody"))
    assert client.spin_until(lambda: "Tried to kill turtle [nobody], which does not exist"
                             in client.logs(Log.ERROR))
    client.call(Empty, "/reset", Empty.Request())
    assert client.spin_until(lambda: "Resetting turtlesim." in client.logs(Log.INFO))
    assert client.spin_until(lambda: client.node.count_publishers("/doomed/pose") == 0)
    client.spawned.clear()                                      # reset removed them already
    assert client.call(Spawn, "/spawn", Spawn.Request(x=1.0, y=1.0)).name == "turtle2"
    assert as_tuple(client.fresh_pose("turtle1")) == (CENTER, CENTER, 0.0, 0.0, 0.0)


def test_sigint_saves_canvas_and_exits_zero(sim: Any, client: Client, canvas_png: Path) -> None:
    before = canvas_png.stat().st_mtime_ns if canvas_png.exists() else 0
    time.sleep(0.01)
    assert sim.stop() == 0
    assert canvas_png.stat().st_mtime_ns > before
    assert read_png(canvas_png).shape == (500, 500, 3)


@pytest.mark.slow
def test_sigterm_saves_canvas_and_exits_zero(tmp_path: Path) -> None:
    png = tmp_path / "term.png"
    with RosGraph(tmp_path / "g") as graph:
        proc = graph.start(ProcessSpec(name="sim", argv=sim_argv(canvas_out=png)))
        with rclpy_node(graph.domain_id, "term_client") as (node, executor):
            poses: list[Pose] = []
            node.create_subscription(Pose, "/turtle1/pose", poses.append, QOS7)
            assert spin_until(executor, lambda: len(poses) > 3, 15.0)
        os.killpg(proc.pgid, signal.SIGTERM)
        assert proc.wait(10) == 0
    img = read_png(png)
    assert tuple(img[5, 5]) == DEFAULT_BACKGROUND


# -- timer catch-up (in-process node, fake timer and steady clock) -----------------------------

class _FakeTime:
    def __init__(self, ns: int) -> None:
        self.nanoseconds = ns


class _FakeSteady:
    """Stands in for the steady clock and the rcl timer grid (next call on 16 ms multiples)."""

    def __init__(self) -> None:
        self.now_ns = 0

    def now(self) -> _FakeTime:
        return _FakeTime(self.now_ns)

    def time_until_next_call(self) -> int:
        period = 16_000_000
        return (self.now_ns // period + 1) * period - self.now_ns


def test_missed_timer_periods_are_caught_up(ros_graph: RosGraph) -> None:
    from grader.sim.node import TurtlesimNode

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=ros_graph.domain_id)
    node = TurtlesimNode(context=ctx)
    try:
        fake = _FakeSteady()
        node._steady_clock = fake
        node._tick_timer = fake
        ms = 1_000_000
        for at, ticks in ((0, 0),                     # first callback: only starts the clock
                          (16 * ms + 500_000, 1),     # on time
                          (64 * ms + 200_000, 4),     # slots 1 and 2 were skipped: 3 ticks
                          (80 * ms + 100_000, 5),     # on time again
                          (400 * ms + 100_000, 6)):   # 19 slots lost: resync, no flood
            fake.now_ns = at
            node._on_tick()
            assert node.world.ticks == ticks, at
        assert (node.caught_up_ticks, node.resynced_ticks) == (2, 19)
    finally:
        node.destroy_node()
        rclpy.shutdown(context=ctx)
