"""``grader rubric ...``: the rubric tools' command line. ``check``, ``schema`` and ``guide`` over
``grader.rubric`` (load, the JSON Schema, the guide's generated tables), ``audit`` and
``collateral`` over ``grader.audit.run`` and ``grader.audit.collateral``. A front-end: the
rubric floor below it registers no command, and this reaches it through ``grader.api``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from grader.errors import GraderError
from grader.audit.mutate import OPERATORS
from grader.audit.report import text_summary
from grader.audit.run import choose, find_reference, run_audit
from grader.commands.options import positive as _positive, time_scale_option as _time_scale_option
from grader.api import load_rubric
from grader.api.rubrics import CHECKOUT, display_path, json_schema, refresh_guide


def register(sub: argparse._SubParsersAction) -> None:
    r = sub.add_parser("rubric", help="rubric tools: check, audit (mutation testing), JSON Schema, the guide's tables")
    rsub = r.add_subparsers(dest="rubric_command", metavar="ACTION", required=True)
    s = rsub.add_parser("schema", help="print (or write) the rubric JSON Schema")
    s.add_argument("-o", "--out", type=Path, default=None)
    s.set_defaults(func=_run_schema)
    g = rsub.add_parser("guide", help="refresh the generated tables of a rubric guide (rubrics/README.md)")
    g.add_argument("readme", type=Path, nargs="?", default=None)
    g.add_argument("--check", action="store_true", help="exit 1 when the tables are stale, write nothing")
    g.set_defaults(func=_run_guide)
    c = rsub.add_parser("check", help="validate a rubric and list what it grades")
    c.add_argument("rubric", type=Path)
    c.set_defaults(func=_run_check)

    register_audit(rsub)


def _run_schema(args: argparse.Namespace) -> int:
    text = json.dumps(json_schema(), indent=1) + "\n"
    if args.out:
        args.out.write_text(text)
    else:
        print(text, end="")
    return 0


def _run_guide(args: argparse.Namespace) -> int:
    readme = args.readme or CHECKOUT / "rubrics" / "README.md"
    changed = refresh_guide(readme, check=args.check)
    if args.check and changed:
        print(f"{readme}: stale generated part(s): {', '.join(changed)} (run grader rubric guide)")
        return 1
    print(f"{readme}: " + (f"updated {', '.join(changed)}" if changed else "up to date"))
    return 0


def _run_check(args: argparse.Namespace) -> int:
    rubric = load_rubric(args.rubric)
    print(f"{rubric.lab}: {rubric.title}")
    print(f"  {len(rubric.items)} items, {rubric.auto_max:g} automatic + {rubric.manual_max:g} manual points; "
          f"scenarios: {', '.join(rubric.scenarios) or 'none'}" + (f"; handout: {rubric.handout}" if rubric.handout else ""))
    for sid, sc in rubric.scenarios.items():
        print(f"  scenario {sid}: {len(sc.steps)} steps, up to {sc.budget_s:g} s; processes: "
              + (", ".join(p.name for p in sc.processes) or "none"))
    if rubric.equivalent_mutants:
        print(f"  {len(rubric.equivalent_mutants)} equivalent mutant(s) of the reference recorded (grader rubric audit)")
    for what, name, use, why in rubric.contract.lines():
        note = "; ".join(x for x in (use, why) if x)
        print(f"  contract {what}: {name}" + (f" ({note})" if note else ""))
    return 0


def register_audit(rsub: argparse._SubParsersAction) -> None:
    a = rsub.add_parser(
        "audit", help="mutation testing: grade mutants of the reference solution, list those that keep full marks",
        description="Mutate the rubric's reference solution (flip a sign, scale a constant, swap arguments, rename a "
                    "topic, drop a publish/log/call, remove an angle wrap, change a timer period), grade every "
                    "mutant and report which keep full marks: a blind spot of the rubric, or an equivalent mutant "
                    "recorded in the rubric's equivalent_mutants. Exit 0 when no mutant survives unrecorded.")
    _graded_mutants_options(a, "audit")
    a.add_argument("--sample", type=_positive, default=None, metavar="N", help="grade N mutants chosen at random")
    a.add_argument("--seed", type=int, default=0, help="seed of --sample (default 0)")
    a.add_argument("--operators", type=_operators, default=None, metavar="OP,OP",
                   help=f"only these operators ({', '.join(OPERATORS)})")
    a.add_argument("--only", nargs="+", metavar="ID", help="only these mutant ids (from an earlier report)")
    a.add_argument("--list", action="store_true", help="list the mutants (id, file:line, change) and grade nothing")
    a.add_argument("--all-files", action="store_true",
                   help="also mutate files the handout gives out unchanged (the lab's own code)")
    a.add_argument("--no-reuse", action="store_true", help="run every scenario of every mutant")
    a.add_argument("--quiet-diffs", action="store_true", help="print survivors without their diffs")
    _time_scale_option(a)
    a.set_defaults(func=run_audit_cli)

    c = rsub.add_parser(
        "collateral", help="one mistake costs once: which items does a one-aspect mutant cost beyond those about it",
        description="Change the rubric's reference solution in one aspect at a time the way students do (a node's "
                    "name, a topic's name, a log line printed instead, a timer's period), grade every such mutant and "
                    "list the items each lost beyond those that judge that aspect (collateral losses), and those the "
                    "rubric's accepted_collateral accepts with a reason. Exit 0 when every collateral loss is accepted.")
    _graded_mutants_options(c, "collateral")
    c.set_defaults(func=run_collateral_cli)


def _graded_mutants_options(parser: argparse.ArgumentParser, name: str) -> None:
    """What `audit` and `collateral` both take: the rubric, where to write, the reference, and
    how the mutants are graded."""
    parser.add_argument("rubric", type=Path)
    parser.add_argument("-o", "--out", type=Path, default=None,
                        help=f"output folder (default: {name}-<lab> in the current folder)")
    parser.add_argument("--reference", type=Path, default=None,
                        help="the reference solution (default: reference/ beside the rubric's handout, or "
                             "fixtures/submissions/<rubric name>/reference)")
    parser.add_argument("--jobs", type=_positive, default=2, help="scenarios (and builds) run at once (default 2)")
    parser.add_argument("--cache-dir", type=Path, default=None, help="build cache folder")
    parser.add_argument("--resume", action="store_true", help="keep mutants already graded in OUT")
    parser.add_argument("--regrade", action="store_true",
                        help="grade the recordings already in OUT again with the rubric as it is now (no ROS: after "
                             "changing items, parameters or analyzers); mutants not yet graded are graded")


def _operators(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in OPERATORS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown operator(s) {', '.join(unknown) or text!r}; "
                                         f"choose from {', '.join(OPERATORS)}")
    return names


def run_audit_cli(args: argparse.Namespace) -> int:
    if args.list:
        rubric = load_rubric(args.rubric)
        ref = find_reference(rubric, args.reference)
        chosen, made, given = choose(rubric, ref, args.operators, args.sample, args.seed, args.all_files)
        recorded = {e.mutant for e in rubric.equivalent_mutants}
        for m in chosen:
            mark = "  (equivalent)" if m.id in recorded else ""
            print(f"{m.id:30} {m.file}:{m.line}  {m.description}{mark}")

        print(f"{len(chosen)} of {made} mutants of {display_path(ref)}" + (f"; not mutated: {', '.join(given)}" if given else ""))
        return 0
    out = args.out
    if out is None:
        out = Path(f"audit-{load_rubric(args.rubric).lab}")

    def say(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    try:
        report = run_audit(args.rubric, out, reference=args.reference, jobs=args.jobs, time_scale=args.time_scale,
                           reuse=not args.no_reuse, cache_dir=args.cache_dir, sample_n=args.sample,
                           operators=args.operators, seed=args.seed, only=args.only, all_files=args.all_files,
                           resume=args.resume, regrade=args.regrade, say=say)
    except KeyboardInterrupt:
        print("grader: interrupted; graded mutants are kept: rerun with --resume to continue", file=sys.stderr)
        return 130
    except GraderError:
        raise
    print(text_summary(report, diffs=not args.quiet_diffs))
    print(f"report: {Path(out) / 'audit.md'} (and audit.json; the mutants' reports: {Path(out) / 'graded' / 'index.html'})")
    return 1 if report.count("surviving") or report.count("error") else 0


def run_collateral_cli(args: argparse.Namespace) -> int:
    from grader.audit.collateral import run_collateral, text_summary  # noqa: PLC0415 - audit.collateral loads pandas, numpy (424 ms CPU), only on this path

    out = args.out or Path(f"collateral-{load_rubric(args.rubric).lab}")

    def say(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    report = run_collateral(args.rubric, out, reference=args.reference, jobs=args.jobs, cache_dir=args.cache_dir,
                            resume=args.resume, regrade=args.regrade, say=say)
    print(text_summary(report))
    print(f"report: {Path(out) / 'collateral.md'} (and collateral.json; the mutants' reports: "
          f"{Path(out) / 'graded' / 'index.html'})")
    return 1 if report.collateral else 0
