"""The `grader` command. Each front-end module registers its own subcommands (see SUBSYSTEMS);
every one of them is in the front-end floor (``grader.commands``, ``grader.lms``, the doctor, set-up),
none in the engine, which registers no command."""

from __future__ import annotations

import argparse
import gc
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


def freeze_heap() -> None:
    """Move every object alive now into the collector's permanent generation: later collections,
    and the interpreter's shutdown, no longer go through them. The `grader` program does it twice:
    after start-up (what its imports made lives as long as the process) and just before it exits
    (atexit handlers, ``weakref.finalize`` and the flushing of stdout/stderr still run). Why, on
    the 2-core machine (``benchmarks/bench_post.py``, Lab 3 reference, load 2-9): with pandas,
    numpy, scipy.stats and matplotlib loaded, the shutdown's collections cost 0.31-0.40 s CPU per
    process (median 0.33 s of 8), 0.03 s after it; and the collections of a self-check's
    post-scenario path 0.61-0.63 s, 0.31-0.38 s with start-up's objects frozen (a full collection
    amid a report's figures, 42,000 objects of theirs freed, went through all of pandas too).
    Only in a process that ends with the command: a caller that goes on (a test calling
    :func:`main`) keeps its garbage collected."""
    gc.freeze()


def main(argv: list[str] | None = None) -> int:
    # a batch killed with SIGTERM unwinds like Ctrl-C: children stop, bags are finalized; and
    # Ctrl-C works even when started from a shell that ignores SIGINT in background jobs
    signal.signal(signal.SIGTERM, _sigterm_as_interrupt)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    parser = build_parser()
    if argv is None:              # the `grader` program (its arguments from sys.argv)
        freeze_heap()
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
    finally:
        if argv is None:          # the program, about to exit
            freeze_heap()


if __name__ == "__main__":
    sys.exit(main())
