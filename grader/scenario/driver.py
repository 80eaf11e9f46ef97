"""The scenario driver: an in-process rclpy node that feeds a student's nodes and watches them.

Everything it sends and everything it learns (goals, stdin lines, action responses and results,
process exits) is also published on ``/grader/events``, and student stdout/stderr lines on
``/grader/stdout``, so the bag alone is enough to recompute a grade. With a ``sink`` (the
scenario's recorder, in this process) they go into the bag from here, not through DDS, where any
node could publish an "event" of its own (:mod:`grader.bag.recorder`).

One node holds every client, publisher and the hold/placement state the steps share; what it
asks the graph is in ``graph_queries.py``, what it listens to (poses, commands, counts, action
status) in ``watches.py``, the step logic in ``steps.py``.
"""

from __future__ import annotations

import collections
import contextlib
import json
import socket
import threading
import time
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterator

from grader.executors import make_executor
from grader.runner import ManagedProcess
from grader.contracts.events import EVENTS_TOPIC, STDOUT_TOPIC, Event, EventRecord, build_event
from grader.scenario.graph_queries import GRADER_NODE_PREFIX
from grader.scenario.watches import TopicWatches
from grader.scenario.messages import import_type
from grader.sim.clock import HOLD_SERVICE
from grader.scenario.lockstep import Stepper
from grader.scenario.simtime import ScenarioClock
from grader.sim import HOLD_TURTLES_SERVICE



