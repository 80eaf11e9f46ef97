"""``grader sim``: run the reference turtlesim in the foreground (Ctrl-C saves the canvas).

The simulator's options are its process's own (``python -m grader.sim``, started by every
scenario), reached through ``grader.api.tools``; this only registers the command."""

from __future__ import annotations

import argparse

from grader.api.tools import run_sim, sim_arguments


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``grader sim`` (see grader.cli.SUBSYSTEMS)."""
    parser = subparsers.add_parser(
        "sim", help="run the reference headless turtlesim node",
        description="Run the reference headless turtlesim (node /turtlesim) until Ctrl-C.")
    sim_arguments(parser)
    parser.set_defaults(func=run_sim)
