"""Reference headless turtlesim (node ``turtlesim``) for recording and grading.

A faithful rclpy re-implementation of ROS 2 Jazzy's ``turtlesim_node`` (the behaviour it follows
is written down in docs/turtlesim.md) plus four grader additions: service introspection on every
simulator service, a PNG of the canvas, a copy of each turtle's pose on a grader topic
(``truth_pose_topic``, which the driver watches live: any node could publish there too), and the
simulator's own record of every pose it publishes (``--pose-record``, :mod:`grader.sim.record`),
which the scenario writes into the bag: grades rest on that record only.  Start it as its own
process (``sim_argv``); this module only holds names and the argv helper, so importing it never
imports rclpy.

Public API::

    argv = sim_argv(canvas_out="run/canvas.png")       # -> [python, -m, grader.sim, ...]
    SAVE_CANVAS_SERVICE                                 # "/turtlesim/save_canvas" (std_srvs/Empty)
    service_event_topic("/turtle1/set_pen")             # "/turtle1/set_pen/_service_event"
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Iterable, Sequence

NODE_NAME = "turtlesim"
#: grader addition; only offered when the sim was started with a canvas path
SAVE_CANVAS_SERVICE = "/turtlesim/save_canvas"
#: grader addition, relative to the simulator's node (``/<node>/hold_turtles``, std_srvs/SetBool):
#: true holds every turtle still (teleports and commands are taken, nothing moves), false releases
HOLD_TURTLES_SERVICE = "hold_turtles"
#: global services of the simulator (all with CONTENTS introspection)
GLOBAL_SERVICES = ("/clear", "/reset", "/spawn", "/kill")
#: per-turtle services, relative to ``/<turtle name>/`` (all with CONTENTS introspection)
TURTLE_SERVICES = ("set_pen", "teleport_absolute", "teleport_relative")
#: per-turtle topics (relative to ``/<turtle name>/``) and the action
TURTLE_TOPICS = {"cmd_vel": "geometry_msgs/msg/Twist", "pose": "turtlesim/msg/Pose",
                 "color_sensor": "turtlesim/msg/Color"}
TURTLE_ACTION = "rotate_absolute"
#: log text of the wall warning (printf format, internal screen coordinates)
WALL_WARNING_PREFIX = "Oh no! I hit the wall!"


#: the simulator's own copy of each pose: ``/grader/sim/<turtle>/pose``
TRUTH_PREFIX = "/grader/sim"


def truth_pose_topic(pose_topic: str) -> str:
    """``/turtle1/pose`` -> ``/grader/sim/turtle1/pose`` (the simulator's live copy for the driver;
    not proof of origin: see :mod:`grader.sim.record`)."""
    return TRUTH_PREFIX + "/" + pose_topic.lstrip("/")


def service_event_topic(service: str) -> str:
    """Topic on which a service with introspection publishes its ``_service_event`` messages."""
    return service.rstrip("/") + "/_service_event"


def turtle_service_events(turtle: str = "turtle1") -> list[str]:
    """The ``_service_event`` topics of one turtle's services."""
    return [service_event_topic(f"/{turtle}/{s}") for s in TURTLE_SERVICES]


def all_service_event_topics(turtles: Iterable[str] = ("turtle1",)) -> list[str]:
    """Global + per-turtle ``_service_event`` topics (what a recorder should subscribe to)."""
    topics = [service_event_topic(s) for s in GLOBAL_SERVICES]
    for turtle in turtles:
        topics.extend(turtle_service_events(turtle))
    return topics


def sim_args(canvas_out: str | Path | None = None, *, holonomic: bool = False,
             background: Sequence[int] | None = None,
             ros_args: Sequence[str] = (), time_scale: float | None = None,
             clock_only: bool = False, pose_record: str | Path | None = None,
             lockstep: bool = False, step_fd: int | None = None) -> list[str]:
    """Command-line arguments of ``python -m grader.sim`` (without the interpreter part).

    ``time_scale``: the simulator owns simulated time and publishes ``/clock`` (see
    :mod:`grader.sim.clock`); ``clock_only``: only that clock, no turtles; ``pose_record``: where
    the simulator writes its own record of the poses it publishes (:mod:`grader.sim.record`);
    ``lockstep``: simulated time advances only when the scenario driver steps it, over the
    inherited socket ``step_fd`` when given (:mod:`grader.sim.stepchannel`).
    """
    args: list[str] = ["--lockstep"] if lockstep else []
    if step_fd is not None:
        args += ["--step-fd", str(step_fd)]
    if pose_record is not None:
        args += ["--pose-record", str(pose_record)]
    if time_scale is not None:
        args += ["--time-scale", repr(float(time_scale))]
    if clock_only:
        args.append("--clock-only")
    if canvas_out is not None:
        args += ["--canvas-out", str(canvas_out)]
    if holonomic:
        args.append("--holonomic")
    if background is not None:
        args += ["--background", *(str(int(c)) for c in background)]
    if ros_args:
        args += ["--ros-args", *ros_args]
    return args


def sim_argv(canvas_out: str | Path | None = None, extra: Sequence[str] = (), *,
             holonomic: bool = False, background: Sequence[int] | None = None,
             ros_args: Sequence[str] = (), time_scale: float | None = None,
             clock_only: bool = False, pose_record: str | Path | None = None,
             lockstep: bool = False, step_fd: int | None = None) -> list[str]:
    """argv that starts the simulator as a separate process with this interpreter.

    ``extra`` is appended verbatim (e.g. ``["--ros-args", "-r", "__ns:=/sim1"]``).
    """
    return [sys.executable, "-m", "grader.sim",
            *sim_args(canvas_out, holonomic=holonomic, background=background, ros_args=ros_args,
                      time_scale=time_scale, clock_only=clock_only, pose_record=pose_record,
                      lockstep=lockstep, step_fd=step_fd),
            *extra]


__all__ = ["NODE_NAME", "TRUTH_PREFIX", "truth_pose_topic", "SAVE_CANVAS_SERVICE", "GLOBAL_SERVICES", "TURTLE_SERVICES",
           "TURTLE_TOPICS", "TURTLE_ACTION", "WALL_WARNING_PREFIX", "service_event_topic",
           "turtle_service_events", "all_service_event_topics", "sim_args", "sim_argv"]
