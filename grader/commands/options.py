"""Options more than one command takes (``--time-scale``, a whole number >= 1), parsed the same way
everywhere."""

from __future__ import annotations

import argparse

from grader.contracts.speed import DEFAULT_TIME_SCALE, MAX_TIME_SCALE, MIN_CPUS_FOR_DEFAULT


def time_scale_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--time-scale", type=time_scale, default=None, metavar="K",
                        help="run scenarios K times faster than real time on simulated time, each one "
                             "that may: a node paced by the wall clock runs at 1x, and the result says "
                             f"so (default {DEFAULT_TIME_SCALE:g} on a grader given {MIN_CPUS_FOR_DEFAULT:g} "
                             "CPUs or more, else 1; 1: real time)")


def time_scale(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = 0.0
    if not 1.0 <= value <= MAX_TIME_SCALE:
        raise argparse.ArgumentTypeError(f"expected a speed-up between 1 and {MAX_TIME_SCALE:g} (e.g. 4), "
                                         f"got {text!r}")
    return value


def positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value