class Driver(TopicWatches):
    """Owns an rclpy context on the scenario's domain and a background executor thread.

    ``time_scale`` > 1: the node runs with ``use_sim_time`` and ``clock`` measures scenario time
    on the ``/clock`` of ``clock_node`` (see :mod:`grader.scenario.simtime`). ``lockstep``: the
    simulator's clock advances only when this driver's waits step it
    (:mod:`grader.scenario.lockstep`); the callable gives the processes each tick waits for,
    ``lockstep_exclude`` threads of this process it does not, ``lockstep_channel`` the socket
    it steps the simulator over (:mod:`grader.sim.stepchannel`; None: its DDS services).
    """

    def __init__(self, domain_id: int, processes: dict[str, ManagedProcess], sim_node: str = "turtlesim",
                 *, time_scale: float = 1.0, clock_node: str | None = None,
                 sink: Callable[[str, bytes], None] | None = None,
                 recording_matched: Callable[[str, int], bool] | None = None,
                 recorded_count: Callable[[str], int | None] | None = None,
                 lockstep: Callable[[], list[int]] | None = None,
                 lockstep_exclude: Callable[[], set[int]] = set,
                 lockstep_channel: socket.socket | None = None) -> None:
        import rclpy  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install
        from rclpy.clock import Clock, ClockType  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install
        from rclpy.parameter import Parameter  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install
        from std_msgs.msg import String  # noqa: PLC0415 - std_msgs: ROS, imported where it is used, so this module loads without a ROS install

        self._open_node(rclpy, Parameter, domain_id, sim_node, time_scale > 1 or lockstep is not None)
        self._make_clock(time_scale, clock_node, lockstep, lockstep_exclude, lockstep_channel)
        self.String = String
        self._keep_recorder_hooks(sink, recording_matched, recorded_count)
        from rclpy.serialization import serialize_message  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install
        self._serialize = serialize_message
        latched = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.events_pub = self.node.create_publisher(String, EVENTS_TOPIC, latched)
        self.stdout_pub = self.node.create_publisher(String, STDOUT_TOPIC, latched)
        self._init_state(processes)
        self._watch_outputs(QoSProfile, Clock, ClockType, time_scale)
        self._start_spinning()

    def _open_node(self, rclpy: Any, parameter_cls: Any, domain_id: int, sim_node: str, sim_time: bool) -> None:
        """Open the driver's own rclpy context on the scenario's domain and the node every entity is on."""
        self.rclpy = rclpy
        self.sim_node = sim_node
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        overrides = [parameter_cls("use_sim_time", parameter_cls.Type.BOOL, True)] if sim_time else []
        self.node = rclpy.create_node("grader_driver", context=self.ctx, parameter_overrides=overrides)

    def _make_clock(self, time_scale: float, clock_node: str | None, lockstep: Callable[[], list[int]] | None,
                    lockstep_exclude: Callable[[], set[int]], lockstep_channel: socket.socket | None = None) -> None:
        """Make the scenario clock (and lockstep's stepper) right after the node, so its entities come first."""
        # its service clients are made here, before the executor spins, and send while it is paused
        stepper = None
        if lockstep is not None:
            stepper = Stepper(self.ctx, self.sim_node, lockstep, lockstep_exclude, lockstep_channel)
        self.clock = ScenarioClock(time_scale, self.node,
                                   f"/{clock_node.strip('/')}/{HOLD_SERVICE}" if clock_node else None,
                                   paused=self.executor_paused, stepper=stepper)

    def _keep_recorder_hooks(self, sink: Callable[[str, bytes], None] | None,
                             recording_matched: Callable[[str, int], bool] | None,
                             recorded_count: Callable[[str], int | None] | None) -> None:
        """Keep the recorder's callables, through which events reach the bag and recording is checked."""
        #: writes a serialized message of EVENTS_TOPIC / STDOUT_TOPIC straight into the bag
        self.sink = sink
        #: (topic, publishers) -> the recorder's subscription is matched with that many (RecorderThread.matched)
        self.recording_matched = recording_matched
        #: topic -> messages the recorder has written on it so far (RecorderThread.recorded), None
        #: for a topic this recording does not take
        self.recorded_count = recorded_count

    def _init_state(self, processes: dict[str, ManagedProcess]) -> None:
        """Set up the state the callbacks and steps share, all of it before the first callback can run."""
        self.processes = processes
        self.events: list[EventRecord] = []
        self.lock = threading.Lock()
        self.pose: Any = None                      # latest pose of the first watched topic
        self.pose_topic: str | None = None
        self.poses: dict[str, Any] = {}            # topic -> latest pose
        #: topic -> the recent poses, numbered in arrival order (a placement looks for the first
        #: one after its teleport, which may arrive before the service's answer does)
        self.pose_log: dict[str, collections.deque[tuple[int, Any]]] = {}
        self.goal_status: dict[bytes, int] = {}    # action goal id -> last status the server sent
        self.last_output = time.monotonic()
        self.counts: dict[str, int] = {}
        self._subs: dict[str, Any] = {}
        #: what each watched topic's one subscription hands its messages to (poses, counts, commands)
        self._handlers: dict[str, list[Callable[[Any], None]]] = {}
        self._counted: set[str] = set()            # topics with a counting handler of their own
        self._pubs: dict[str, Any] = {}
        self._clients: dict[tuple[str, str], Any] = {}
        #: each output log, opened once and read on from where the last read ended (_tail_outputs)
        self._tail_files: dict[Path, BinaryIO] = {}
        self._tail_rest: dict[Path, bytes] = {}
        self._exited: set[str] = set()
        self.lines: dict[str, list[str]] = {}      # process -> output lines seen so far
        self._watch: set[str] = set()              # topics to count once they appear
        self.watchdog: Any = None                  # a RateWatchdog on simulated time (run.py)
        self._hold_client: Any = None              # the simulator's hold_turtles (placements)
        self._held_since: float | None = None
        self.turtle_hold_requests = 0
        self.commands: dict[str, list] = {}       # topic -> [count, last (linear.x, linear.y, angular.z)]

    def _watch_outputs(self, qos_profile_cls: Any, clock_cls: Any, clock_type: Any, time_scale: float) -> None:
        """Subscribe /rosout and start the tail timer: they turn student output into counts and bag lines."""
        self.node.create_subscription(self._import("rcl_interfaces/msg/Log"), "/rosout",
                                      self._on_rosout, qos_profile_cls(depth=1000))
        if time_scale > 1:   # output lines reach the bag as often, in scenario time, as at 1x
            self.node.create_timer(0.05 / time_scale, self._tail_outputs,
                                   clock=clock_cls(clock_type=clock_type.STEADY_TIME))
        else:
            self.node.create_timer(0.05, self._tail_outputs)

    def _start_spinning(self) -> None:
        """Start the executor's spin thread last, once every entity of the driver's node exists."""
        self.executor = make_executor(self.ctx)   # EventsExecutor: the CPU goes to student nodes
        self.executor.add_node(self.node)
        self._spin_lock = threading.Lock()
        self._stopping = False
        self._paused_waiters = 0
        self._spin = threading.Thread(target=self._spin_forever, name="driver-spin", daemon=True)
        self._spin.start()

    # -- plumbing ------------------------------------------------------------------------
    def _import(self, name: str):
        return import_type(name)

    @contextlib.contextmanager
    def executor_paused(self) -> Iterator[None]:
        """Hold the executor between two of its spins.

        rclpy's ActionClient (7.1.x, Jazzy) registers the future of ``send_goal_async`` and
        ``cancel_goal_async`` only after the request is sent; when the executor, spinning in
        another thread, takes the response before that, the response is dropped and the future
        never completes (ros2/rclpy#1123). That is how a correct server's accepted goal showed up
        as "no response from the server" under load. Sending with the executor paused closes
        the window.
        """
        self._paused_waiters += 1
        try:
            with self._spin_lock:
                yield
        finally:
            self._paused_waiters -= 1

    def _spin_forever(self) -> None:
        while self.rclpy.ok(context=self.ctx):
            if self._paused_waiters:
                time.sleep(0.001)          # let a caller of executor_paused() in
            try:
                with self._spin_lock:
                    if self._stopping:
                        break
                    self.executor.spin_once(timeout_sec=0.05)
            except Exception:  # noqa: BLE001 - shutdown races end the loop
                if not self.rclpy.ok(context=self.ctx):
                    break

    def event(self, event: Event, **fields: Any) -> None:
        """Emit one event: its model (grader.contracts.events) is built from the fields as JSON
        has them, so an undeclared field fails here, in the scenario child, not in a reader."""
        plain = json.loads(json.dumps(fields, default=str))
        record = build_event(event, time.time(), plain)
        with self.lock:
            self.events.append(record)
        self._emit(self.events_pub, EVENTS_TOPIC, json.dumps({"event": str(event), "wall": record.wall, **plain}))

    def _emit(self, pub: Any, topic: str, text: str) -> None:
        msg = self.String(data=text)
        if self.sink is not None:     # the bag only: one serialization, no DDS round trip per line
            self.sink(topic, self._serialize(msg))
        else:
            pub.publish(msg)

    def _on_rosout(self, msg: Any) -> None:
        if not msg.name.startswith(GRADER_NODE_PREFIX) and msg.name != self.sim_node:
            self.last_output = time.monotonic()
            self.counts["/rosout:student"] = self.counts.get("/rosout:student", 0) + 1

    def output_count(self) -> int:
        """Student output so far: /rosout messages plus stdout lines (for pacing replays)."""
        return self.counts.get("/rosout:student", 0) + self.counts.get("stdout:student", 0)

    def _tail_outputs(self) -> None:
        """Publish new student output lines; notice process exits; subscribe watched topics.

        Each log is opened once and read on from where the previous read ended (the logs only
        grow: a process started again under the same name truncates the same file, which a held
        descriptor reads exactly as a new open that seeks to the old offset did). Opening, seeking
        and closing each log on every call cost 27 us per pass over two processes' four logs,
        2.2 ms of CPU per second at ``--time-scale 4`` (the timer runs every 12.5 ms there);
        reading held descriptors 4.4 us, 0.35 ms per second (benchmarks/README.md, "The
        scenario's own processes")."""
        for topic in list(self._watch):
            self.count_messages(topic, None, wait_s=0.0)
        for name, proc in list(self.processes.items()):
            for stream, path in (("stdout", proc.stdout_path), ("stderr", proc.stderr_path)):
                f = self._tail_files.get(path)
                if f is None:
                    try:
                        f = self._tail_files[path] = open(path, "rb")     # held open until shutdown
                    except FileNotFoundError:
                        continue
                chunk = f.read()
                if not chunk:
                    continue
                data = self._tail_rest.pop(path, b"") + chunk
                *lines, rest = data.split(b"\n")
                if rest:
                    self._tail_rest[path] = rest
                for raw in lines:
                    line = raw.decode(errors="replace").rstrip("\r")
                    self.lines.setdefault(name, []).append(line)
                    self._emit(self.stdout_pub, STDOUT_TOPIC,
                               json.dumps({"process": name, "stream": stream, "line": line}))
                    if stream == "stdout" or not line.startswith("["):
                        self.last_output = time.monotonic()
                        self.counts["stdout:student"] = self.counts.get("stdout:student", 0) + 1
            if name not in self._exited and proc.returncode is not None:
                self._exited.add(name)
                self.event(Event.PROCESS_EXIT, process=name, returncode=proc.returncode,
                           stopped_by_grader=proc.stopped_by_grader, timed_out=proc.timed_out)

    def flush_outputs(self) -> None:
        self._tail_outputs()
        for path, rest in list(self._tail_rest.items()):
            name = next((n for n, p in self.processes.items() if path in (p.stdout_path, p.stderr_path)), "?")
            stream = "stdout" if path.name.endswith("stdout.log") else "stderr"
            self._emit(self.stdout_pub, STDOUT_TOPIC,
                       json.dumps({"process": name, "stream": stream, "line": rest.decode(errors="replace")}))
            del self._tail_rest[path]

    def service_client(self, cls: Any, name: str) -> Any:
        """The driver's client of service ``name`` (one per service and type, made on first use):
        a new client per call costs a discovery round each time (``wait_for_service`` then sleeps
        0.25 s of wall time), and in lockstep a request the server has not matched yet waits for
        DDS to send it again, on the wall clock."""
        key = (name, f"{cls.__module__}.{cls.__qualname__}")
        if key not in self._clients:
            self._clients[key] = self.node.create_client(cls, name)
        return self._clients[key]

    def publisher(self, topic: str, type_name: str):
        if topic not in self._pubs:
            self._pubs[topic] = self.node.create_publisher(self._import(type_name), topic, 10)
        return self._pubs[topic]

    # -- holding the turtles still (grader.sim: ~/hold_turtles) --------------------------------
    def prepare_turtle_hold(self) -> None:
        """Create the client of the simulator's ``hold_turtles`` service before the scenario
        starts (every scenario with a simulator: placements, and the hold at its end), so it is
        discovered in time."""
        if self._hold_client is None:
            from std_srvs.srv import SetBool  # noqa: PLC0415 - std_srvs: ROS, imported where it is used, so this module loads without a ROS install

            self._hold_client = self.node.create_client(SetBool, f"/{self.sim_node}/{HOLD_TURTLES_SERVICE}")

    def hold_turtles(self, on: bool, step: str | None = None, wait_s: float = 5.0) -> bool:
        """Hold every turtle still (``on``) or let them move again; True when the simulator
        answered. Counted in ``turtle_hold_requests`` (the simulator counts what it serves)."""
        from std_srvs.srv import SetBool  # noqa: PLC0415 - std_srvs: ROS, imported where it is used, so this module loads without a ROS install

        self.prepare_turtle_hold()
        ok = False
        if self._hold_client.wait_for_service(timeout_sec=wait_s):
            self.turtle_hold_requests += 1
            with self.executor_paused():
                future = self._hold_client.call_async(SetBool.Request(data=on))
            end = time.monotonic() + wait_s
            while not future.done() and time.monotonic() < end:
                time.sleep(0.001)
            ok = future.done() and future.result() is not None
        if on:
            self._held_since = time.monotonic()
            self.event(Event.TURTLES_HELD, step=step, ok=ok)
        else:
            held_s = time.monotonic() - self._held_since if self._held_since is not None else None
            self._held_since = None
            self.event(Event.TURTLES_RELEASED, step=step, ok=ok,
                       held_s=None if held_s is None else round(held_s, 3))
        return ok

    def wait_until(self, predicate: Callable[[], bool], timeout_s: float, poll: float = 0.02,
                   *, wall: bool = False, react: bool = False) -> bool:
        """Poll until ``predicate()`` or ``timeout_s`` of scenario time (``wall``: wall seconds;
        ``react``: a wall wait that ticks in lockstep, see ScenarioClock.wait_until)."""
        return self.clock.wait_until(predicate, timeout_s, poll, wall=wall, react=react)

    def shutdown(self) -> None:
        try:
            self.flush_outputs()
            time.sleep(0.2)
        finally:
            # the spin thread ends between two spins before the node goes away: destroying it
            # under a running spin crashed a scenario process (SIGSEGV in destroy_node, once, while
            # the fixture bags were recorded again on a loaded machine)
            with self._spin_lock:
                self._stopping = True
            self._spin.join(timeout=2.0)
            self.executor.shutdown(timeout_sec=1.0)
            if self.clock.stepper is not None:
                self.clock.stepper.close()
            self.node.destroy_node()
            self.rclpy.try_shutdown(context=self.ctx)
            files, self._tail_files = self._tail_files, {}
            for f in files.values():
                f.close()
