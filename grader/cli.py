"""The `grader` command. Each front-end module registers its own subcommands (see SUBSYSTEMS);
every one of them is in the front-end floor (``grader.commands``, ``grader.lms``, the doctor, set-up),
none in the engine, which registers no command."""

from __future__ import annotations

import argparse
import importlib
import signal
import sys

from grader.errors import GraderError

#: modules with a ``register(subparsers)`` function, in the order ``grader --help`` lists their
#: commands; missing ones are skipped so that a partial checkout still gives a working CLI for
#: what it has.
SUBSYSTEMS = (
    "grader.bootstrap",
    "grader.commands.labs",
    "grader.doctor",
    "grader.commands.build",
    "grader.commands.sim",
    "grader.commands.bag",
    "grader.commands.grading",
    "grader.commands.cache",
    "grader.commands.rubric",
    "grader.commands.scores",
    "grader.lms.cli",
    "grader.commands.similarity",
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
