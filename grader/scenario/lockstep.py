"""Lockstep simulated time: the driver advances the clock, one tick once everybody is done.

A scenario marked ``lockstep: true`` runs every node on simulated time that only the driver
moves (the simulator's ``--lockstep``, :mod:`grader.sim.clock`). A tick is two calls: time
advances and goes out on ``/clock`` (the nodes' timers fire), then once every process is quiet
(:mod:`grader.scenario.quiescence`) the world steps with the commands those timers sent and
publishes its poses, and once the processes are quiet again the next tick may follow. Between
ticks the driver checks its step's condition. So a node paced by ROS time receives the same
messages at the same simulated times in every run and answers them the same way, however loaded
the machine is: a chaotic controller (a missing angle wrap, a wall it touches) draws the same
path every time, where on the wall clock a command one tick late sends it elsewhere
(``benchmarks/bench_flake.py``, issue 22).

The cost is the wall time of the calls and the quiet checks, and their CPU. The two calls go
over a socket of their own to the simulator (:mod:`grader.sim.stepchannel`), not through its DDS
services: on Lab 3's ``ex3_action`` (2,117 ticks, the same poses byte for byte) the stepping
thread's CPU in them fell from 1.3-1.9 s to 0.10-0.26 s, their wall time (``call_wall_s``) from
4.4-7.2 s to 2.5-3.9 s at load 1.5-6 (7.7 s in one run at 5.9), and the scenario's CPU (its
process and its children) from 13.3-19.8 s to 11.0-13.7 s at load 1.5-5; at load 5-10 the load's
noise hides the difference (benchmarks/README.md, "A cheaper lockstep tick"). What the stepping thread
spends now is the quiet checks (``tick_cpu_s`` less ``call_cpu_s`` in the record: 3.7-5.6 s), a
``stat`` and two ``schedstat`` reads per waited thread and pass.

Measured earlier on this project's 2-core
machine: a no-wrap chaser's 400 ticks took 13.5 ms of wall time each with the test suite running
beside it (4 ms in the two calls, 9.5 ms waiting for quiet), the same 400 ticks hashed alike in
every run, while two runs on the free-running clock differed (416 and 419 poses, other paths);
wall_pen's 62 s drive (4033 ticks) took 80 s alone, 83-111 s in a batch at ``--jobs 2``, and
~440 s with three batches side by side (load 15), where the free clock takes 62 s whatever the
load and the grade follows the load instead.

Not quiet within ``QUIET_WAIT_S`` of wall time in which the waited threads also ran half that
on a CPU (a node busy-looping; :meth:`Quiescence.wait`): the tick goes on and is counted in
``quiet_timeouts``; a run with any is not guaranteed to repeat, and after
``MAX_QUIET_TIMEOUTS`` of them the run ends (:class:`LockstepFailed`) and the scenario runs again
on the wall clock, the record saying why (:func:`grader.grading.timescale.run_at_scale`).
"""

from __future__ import annotations

import heapq
import itertools
import os
import socket
import threading
import time
from collections import Counter
from typing import Any, Callable

from grader.scenario.cpuwait import TreeCpu
from grader.scenario.quiescence import Quiescence
from grader.scenario.simtime import LOCKSTEP_WALL_FACTOR
from grader.sim.clock import HOLD_SERVICE, STEP_CLOCK_SERVICE, STEP_WORLD_SERVICE, TICK_NS, hold_point
from grader.sim.stepchannel import STEP_CLOCK, STEP_WORLD, StepChannelError, StepClient

