"""``grader labs``: the labs this grader has rubrics for (id, points, title, where the rubric is).
A front-end: the labs are ``grader.labs``'s, reached through ``grader.api.rubrics``."""

from __future__ import annotations

import argparse
import json
import sys

from grader.api.rubrics import known_labs, rubrics_dir


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("labs", help="list the labs this grader has rubrics for",
                       description="Lists each known lab (id, points, title) and where its rubric is. "
                                   "Use an id with `grader check --lab ID`.")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run_labs)


def run_labs(args: argparse.Namespace) -> int:
    labs, broken = known_labs()
    if args.json:
        print(json.dumps([{"id": lab.id, "title": lab.title, "points": lab.points,
                           "auto_points": lab.auto_points, "rubric": str(lab.rubric)} for lab in labs],
                         indent=1))
    else:
        width = max((len(lab.id) for lab in labs), default=2)
        for lab in labs:
            print(f"{lab.id:<{width}}  {lab.points:>4g} points ({lab.auto_points:g} automatic)  {lab.title}")
        if not labs:
            print(f"no labs found in {rubrics_dir()}")
        else:
            print(f"\nrubrics in {rubrics_dir()}; self-check with `grader check --lab {labs[0].id}`")
    for line in broken:
        print(f"grader: warning: rubric {line}", file=sys.stderr)
    return 0 if labs else 1
