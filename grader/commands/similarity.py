"""``grader similarity OUT --rubric R``: source and behaviour similarity of a graded class; the
options ``grader grade`` and ``grader merge`` share with it, and what they print of the comparison
after a batch. A front-end (it lived in ``grader.similarity``): it reaches the engine through
``grader.api`` (``grader.api.similarity``, which loads pandas, imported where it is used)."""

from __future__ import annotations

import sys
import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from grader.api import load_rubric
from grader.errors import GraderError

if TYPE_CHECKING:
    from grader.api.similarity import ClassComparison, Settings


def add_options(p: argparse.ArgumentParser) -> None:
    """The options `grader similarity` and `grader grade` share."""
    p.add_argument("--known", type=Path, metavar="DIR",
                   help="a folder of known solutions (workspaces or archives, e.g. public repositories): "
                        "each is compared with every submission, both ways")
    p.add_argument("--boilerplate", type=Path, action="append", default=[], metavar="DIR",
                   help="code the students were given besides the rubric's handout and support packages "
                        "(e.g. the lab text's code): never counted (repeatable)")
    p.add_argument("--threshold", type=_share, default=None, metavar="SHARE",
                   help="list a pair when its source similarity reaches this (0-1, default 0.5) ...")
    p.add_argument("--behaviour-threshold", type=_share, default=None, metavar="SHARE",
                   help="... or its behaviour similarity reaches this (0-1, default 0.3)")
    p.add_argument("--max-pages", type=int, default=None, metavar="N",
                   help="side-by-side pages (and class-view rows) for the N most similar listed pairs "
                        "(default 50; every pair is in OUT/similarity/pairs.csv)")


def add_grade_options(p: argparse.ArgumentParser) -> None:
    """`grader grade` and `grader merge`: similarity runs after grading unless --no-similarity."""
    p.add_argument("--no-similarity", action="store_true",
                   help="do not compare the graded submissions with each other (grader similarity)")
    add_options(p)


def grade_settings(args: argparse.Namespace) -> Settings | None:
    """The similarity settings of `grader grade`/`grader merge`, checked before any grading (a
    wrong --known or --boilerplate folder is reported at once, not after an hour of grading);
    None with --no-similarity."""
    return None if getattr(args, "no_similarity", False) else settings_from(args)


def say_comparison(out: Path, comparison: ClassComparison | None) -> None:
    """What ``grader grade``/``grader merge`` print of the similarity they ran after the batch
    (:func:`grader.api.similarity.compare_graded`): one line, on stderr when it was not computed."""
    if comparison is None:
        return
    if comparison.summary is None:
        print(f"grader: similarity not computed ({comparison.error}); run `grader similarity "
              f"{out} --rubric ...` to retry", file=sys.stderr)
        return
    summary = comparison.summary
    listed = sum(1 for p in summary["pairs"] if p["listed"])
    print(f"similarity: {summary['pairs_compared']} pairs in {summary['timings'].get('total_s', 0):.1f} s, "
          f"{listed} listed in {out / 'index.html'} (details: grader similarity)")


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("similarity", help="source and behaviour similarity of a graded class",
                       description="Compare every pair of submissions of a graded batch (and each with known "
                                   "solutions) by source (copydetect fingerprints, given code removed) and by "
                                   "behaviour (the recorded scenarios: paths, commands, rates, log lines, failing "
                                   "items), weighed by how unusual it is in this class. Writes OUT/similarity/ "
                                   "(similarity.json, pairs.csv, one side-by-side page per listed pair) and adds "
                                   "the list to OUT/index.html. Runs no student code.")
    s.add_argument("out", type=Path, help="the output folder of `grader grade`")
    s.add_argument("--rubric", type=Path, required=True, help="the rubric the batch was graded with")
    add_options(s)
    s.add_argument("--jobs", type=int, default=2, help="processes for bags without a stored fingerprint")
    s.set_defaults(func=run_cli)


def _share(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a share between 0 and 1 (e.g. 0.5), got {text!r}")
    return value


def settings_from(args: argparse.Namespace) -> Settings:
    from grader.api.similarity import Settings  # noqa: PLC0415 - api.similarity loads grading.similarity, pandas, numpy (424 ms CPU), only on this path

    for d in args.boilerplate:
        if not Path(d).is_dir():
            raise GraderError(f"--boilerplate {d}: not a folder (give the folder of the code the students "
                              "were given)")
    if args.known and not Path(args.known).is_dir():
        raise GraderError(f"--known {args.known}: not a folder (give a folder of workspaces or archives)")
    settings = Settings(boilerplate=[str(Path(d).resolve()) for d in args.boilerplate],
                        known=str(Path(args.known).resolve()) if args.known else None)
    if args.threshold is not None:
        settings.threshold = args.threshold
    if args.behaviour_threshold is not None:
        settings.behaviour_threshold = args.behaviour_threshold
    if args.max_pages is not None:
        if args.max_pages < 0:
            raise GraderError(f"--max-pages {args.max_pages}: give 0 or more")
        settings.max_pages = args.max_pages
    return settings


def print_summary(summary: dict, out: Path) -> None:
    listed = [p for p in summary["pairs"] if p["listed"]]
    t = summary["timings"]
    print(f"similarity: {summary['class_size']} submissions, {summary['pairs_compared']} pairs"
          + (f", {len(summary['known'])} known solution(s)" if summary["known"] else "")
          + f" in {t.get('total_s', 0):.1f} s; {len(listed)} pair(s) at or above source "
          f"{summary['settings']['threshold']:g} or behaviour {summary['settings']['behaviour_threshold']:g}")
    for p in listed[:20]:
        other = ("known solution " + p["b"].split(":", 1)[1]) if p["known"] else p["b"]
        print(f"  {p['a']:<20} {other:<28} source {p['source']:.0%}  behaviour {p['behaviour']:.0%}")
    for i, c in enumerate(summary["clusters"], 1):
        print(f"  group {i}: {', '.join(c)}")
    print(f"wrote {out / 'similarity'} (pairs.csv, one page per listed pair) and {out / 'index.html'}")


def run_cli(args: argparse.Namespace) -> int:
    from grader.api.similarity import run_similarity  # noqa: PLC0415 - api.similarity loads grading.similarity, pandas, numpy (424 ms CPU), only on this path

    if not args.out.is_dir():
        raise GraderError(f"{args.out} is not a folder (give the output folder of `grader grade`)")
    rubric = load_rubric(args.rubric)
    summary = run_similarity(args.out, rubric, settings_from(args), jobs=max(1, args.jobs))
    if summary["no_source"]:
        print(f"note: no source kept for {', '.join(summary['no_source'][:10])} (graded before grader kept "
              "sources, or the build failed before staging): compared by behaviour only")
    print_summary(summary, args.out)
    return 0
