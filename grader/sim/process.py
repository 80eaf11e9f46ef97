"""The simulator's process: its executor, its stop on SIGINT/SIGTERM, and what it leaves behind
(the canvas PNG, the closed pose record, a line on stderr when ticks ran late).

Kept apart from :mod:`grader.sim.node`, which holds the node's endpoints only, so the node can be
made in any process (tests spin it in their own executor) while ``grader sim`` runs it here.

The clock of a scenario without a simulator (``--clock-only``, node ``grader_clock``) never
imports :mod:`grader.sim.node` (geometry_msgs, turtlesim's messages and action, the canvas):
474 modules loaded before, 408 after. Measured (CPU when its node exists, median of 10 starts
alternating with the old code, load 7.7): 0.270 s before, 0.246 s after. Less than the import
costs alone (0.10 s in a fresh interpreter), since numpy, which ``geometry_msgs`` loaded, comes
anyway with the clock's services (``service_msgs``); see benchmarks/README.md, "The scenario's
own processes".
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path
from typing import Any, Sequence

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions

from grader.executors import make_executor as shared_make_executor
from grader.sim.clock import make_clock_node
from grader.sim.stepchannel import StepServer


def make_executor(context: rclpy.context.Context) -> Any:
    """The executor of the sim: ``GRADER_SIM_EXECUTOR`` = ``events`` (default) or ``single``.

    EventsExecutor keeps the 16 ms cadence on a loaded 2-core machine with 20 turtles, where the
    SingleThreadedExecutor rebuilds its wait set from ~200 entities on every wake.
    """
    return shared_make_executor(context, os.environ.get("GRADER_SIM_EXECUTOR", "events"))


def run(args: Sequence[str] | None = None, *, canvas_out: str | Path | None = None,
        time_scale: float | None = None, clock_only: bool = False,
        pose_record: str | Path | None = None, lockstep: bool = False, step_fd: int | None = None) -> int:
    """Run the node until SIGINT/SIGTERM or ROS shutdown; save the canvas; return 0.

    ``args`` is the full argv for rclpy (ROS arguments after ``--ros-args``). ``time_scale``:
    simulated time K times faster than the wall clock, published on ``/clock``;
    ``clock_only``: no turtles, only the clock (node ``grader_clock``); ``pose_record``: the
    file of :mod:`grader.sim.record`; ``step_fd``: with ``lockstep``, the descriptor of the
    driver's step channel (:mod:`grader.sim.stepchannel`), over which it then steps.
    """
    context = rclpy.Context()
    rclpy.init(args=list(args) if args is not None else None, context=context,
               signal_handler_options=SignalHandlerOptions.NO)
    stop = {"flag": False}

    def _request_stop(_signum: int, _frame: Any) -> None:
        stop["flag"] = True

    previous = {sig: signal.signal(sig, _request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    node = None
    executor = None
    steps: StepServer | None = None
    try:
        if clock_only:
            node = make_clock_node(context, time_scale or 1.0)
        else:
            from grader.sim.node import TurtlesimNode  # noqa: PLC0415 - sim.node loads geometry_msgs, turtlesim, the canvas: 0.024 s CPU (66 modules) a clock-only process does not need

            node = TurtlesimNode(context=context, canvas_out=canvas_out, time_scale=time_scale,
                                 pose_record=pose_record, lockstep=lockstep)
        executor = make_executor(context)
        executor.add_node(node)
        if step_fd is not None and lockstep and not clock_only:
            node.steps_by_channel = True
            steps = StepServer(step_fd, node.serve_step, executor.create_task)
            steps.start()
        while not stop["flag"] and context.ok():
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if steps is not None:
            steps.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if node is not None and not clock_only:     # the simulator (a TurtlesimNode)
            if node.caught_up_ticks or node.resynced_ticks:
                print(f"turtlesim: ran {node.caught_up_ticks} timer ticks late, dropped "
                      f"{node.resynced_ticks} after long stalls", file=sys.stderr)
            try:
                node.save_canvas()
            except OSError as exc:
                print(f"turtlesim: could not save canvas: {exc}", file=sys.stderr)
            if node.pose_record is not None:
                node.pose_record.close()
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        if context.ok():
            rclpy.shutdown(context=context)
    return 0