#: wall seconds a tick waits for every process to be quiet before it goes on regardless
QUIET_WAIT_S = 2.0
#: wall seconds for the simulator's answer to a step
STEP_WAIT_S = 10.0
#: wall seconds for one answer to a probe before it is asked again (:meth:`Stepper.ready`)
PROBE_WAIT_S = 1.0
#: ticks that went on without quiet before the lockstep run is given up
MAX_QUIET_TIMEOUTS = 5
#: a lockstep run is given up, and runs on the wall clock, once its ticks take more than
#: ``MAX_SLOWDOWN`` times their simulated time of wall time (the factor of a wait's own wall limit,
#: ``LOCKSTEP_WALL_FACTOR``: slower, its step would be cut short anyway, and a cut run is not
#: exact; at 8, that node's run was given up at its tick 3968 of 4033, at 8.2 times, two gradings
#: side by side, where it would have ended exact) *and* its processes (the simulator's
#: and the students', not the driver's) used more than ``MAX_CPU_PER_SIM_S`` CPU seconds per
#: simulated second since its first tick, from ``SLOW_AFTER_TICKS`` on: slow, and slow because
#: of its own nodes, not the machine's load. A node that keeps waking the others (wall_pen's
#: chapter.scale_constant makes a new client on every pose) made ticks take 16-24 times their
#: simulated time at load 9-26 and used 2.4-2.8 CPU s per simulated second there (0.53 with its
#: ticks at 7.3 times beside six CPU burners, where it stayed in lockstep to the end); over 229
#: lockstep runs of that class benchmark (start-up included) every other node used 0.2-0.64 while
#: its ticks took 2.5-7.8 times their simulated time with the load. Neither alone can decide:
#: the wall time follows the load (with a load allowance instead of the CPU, that node was given
#: up after ~600 s in some runs and cut by the step's wall limit in others), and so does the CPU
#: of an executor that spins (chase's correct ``alt_multithreaded``, rclpy's busy loop under
#: ``/clock`` at times: 0.4 at load 9-26, 1.1 in one fixture batch and 0.09 in the next, with its
#: ticks fast in both).
MAX_SLOWDOWN = LOCKSTEP_WALL_FACTOR
MAX_CPU_PER_SIM_S = 1.5
SLOW_AFTER_TICKS = 250
#: ticks between two readings of the processes' CPU (62: about one simulated second)
CPU_CHECK_TICKS = 62


class LockstepFailed(RuntimeError):
    """The lockstep run cannot go on as lockstep (the record's ``lockstep.fallback``)."""


class LockstepError(LockstepFailed):
    """The simulator did not answer a step: the clock cannot advance."""


class CpuBudget:
    """The waited processes' CPU seconds per simulated second, from :meth:`start` on; over
    :data:`MAX_CPU_PER_SIM_S`, :meth:`check` gives the lockstep run up (the stepper asks only
    once its ticks are slow)."""

    def __init__(self, pids: Callable[[], list[int]]) -> None:
        self._cpu = TreeCpu(pids)
        self._from_ns: int | None = None

    def start(self, now_ns: int) -> None:
        self._cpu.mark()
        self._from_ns = now_ns

    def rate(self, now_ns: int) -> float | None:
        if self._from_ns is None or now_ns <= self._from_ns:
            return None
        return self._cpu.used_s() / ((now_ns - self._from_ns) / 1e9)

    def check(self, now_ns: int, slow: str = "") -> None:
        """``slow``: what else was found, the start of the reason given."""
        rate = self.rate(now_ns)
        if rate is not None and rate > MAX_CPU_PER_SIM_S:
            raise LockstepFailed(f"{slow}its processes used {rate:.2f} CPU seconds per simulated second "
                                 f"(over {MAX_CPU_PER_SIM_S:g}: a process kept waking up the others)")


