"""The engine behind the tool commands: ``grader record``/``bag``/``replay`` (bags),
``grader cache`` (the build and recording cache; a bag's info, repair and verification are in
:mod:`grader.api.bags`), ``grader build`` (one submission's build),
``grader sim`` (the reference simulator in the foreground), ``grader scores`` (manual scores,
gradebooks) and ``grader labs``. Their front-ends are in ``grader.commands``; they reach the
engine through these names only.

Most are the engine's own typed, documented functions, re-exported. The bag tools and the
simulator are entry points that take the parsed options (the same ones ``python -m
grader.bag.recorder``/``grader.sim`` parse when a scenario starts them as processes): their
options are added by :func:`recorder_arguments`, :func:`replay_arguments` and
:func:`sim_arguments`, and each runs with ``(args) -> exit status``. The bag replay (numpy,
147 ms CPU; rclpy) is imported only when its command runs.
"""

from __future__ import annotations

import argparse
from typing import Any

from grader.bag.recorder import add_arguments as recorder_arguments, run as record
from grader.cache import default_cache_dir
from grader.cache.store import KINDS as CACHE_KINDS, MAX_SIZE_ENV, hit_rate, human, info as cache_info, max_size, prune
from grader.intake.model import INTAKE_FILE
from grader.scores.export import export_gradebook
from grader.scores.merge import merge_manual_scores
from grader.scores.roster import parse_mapping, read_roster
from grader.sim.cli import _add_options as sim_arguments, run_from_args as run_sim
from grader.workspace.build import BuildResult, _to_json, build_workspace

__all__ = ["BuildResult", "CACHE_KINDS", "INTAKE_FILE", "MAX_SIZE_ENV", "build_json", "build_workspace", "cache_info", "default_cache_dir", "export_gradebook", "hit_rate", "human",
           "max_size", "merge_manual_scores", "parse_mapping", "prune", "read_roster", "record", "recorder_arguments",
           "replay", "replay_arguments", "run_sim", "sim_arguments"]


def build_json(result: BuildResult) -> dict[str, Any]:
    """``grader build --json``: a build's result as JSON (packages, executables, logs)."""
    return _to_json(result)


def replay(args: argparse.Namespace) -> int:
    """``grader replay BAG``: publish a bag into the live graph with its timing."""
    from grader.bag import replay as bag_replay  # noqa: PLC0415 - bag.replay loads numpy (147 ms CPU), only on this path

    return bag_replay.run(args)


def replay_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``grader replay`` (those of ``python -m grader.bag.replay``)."""
    from grader.bag.replay import add_arguments  # noqa: PLC0415 - bag.replay loads numpy (147 ms CPU), only on this path

    add_arguments(parser)
