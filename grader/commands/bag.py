"""``grader record``, ``grader bag info|repair|verify``, ``grader replay``: the bag tools' command
line (it lived in ``grader.bag``; the engine is reached through ``grader.api.tools``)."""

from __future__ import annotations

from typing import Any

from grader.api.tools import (bag_info as _info, bag_repair as _repair, bag_verify as _verify, record as _record,
                               recorder_arguments, replay as _replay, replay_arguments)


def register(subparsers: Any) -> None:
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