class Stepper:
    """Advances the simulator's lockstep clock, over its step channel, or from a node of its own
    in the driver's context.

    The node is spun only by the thread that steps, while it waits for the simulator's answer:
    through the driver's executor (spinning in another thread with a 50 ms timeout, and paused
    for each request) a tick of wall_pen's drive took 106 ms of wall time; spun here, 20 ms (on
    the channel, nothing spins: one ``send``, one blocking ``recv``).
    ``pids()``: the processes to wait for (the simulator's and the students'); the driver's own
    process is always waited for too, except the calling thread and ``exclude()`` (the
    recorder's writing thread, whose work changes nothing anyone receives): its subscriptions
    must have taken what a tick sent before a condition is checked. ``channel``: the socket the
    ticks' two calls go over (:mod:`grader.sim.stepchannel`); without one, the simulator's DDS
    services. The probes before the first tick (:meth:`ready`) and the hold service's questions
    always go over DDS: the probes wait for discovery, as they did before the channel.
    """

    def __init__(self, context: Any, sim_node: str, pids: Callable[[], list[int]],
                 exclude: Callable[[], set[int]] = set, channel: socket.socket | None = None) -> None:
        import rclpy  # noqa: PLC0415 - rclpy: ROS, imported where it is used (this module loads in processes that never use it)
        from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415 - rclpy.executors: ROS, imported where it is used (this module loads in processes that never use it)
        from std_srvs.srv import SetBool, Trigger  # noqa: PLC0415 - std_srvs.srv: ROS, imported where it is used (this module loads in processes that never use it)

        node = rclpy.create_node("grader_lockstep", context=context, start_parameter_services=False)
        self.node = node
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(node)
        self._hold = node.create_client(SetBool, f"/{sim_node}/{HOLD_SERVICE}")
        self._clock = node.create_client(SetBool, f"/{sim_node}/{STEP_CLOCK_SERVICE}")
        self._world = node.create_client(Trigger, f"/{sim_node}/{STEP_WORLD_SERVICE}")
        self._request = Trigger.Request()
        self._step = SetBool.Request(data=True)
        self._channel = None if channel is None else StepClient(channel)
        self._pids = pids
        self._exclude = exclude
        self.now_ns = 0
        self.ticks = 0
        #: one thread ticks at a time (a step's wait and a stdin line's delay may both wait on
        #: the clock: each ticking on its own, two waits ran the clock twice as fast and spun
        #: this node's executor from two threads, "generator already executing")
        self._ticking = threading.Lock()
        self._ticked = threading.Condition()
        self.tick_wall_s = 0.0          # wall time spent in ticks
        self.call_wall_s = 0.0          # ... of which waiting for the simulator's two answers
        #: CPU of this (the stepping) thread in ticks, and of it in the two calls (the rest: the
        #: quiet checks and the actions due)
        self.tick_cpu_s = 0.0
        self.call_cpu_s = 0.0
        #: waits that ended by their wall-time limit before their simulated time (ScenarioClock)
        self.wall_cuts = 0
        #: (time, order, action): what :meth:`schedule` asked to run at a tick boundary
        self._due: list[tuple[int, int, Callable[[], None]]] = []
        self._order = itertools.count()
        #: the waits after ``/clock`` (False) and after the world's step (True, this process too)
        self.quiet = {False: Quiescence([]), True: Quiescence([])}
        #: the waited processes' CPU from the first tick on (:data:`MAX_CPU_PER_SIM_S`)
        self.cpu = CpuBudget(pids)

    def close(self) -> None:
        for quiet in self.quiet.values():
            quiet.close()
        if self._channel is not None:
            self._channel.close()
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()

    def ready(self, timeout_s: float) -> bool:
        """Both step services answer: each is probed until an answer arrives. Found is not
        enough: while discovery has not matched both ends of a service's two topics, a request
        or its reply can be lost, and a lost step cannot be asked again (it may have ticked).
        In CI, three CPU burners beside a batch, the first tick of a chaotic controller's run
        went unanswered for 10 s and the run fell back to the wall clock."""
        from std_srvs.srv import SetBool  # noqa: PLC0415 - std_srvs.srv: ROS, imported where it is used (this module loads in processes that never use it)

        end = time.monotonic() + timeout_s
        for client, probe in ((self._clock, SetBool.Request(data=False)), (self._world, None)):
            if not client.wait_for_service(timeout_sec=max(0.0, end - time.monotonic())):
                return False
            while True:
                try:
                    self._call(client, probe, wait_s=PROBE_WAIT_S)
                    break
                except LockstepError:
                    if time.monotonic() >= end:
                        return False
        return True

    def _call(self, client: Any, request: Any = None, wait_s: float = STEP_WAIT_S) -> str:
        future = client.call_async(self._request if request is None else request)
        end = time.monotonic() + wait_s
        while not future.done() and time.monotonic() < end:
            self._executor.spin_once(timeout_sec=0.05)
        if not future.done() or future.result() is None:
            client.remove_pending_request(future)
            raise LockstepError(f"the simulator did not answer {client.srv_name} within {wait_s:g} s")
        return str(future.result().message)

    def _step_clock(self) -> int:
        """A tick of time on ``/clock``; the new time."""
        if self._channel is None:
            return int(self._call(self._clock, self._step).split()[0])
        try:
            return int(self._channel.call(STEP_CLOCK, STEP_WAIT_S).split()[0])
        except StepChannelError as exc:
            raise LockstepError(str(exc)) from exc

    def _step_world(self) -> None:
        if self._channel is None:
            self._call(self._world)
            return
        try:
            self._channel.call(STEP_WORLD, STEP_WAIT_S)
        except StepChannelError as exc:
            raise LockstepError(str(exc)) from exc

    def _settle(self, own: bool) -> None:
        """Wait until the processes are quiet; ``own``: this process too (its subscriptions),
        which only the world's step concerns (nobody here answers ``/clock``)."""
        quiet = self.quiet[own]
        roots = [*([os.getpid()] if own else []), *self._pids()]
        if roots != quiet.roots:
            quiet.roots = roots
            quiet.refresh()
        quiet.exclude = {threading.get_native_id(), *self._exclude()}
        if not quiet.wait(QUIET_WAIT_S) and self.quiet_timeouts > MAX_QUIET_TIMEOUTS:
            raise LockstepFailed(f"a process did not come to rest within {QUIET_WAIT_S:g} s after "
                                 f"{self.quiet_timeouts} ticks (busy without pause): lockstep needs every "
                                 "node to wait for its next message or timer")

    def clock_readers(self) -> int | None:
        """How many ``/clock`` readers the simulator has matched (a starting node's must be, before
        the next tick), from its ``hold_clock`` service (a release: nothing is held in lockstep)."""
        from std_srvs.srv import SetBool  # noqa: PLC0415 - std_srvs.srv: ROS, imported where it is used (this module loads in processes that never use it)

        try:
            return int(self._call(self._hold, SetBool.Request(data=False)).split()[1])
        except (LockstepError, IndexError, ValueError):
            return None

    def tick(self) -> int:
        """One tick: time on ``/clock``, quiet, the world's step, quiet. Returns the new time."""
        t0, c0 = time.monotonic(), time.thread_time()
        self.now_ns = self._step_clock()
        t1, c1 = time.monotonic(), time.thread_time()
        self._settle(own=False)
        t2, c2 = time.monotonic(), time.thread_time()
        self._step_world()
        t3, c3 = time.monotonic(), time.thread_time()
        self.call_wall_s += (t1 - t0) + (t3 - t2)
        self._settle(own=True)
        if self._run_due():
            self._settle(own=True)
        self.ticks += 1
        self.tick_wall_s += time.monotonic() - t0
        self.tick_cpu_s += time.thread_time() - c0
        self.call_cpu_s += (c1 - c0) + (c3 - c2)
        if self.ticks == 1:
            self.cpu.start(self.now_ns)
        elif self.ticks >= SLOW_AFTER_TICKS and self.ticks % CPU_CHECK_TICKS == 0:
            slowdown = self.tick_wall_s / (self.ticks * TICK_NS / 1e9)
            if slowdown > MAX_SLOWDOWN:
                self.cpu.check(self.now_ns, f"its ticks took {slowdown:.1f} times their simulated time "
                                            f"(over {MAX_SLOWDOWN:g}) and ")
        return self.now_ns

    def schedule(self, t_ns: int, action: Callable[[], None]) -> None:
        """Run ``action`` in the thread that ticks, after the first tick that reaches ``t_ns``
        (the world stepped and every process quiet), and let it be handled before the next
        tick. A scripted stdin line is typed so: from a thread of its own it reached the node
        some wall time after its tick, while the step's wait ticked on (Lab 3's client typed its
        goal 1.95 s into its step in one run, 4.05 s in another). Actions must not block."""
        with self._ticked:
            heapq.heappush(self._due, (t_ns, next(self._order), action))

    def _run_due(self) -> bool:
        ran = False
        while True:
            with self._ticked:
                if not self._due or self._due[0][0] > self.now_ns:
                    return ran
                action = heapq.heappop(self._due)[2]
            ran = True
            try:
                action()
            except Exception:  # noqa: BLE001 - a scheduled action (a line typed) never stops the clock
                pass

    def advance(self) -> None:
        """Tick, or, while another thread is ticking, wait (asleep, so the quiet checks see it
        rest) until its tick is done: however many threads wait on the clock, it advances one
        tick at a time and each sees every tick."""
        with self._ticked:
            seen = self.ticks
        if self._ticking.acquire(blocking=False):
            try:
                self.tick()
            finally:
                self._ticking.release()
                with self._ticked:
                    self._ticked.notify_all()
            return
        with self._ticked:
            self._ticked.wait_for(lambda: self.ticks != seen or not self._ticking.locked(),
                                  timeout=STEP_WAIT_S)

    def settle(self) -> None:
        """Wait, without a tick, until every process has handled what was sent since the last
        tick (a goal, a service request, a teleport): a wait checks its condition only then, so
        whether the answer is seen before the next tick never depends on the wall time it took.
        Without it, the tick at which an action server's acceptance or a teleport's answer was
        seen varied, and Lab 3's second goal was handed over 0-4 ticks later from run to run;
        with it (and one driver client per service), two runs of the reference drew the same
        poses at the same ticks (benchmarks/README.md). While another thread ticks, that tick
        settles."""
        if self._ticking.acquire(blocking=False):
            try:
                self._settle(own=True)
            finally:
                self._ticking.release()

    def to_grid(self) -> None:
        """Advance to the next hold point (one tick after a multiple of 2 s, as the free clock's
        holds: a node started there keeps its timers' phase)."""
        target = hold_point(self.now_ns)
        while self.now_ns < target:
            self.advance()

    @property
    def quiet_timeouts(self) -> int:
        return sum(q.timeouts for q in self.quiet.values())

    def summary(self) -> dict[str, Any]:
        both = self.quiet.values()
        blockers = sum((q.blockers for q in both), Counter())
        return {"ticks": self.ticks, "sim_s": round(self.now_ns / 1e9, 3),
                "channel": "dds" if self._channel is None else "socket",
                "tick_wall_s": round(self.tick_wall_s, 3), "call_wall_s": round(self.call_wall_s, 3),
                "tick_cpu_s": round(self.tick_cpu_s, 3), "call_cpu_s": round(self.call_cpu_s, 3),
                "cpu_per_sim_s": None if (rate := self.cpu.rate(self.now_ns)) is None else round(rate, 3),
                "quiet_waits": sum(q.waits for q in both), "quiet_scans": sum(q.scans for q in both),
                "quiet_timeouts": self.quiet_timeouts, "wall_cuts": self.wall_cuts,
                "quiet_starved_s": round(max(q.starved_s for q in both), 3), "tick_ns": TICK_NS,
                "processes": self.quiet[True].processes,
                "blockers": dict(blockers.most_common(5))}
