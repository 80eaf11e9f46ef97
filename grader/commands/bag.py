"""``grader record``, ``grader bag info|repair|verify``, ``grader replay``: the bag tools' command
line (it lived in ``grader.bag``; the engine is reached through ``grader.api.tools``)."""

from __future__ import annotations

from typing import Any

import json
from pathlib import Path

from grader.api.tools import record as _record, recorder_arguments, replay as _replay, replay_arguments
from grader.errors import GraderError


def _info(args: Any) -> int:
    from grader.api.bags import bag_info, format_info  # noqa: PLC0415 - api.bags loads numpy (147 ms CPU), only on this path

    info = bag_info(args.bag)
    if args.json:
        print(json.dumps(info, indent=1))
    else:
        print(format_info(info))
    return 0


def _repair(args: Any) -> int:
    from grader.api.bags import repair_bag  # noqa: PLC0415 - api.bags loads numpy, mcap (147 ms CPU), only on this path

    report = repair_bag(args.bag, keep_damaged=not args.no_backup)
    print(report.summary())
    return 0


def _verify(args: Any) -> int:
    """``grader bag verify BAG...``: one line per problem, exit 1 if any bag does not conform."""
    from grader.api.bags import verify  # noqa: PLC0415 - api.bags loads numpy (147 ms CPU), only on this path

    for b in args.bags:
        if not Path(b).is_dir():
            raise GraderError(f"{b} is not a bag directory; pass the folder that holds "
                              "metadata.yaml and the .mcap file(s).")
    bad = 0
    for b in args.bags:
        res = verify(b)
        if res.problems:
            bad += 1
            for problem in res.problems:
                print(f"{b}: {problem}")
        else:
            counts = res.counts.get("grader", {})
            print(f"{b}: conforms ({sum(counts.values())} messages on {len(counts)} topics; "
                  "rosbags, mcap + mcap-ros2-support and grader agree with metadata.yaml)")
            for note in res.notes:
                print(f"{b}: note: {note}")
    return 1 if bad else 0


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
