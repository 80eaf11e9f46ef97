"""`grader gradescope` (write an autograder zip) and `grader gradescope-run` (what it runs)."""

from __future__ import annotations

import sys
import os
import argparse
from pathlib import Path

from grader.lms.classroom import points, step_output
from grader.lms.gradescope import default_root, prepare_image, run
from grader.lms.gradescope_bundle import BASE_IMAGE, write_bundle


def register(sub: argparse._SubParsersAction) -> None:
    g = sub.add_parser("gradescope", help="write a Gradescope autograder zip for a rubric",
                       description="Writes the autograder .zip to upload on a Gradescope programming "
                                   "assignment: setup.sh (Ubuntu 22.04 base image), run_autograder, the "
                                   "grader wheel and the rubric with its support files.")
    g.add_argument("--rubric", type=Path, required=True, help="rubric YAML (e.g. rubrics/enee467_lab3.yaml)")
    g.add_argument("-o", "--out", type=Path, required=True, help="the zip to write (e.g. autograder.zip)")
    g.add_argument("--wheel", type=Path, default=None,
                   help="grader wheel to ship (default: build one from this source checkout)")
    g.add_argument("--sandbox", choices=("auto", "require"), default="auto",
                   help="require: fail the image build (and every run) unless every sandbox protection "
                        "works in Gradescope's container; auto (default): grade with what works, and say so")
    g.set_defaults(func=run_bundle)

    s = sub.add_parser("gradescope-setup", help="prepare a Gradescope image (setup.sh calls this)",
                       description="Builds the rubric's support packages into ROOT/grader-cache, so no "
                                   "submission compiles them again, and lists the sandbox protections "
                                   "student code gets in this image.")
    s.add_argument("--rubric", type=Path, required=True)
    s.add_argument("--root", type=Path, default=None,
                   help="the autograder root (default: $GRADER_AUTOGRADER_ROOT or /autograder)")
    s.set_defaults(func=run_setup)

    c = sub.add_parser("classroom-result", help="grader check's result as a GitHub Classroom autograding runner",
                       description="Prints `result=<base64 JSON>` for $GITHUB_OUTPUT: the runner document "
                                   "GitHub Classroom's autograding reporter reads (one test per public "
                                   "automatic item, with its points). Appends to $GITHUB_OUTPUT itself when "
                                   "that is set. A missing result.json gives an `error` runner.")
    c.add_argument("result", type=Path, help="grader check's result.json (e.g. grader-report/check/result.json)")
    c.set_defaults(func=run_classroom_result)

    r = sub.add_parser("gradescope-run", help="grade a Gradescope submission (run_autograder calls this)",
                       description="Grades ROOT/submission with every item of the rubric and writes "
                                   "ROOT/results/results.json in Gradescope's format.")
    r.add_argument("--rubric", type=Path, required=True)
    r.add_argument("--root", type=Path, default=None,
                   help="the autograder root (default: $GRADER_AUTOGRADER_ROOT or /autograder)")
    r.add_argument("--cache-dir", type=Path, default=None,
                   help="build cache folder (default: ROOT/grader-cache, made by gradescope-setup)")
    r.set_defaults(func=run_autograder)


def run_bundle(args: argparse.Namespace) -> int:
    info = write_bundle(args.rubric, args.out, wheel=args.wheel, sandbox=args.sandbox)
    size = info["zip"].stat().st_size / 2**20
    print(f"wrote {info['zip']} ({size:.1f} MiB): lab {info['lab']}, {info['wheel']}, {info['rubric']}")
    print(f"  {info['tests']} autograder tests worth {info['auto_points']:g} points "
          f"({info['hidden']} shown after publishing, {info['integrity']} integrity flags for staff only)")
    if info["manual"]:
        manual = ", ".join(f"{item} ({points:g})" for item, points in info["manual"])
        print(f"  manual items, to create as Gradescope questions: {manual}")
    print(f"  on Gradescope: base image {BASE_IMAGE}; in the autograder settings give it 2 CPUs, "
          "4 GB of memory and a 20 minute timeout (it runs ROS 2 live)")
    return 0


def run_classroom_result(args: argparse.Namespace) -> int:
    line, runner = step_output(args.result)
    target = os.environ.get("GITHUB_OUTPUT")
    if target:
        with open(target, "a") as f:
            f.write(line + "\n")
    else:
        print(line)
    got, most = points(runner)
    print(f"Points {got:g}/{most:g} ({runner['status']})", file=sys.stderr)
    return 0


def run_setup(args: argparse.Namespace) -> int:
    info = prepare_image(args.root or default_root(), args.rubric)
    if info["support"]:
        how = "already built" if info["cached"] else "built"
        print(f"support packages {how} into {info['cache']}: {', '.join(info['support'])}")
    else:
        print("the rubric has no support packages to pre-build")
    rows = info["protections"]
    print(f"sandbox of student code in this image: {sum(p.active for p in rows)}/{len(rows)} protections active")
    for p in rows:
        print(f"  {p.line()}")
    return 0


def run_autograder(args: argparse.Namespace) -> int:
    root = args.root or default_root()
    doc = run(root, args.rubric, cache_dir=args.cache_dir)
    print(f"{root / 'results' / 'results.json'}: {doc['score']:g} points, {len(doc['tests'])} tests")
    return 0
