"""The `grader` command. Each subsystem registers its own subcommands (see SUBSYSTEMS)."""

from __future__ import annotations

import argparse
import importlib
import signal
import sys

from grader.errors import GraderError

#: modules with a ``register(subparsers)`` function; missing ones are skipped so that a partial
#: checkout still gives a working CLI for what it has.
SUBSYSTEMS = (
    "grader.bootstrap",
    "grader.labs",
    "grader.doctor",
    "grader.workspace.cli",
    "grader.sim.cli",
    "grader.bag.cli",
    "grader.commands.grading",
    "grader.grading.shards",
    "grader.cache.cli",
    "grader.commands.rubric",
    "grader.scores.cli",
    "grader.lms.cli",
    "grader.similarity.cli",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="grader",
        description="Record-and-replay grading of ROS 2 Jazzy turtlesim labs.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBSYSTEMS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name and name.startswith(exc.name):
                continue
            raise
        module.register(sub)
    return parser


def _sigterm_as_interrupt(*_args) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    # a batch killed with SIGTERM unwinds like Ctrl-C: children stop, bags are finalized; and
    # Ctrl-C works even when started from a shell that ignores SIGINT in background jobs
    signal.signal(signal.SIGTERM, _sigterm_as_interrupt)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except GraderError as exc:
        print(f"grader: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("grader: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
