"""CLI registration of the bag layer: ``grader record``, ``grader bag info|repair|verify``, ``grader replay``."""

from __future__ import annotations

import argparse
from typing import Any

from grader.bag import recorder
from grader.bag.recorder import add_arguments as recorder_arguments


def _record(args: argparse.Namespace) -> int:
    return recorder.run(args)


def _info(args: argparse.Namespace) -> int:
    from grader.bag import info  # noqa: PLC0415 - bag.info loads numpy (147 ms CPU), only on this path

    return info.run(args)


def _repair(args: argparse.Namespace) -> int:
    from grader.bag import repair  # noqa: PLC0415 - bag.repair loads numpy, mcap (147 ms CPU), only on this path

    return repair.run(args)


def _verify(args: argparse.Namespace) -> int:
    from grader.bag import conformance  # noqa: PLC0415 - bag.conformance loads numpy (147 ms CPU), only on this path

    return conformance.run(args)


def _replay(args: argparse.Namespace) -> int:
    from grader.bag import replay  # noqa: PLC0415 - bag.replay loads numpy (147 ms CPU), only on this path

    return replay.run(args)


def register(subparsers: Any) -> None:
    from grader.bag.replay import add_arguments as replay_arguments  # noqa: PLC0415 - bag.replay loads numpy (147 ms CPU), only on this path

    rec = subparsers.add_parser(
        "record", help="record topics of the live graph to a rosbag2 MCAP bag",
        description="Record topics (new ones are picked up while recording) until Ctrl-C.")
    recorder_arguments(rec)
    rec.set_defaults(func=_record)

    bag = subparsers.add_parser("bag", help="inspect or repair a bag")
    bag_sub = bag.add_subparsers(dest="bag_command", metavar="SUBCOMMAND")
    info = bag_sub.add_parser("info", help="duration, counts, types and rates of a bag")
    info.add_argument("bag", help="bag directory")
    info.add_argument("--json", action="store_true", help="machine-readable output")
    info.set_defaults(func=_info)
    repair = bag_sub.add_parser("repair", help="recover a bag whose recorder was killed")
    repair.add_argument("bag", help="bag directory")
    repair.add_argument("--no-backup", action="store_true",
                        help="delete the damaged MCAP file instead of keeping *.mcap.damaged")
    repair.set_defaults(func=_repair)
    verify = bag_sub.add_parser(
        "verify", help="check that ros2 bag, rosbags and Foxglove's mcap tooling read a bag alike",
        description="Read each bag with rosbags, mcap + mcap-ros2-support and the grader's reader "
                    "(decoding every message), compare their counts with metadata.yaml and the "
                    "MCAP summary, and check the metadata the way rosbag2 Jazzy decodes it. "
                    "Prints one line per problem; exit 1 when a bag does not conform.")
    verify.add_argument("bags", nargs="+", metavar="BAG", help="bag directories")
    verify.set_defaults(func=_verify)
    bag.set_defaults(func=lambda args: (bag.print_help(), 2)[1])

    rp = subparsers.add_parser("replay", help="publish a bag into the live graph with its timing")
    replay_arguments(rp)
    rp.set_defaults(func=_replay)
