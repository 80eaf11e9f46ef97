"""`grader build PATH`: build a submission and show per-package results (a front-end: it lived in
``grader.workspace``, which it reaches through ``grader.api.tools``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from grader.api.tools import build_json as _to_json, build_workspace, default_cache_dir


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("build", help="colcon-build a submission (workspace, package folder or archive)",
                       description="Copy a submission into an isolated build area, colcon-build it "
                                   "(cached by content hash) and list each package's result.")
    p.add_argument("path", type=Path, help="workspace with src/, folder of packages, one package, or .zip/.tar.gz")
    p.add_argument("--cache-dir", type=Path, default=None, help=f"build cache (default {default_cache_dir()})")
    p.add_argument("--support", action="append", default=[], metavar="NAME=PATH",
                   help="package to add when the submission lacks it (repeatable)")
    p.add_argument("--force", action="store_true", help="rebuild even if cached")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    support = dict(s.split("=", 1) for s in args.support)
    result = build_workspace(args.path, cache_dir=args.cache_dir,
                             support={k: Path(v) for k, v in support.items()}, force=args.force)
    if args.json:
        print(json.dumps(_to_json(result), indent=1))
        return 0 if result.ok else 1
    state = "cache hit" if result.cached else f"built in {result.duration_s:.1f}s"
    print(f"{args.path}: {state}; build area {result.root}")
    for name, pkg in sorted(result.packages.items()):
        reused = "  [reused: an earlier build of the same sources]" if pkg.reused_from else ""
        print(f"  {pkg.status:8} {name} ({pkg.build_type}){reused}")
        for exe, entry in sorted(pkg.executables.items()):
            print(f"             {exe} -> {entry}")
        if pkg.status != "built":
            print(pkg.log_excerpt)
        elif pkg.missing_dependencies:
            print(f"    note: package.xml names {', '.join(pkg.missing_dependencies)}, which the "
                  "grading machine lacks")
    if not result.ok:
        failed = [n for n, p in sorted(result.packages.items()) if p.status == "failed"]
        skipped = [n for n, p in sorted(result.packages.items()) if p.status == "skipped"]
        print(f"build failed for: {', '.join(failed) or 'none'}"
              + (f"; skipped: {', '.join(skipped)}" if skipped else "")
              + f" (full log: {result.build_log})")
    return 0 if result.ok else 1
