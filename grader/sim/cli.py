"""The reference turtlesim's process options (``python -m grader.sim``, which a scenario starts),
also those of ``grader sim`` in the foreground (Ctrl-C saves the canvas; the command itself is
registered by ``grader.commands.sim``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from grader.contracts.speed import MAX_TIME_SCALE
from grader.errors import GraderError


def _add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--canvas-out", type=Path, metavar="FILE",
                        help="write the canvas PNG here on shutdown and on "
                             "/turtlesim/save_canvas (std_srvs/srv/Empty)")
    parser.add_argument("--holonomic", action="store_true",
                        help="start with parameter holonomic:=true")
    parser.add_argument("--background", nargs=3, type=int, metavar=("R", "G", "B"),
                        help="background colour (parameters background_r/g/b), 0..255 each")
    parser.add_argument("--time-scale", type=float, metavar="K", default=None,
                        help="own simulated time: publish /clock and step the physics on it, K times "
                             "faster than the wall clock (K >= 1; nodes need use_sim_time:=true)")
    parser.add_argument("--pose-record", type=Path, metavar="FILE",
                        help="also write every pose published to FILE (the simulator's own record, "
                             "see grader.sim.record)")
    parser.add_argument("--lockstep", action="store_true",
                        help="own simulated time and advance it only when asked: ~/step_clock "
                             "(a tick of time on /clock), then ~/step_world (the world's step, poses)")
    parser.add_argument("--step-fd", type=int, metavar="FD", default=None,
                        help="with --lockstep: the inherited socket the scenario driver steps over "
                             "(grader.sim.stepchannel); the two services then only answer")
    parser.add_argument("--clock-only", action="store_true",
                        help="with --time-scale: no turtles, only /clock (node grader_clock)")
    parser.add_argument("--ros-args", dest="ros_args", nargs=argparse.REMAINDER, default=[],
                        help="everything after this goes to ROS (remaps, -p name:=value, ...)")


def ros_argv(args: argparse.Namespace, prog: str = "grader-sim") -> list[str]:
    """The argv handed to rclpy: parameter overrides from our options, then the user's."""
    params: list[str] = []
    if args.holonomic:
        params += ["-p", "holonomic:=true"]
    if args.background is not None:
        for channel, value in zip("rgb", args.background):
            if not 0 <= value <= 255:
                raise GraderError(f"--background values must be 0..255, got {value}")
            params += ["-p", f"background_{channel}:={value}"]
    argv = [prog]
    if params:
        argv += ["--ros-args", *params]
    if args.ros_args:
        argv += ["--ros-args", *args.ros_args]
    return argv


def run_from_args(args: argparse.Namespace) -> int:
    """Start the node in this process; returns its exit status (0 after a clean stop)."""
    if args.canvas_out is not None and args.canvas_out.exists() and args.canvas_out.is_dir():
        raise GraderError(f"--canvas-out {args.canvas_out} is a directory; give a .png file path")
    if args.time_scale is not None and not 1.0 <= args.time_scale <= MAX_TIME_SCALE:
        raise GraderError(f"--time-scale must be between 1 and {MAX_TIME_SCALE:g}, got {args.time_scale:g}")
    if args.clock_only and args.time_scale is None:
        raise GraderError("--clock-only needs --time-scale K (the clock it publishes)")
    from grader.sim.process import run  # noqa: PLC0415 - rclpy only when actually running

    return run(ros_argv(args), canvas_out=args.canvas_out, time_scale=args.time_scale,
               clock_only=args.clock_only, pose_record=args.pose_record, lockstep=args.lockstep,
               step_fd=args.step_fd)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m grader.sim``."""
    parser = argparse.ArgumentParser(prog="python -m grader.sim",
                                     description="Reference headless turtlesim.")
    _add_options(parser)
    args = parser.parse_args(argv)
    try:
        return run_from_args(args)
    except GraderError as exc:
        print(f"grader: error: {exc}", file=sys.stderr)
        return 2
