"""The time a scenario's steps are measured in: the wall clock at 1x, simulated time when faster.

At 1x (the default) this is ``time.monotonic()``, exactly as before time scales existed. With a
time scale the simulator (or ``grader_clock``) owns ``/clock`` (:mod:`grader.sim.clock`) and the
driver's node runs with ``use_sim_time``; then *scenario time* is simulated time plus the wall
time during which the clock was held for a student process to start. That sum is what a 1x run
measures for the same scenario (at 1x a process's start-up costs wall time too), so a step's
``timeout: 10`` means the same thing at every speed, and a starting node never has to come up
in a quarter of the time.

Lockstep (a scenario's ``lockstep: true``, :mod:`grader.scenario.lockstep`): scenario time is
simulated time alone, and it only advances when a wait of this clock steps it, one tick after
another with the step's condition checked between ticks. A process starting costs no simulated
time: nothing ticks while it comes up. Waits on work rather than time (``wall=True``: discovery)
do not tick; waits for a node's answer to what it was sent (``react=True``) tick, as it needs its
timers to answer.

Every wait also ends after its timeout in *wall* seconds: the scenario clock normally runs at
least as fast as the wall clock, so that bound only matters when the clock stalls (a dead
simulator) and a step would otherwise wait forever.
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Any, Callable, Iterator

from grader.sim.clock import HOLD_SERVICE, STOP_SERVICE

#: wall seconds to wait for the clock owner's hold service and for the clock to reach the hold
HOLD_WAIT_S = 10.0
#: lockstep: a wait of T seconds of simulated time ends after T * this + LOCKSTEP_WALL_EXTRA_S
#: of wall time at the latest (a tick takes 10-20 ms of wall time on a busy 2-core machine)
LOCKSTEP_WALL_FACTOR = 10.0
LOCKSTEP_WALL_EXTRA_S = 10.0


class ScenarioClock:
    """``now()``, ``sleep()``, ``wait_until()`` and ``held()`` in scenario time.

    ``node``: the driver's rclpy node (created with ``use_sim_time``) when ``time_scale`` > 1;
    ``hold_service``: the clock owner's ``hold_clock`` service (``std_srvs/srv/SetBool``);
    ``paused``: a context manager that holds the node's executor while a request is sent (an
    rclpy client registers its future only after sending: see ``Driver.executor_paused``).
    """

    def __init__(self, time_scale: float = 1.0, node: Any = None, hold_service: str | None = None,
                 paused: Callable[[], Any] | None = None, stepper: Any = None) -> None:
        self.time_scale = float(time_scale)
        #: lockstep: the :class:`grader.scenario.lockstep.Stepper` that advances the clock
        self.stepper = stepper
        self.lockstep = stepper is not None
        self.simulated = self.time_scale > 1.0 or self.lockstep
        self.node = node
        self.hold_service = hold_service
        self.held_s = 0.0                       # wall seconds the clock was held, finished holds
        self._held_since: float | None = None   # monotonic time the current hold froze the clock
        self._holds = 0
        self.requests = 0                       # hold/stop requests made to the clock owner
        self._lock = threading.Lock()
        self._paused = paused or contextlib.nullcontext
        self._client: Any = None
        self._stop_client: Any = None
        if self.simulated and hold_service is not None and not self.lockstep:
            from std_srvs.srv import SetBool, Trigger  # noqa: PLC0415 - std_srvs.srv: ROS, imported where it is used (this module loads in processes that never use it)

            self._client = node.create_client(SetBool, hold_service)
            self._stop_client = node.create_client(Trigger, hold_service.replace(HOLD_SERVICE, STOP_SERVICE))

    # -- reading the time -------------------------------------------------------------------
    def sim_s(self) -> float:
        """Simulated seconds (0 until the first ``/clock``); the wall clock at 1x."""
        if not self.simulated:
            return time.monotonic()
        if self.stepper is not None:
            return self.stepper.now_ns / 1e9
        return self.node.get_clock().now().nanoseconds / 1e9

    def now(self) -> float:
        """Scenario seconds: at 1x the wall clock less the time held (student processes
        starting); scaled, simulated time plus the wall time held."""
        if self.lockstep:
            return self.sim_s()
        since = self._held_since
        if not self.simulated:
            return time.monotonic() - self.held_s - (time.monotonic() - since if since is not None else 0.0)
        return self.sim_s() + self.held_s + (time.monotonic() - since if since is not None else 0.0)

    def _poll(self, poll: float) -> float:
        """Wall seconds between checks: the 1x poll in scenario time (at least 1 ms)."""
        return max(0.001, poll / self.time_scale)

    # -- waiting ------------------------------------------------------------------------------
    def wait_until(self, predicate: Callable[[], bool], timeout_s: float, poll: float = 0.02,
                   *, wall: bool = False, react: bool = False) -> bool:
        """Poll ``predicate`` until it holds or ``timeout_s`` pass (scenario time, and never
        longer than ``timeout_s`` wall seconds). ``wall``: wall seconds only, for waits on
        work rather than on time (discovery, a student's processing of inputs); ``react``: a
        wall wait for a node's answer, which in lockstep needs ticks (its timers) to come."""
        if self.stepper is not None and (react or not wall) and not self._holds:
            return self._step_until(predicate, timeout_s)
        wall_end = time.monotonic() + timeout_s
        if wall or not self.simulated:
            while time.monotonic() < wall_end:
                if predicate():
                    return True
                time.sleep(poll)
            return predicate()
        end = self.now() + timeout_s
        step = self._poll(poll)
        while self.now() < end and time.monotonic() < wall_end:
            if predicate():
                return True
            time.sleep(step)
        return predicate()

    def _step_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Lockstep: tick until ``predicate`` holds or ``timeout_s`` of simulated time passed."""
        end_ns = self.stepper.now_ns + round(timeout_s * 1e9)
        wall_end = time.monotonic() + timeout_s * LOCKSTEP_WALL_FACTOR + LOCKSTEP_WALL_EXTRA_S
        self.stepper.settle()             # what was just sent is handled before the first check
        while not predicate():
            if self.stepper.now_ns >= end_ns:
                return predicate()
            if time.monotonic() >= wall_end:
                # cut short by the wall: how long the step lasted followed the machine's load
                # (Lab 3's last step: 10 s of simulated time in one run, 9.39 s in another)
                self.stepper.wall_cuts += 1
                return predicate()
            self.stepper.advance()
        return True

    def sleep(self, seconds: float, stop: Callable[[], bool] | None = None) -> bool:
        """Sleep ``seconds`` of scenario time; True when ``stop()`` became true first."""
        if seconds <= 0:
            return bool(stop and stop())
        if not self.simulated and stop is None:
            time.sleep(seconds)
            return False
        return self.wait_until(stop or (lambda: False), seconds, poll=min(0.02, seconds))

    def sleep_until(self, t: float) -> None:
        """Sleep until scenario time ``t`` (returns at once when it has passed)."""
        if not self.simulated:
            delay = t - self.now()
            if delay > 0:
                time.sleep(delay)
            return
        self.wait_until(lambda: False, t - self.now(), poll=0.002)

    def wait_for_clock(self, timeout_s: float) -> bool:
        """Wait (wall seconds) for the first ``/clock``: before it ``now()`` reads zero."""
        if not self.simulated:
            return True
        if self.stepper is not None:      # the first tick is the first /clock
            if not self.stepper.ready(timeout_s):
                return False
            self.stepper.advance()
            return True
        return self.wait_until(lambda: self.sim_s() > 0, timeout_s, poll=0.01, wall=True)

    # -- holding the clock while student processes start ---------------------------------------
    @contextlib.contextmanager
    def held(self) -> Iterator[None]:
        """Hold the clock for the block (nested holds share one). The clock holds at its next
        grid point (:func:`grader.sim.clock.hold_point`: a starting node's timers keep their
        phase). At 1x nothing stops, but scenario time does not count the block either: a
        step's limit never pays for a process's start-up, which a loaded machine stretches
        (measured at load 29: the Lab 3 client took 9.5 s to come up, its step allowed 10)."""
        if not self.simulated:
            with self._lock:
                self._holds += 1
                if self._holds == 1:
                    self._held_since = time.monotonic()
            try:
                yield
            finally:
                with self._lock:
                    self._holds -= 1
                    if self._holds == 0 and self._held_since is not None:
                        self.held_s += time.monotonic() - self._held_since
                        self._held_since = None
            return
        if self.hold_service is None and not self.lockstep:
            yield
            return
        if self.lockstep:                 # nothing ticks in the block; it starts on the grid
            with self._lock:
                self._holds += 1
                if self._holds == 1:
                    self.stepper.to_grid()
            try:
                yield
            finally:
                with self._lock:
                    self._holds -= 1
            return
        with self._lock:
            self._holds += 1
            if self._holds == 1:
                self._hold()
        try:
            yield
        finally:
            with self._lock:
                self._holds -= 1
                if self._holds == 0:
                    self._release()

    def stop(self) -> bool:
        """Stop the clock for good (the scenario ended; a no-op at 1x). False when the clock
        owner served more hold requests than this driver made: someone else held the clock."""
        if not self.simulated or self.hold_service is None or self.lockstep:
            return True
        from std_srvs.srv import Trigger  # noqa: PLC0415 - std_srvs.srv: ROS, imported where it is used (this module loads in processes that never use it)

        reply = self._request(self._stop_client, Trigger.Request())
        try:
            return int(reply.split()[1]) <= self.requests  # type: ignore[union-attr]  # (None: caught)
        except (AttributeError, IndexError, ValueError):
            return True

    def _request(self, client: Any, request: Any) -> str | None:
        """Send ``request`` to one of the clock owner's services (counted in ``requests``) and
        wait (wall time) for its reply's ``message``; None without a service or a reply."""
        if not client.wait_for_service(timeout_sec=HOLD_WAIT_S):
            return None
        self.requests += 1
        with self._paused():
            future = client.call_async(request)
        end = time.monotonic() + HOLD_WAIT_S
        while not future.done() and time.monotonic() < end:
            time.sleep(0.002)
        return future.result().message if future.done() and future.result() is not None else None

    def _call(self, on: bool) -> tuple[int, int] | None:
        """Ask the clock owner to hold (or run); its reply: (time in ns, matched readers)."""
        from std_srvs.srv import SetBool  # noqa: PLC0415 - std_srvs.srv: ROS, imported where it is used (this module loads in processes that never use it)

        reply = self._request(self._client, SetBool.Request(data=on))
        try:
            at, readers = reply.split()  # type: ignore[union-attr]  # (None: caught)
            return int(at), int(readers)
        except (AttributeError, ValueError):
            return None

    def clock_readers(self) -> int | None:
        """While held: how many ``/clock`` readers the clock owner has matched (None otherwise)."""
        if self.stepper is not None:
            return self.stepper.clock_readers() if self._holds else None
        if not self.simulated or self._held_since is None:
            return None
        reply = self._call(True)
        return reply[1] if reply else None

    def _hold(self) -> None:
        reply = self._call(True)
        if reply is None:
            return                           # no hold: the process starts on the running clock
        end = time.monotonic() + HOLD_WAIT_S
        while self.node.get_clock().now().nanoseconds < reply[0] and time.monotonic() < end:
            time.sleep(0.001)
        self._held_since = time.monotonic()

    def _release(self) -> None:
        since = self._held_since
        self._call(False)
        if since is not None:
            self.held_s += time.monotonic() - since
            self._held_since = None
