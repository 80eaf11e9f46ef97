"""``grader cache info`` (what the cache holds, the last batch's hit rates) and ``grader cache
prune`` (by age, by last use, by total size, or everything). A front-end (it lived in
``grader.cache``): the cache is reached through ``grader.api.tools``."""

from __future__ import annotations

import argparse
import datetime as dt
import json
import re
from pathlib import Path

from grader.errors import GraderError
from grader.api.batch import parse_size
from grader.api.tools import (CACHE_KINDS as KINDS, MAX_SIZE_ENV, cache_info as info, default_cache_dir, hit_rate,
                              human, max_size, prune)

_AGE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([smhdw])\s*$")
_AGE_S = {"s": 1, "m": 60, "h": 3600, "d": 86400, "w": 7 * 86400}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("cache", help="see and prune the build and recording cache",
                       description="The cache holds build areas, the support packages' builds and scenario "
                                   f"recordings (default {default_cache_dir()}). Batches keep it under a cap "
                                   f"(--cache-max-size, ${MAX_SIZE_ENV}, default 5G).")
    cmds = p.add_subparsers(dest="cache_command", metavar="{info,prune}")
    i = cmds.add_parser("info", help="size per kind, entries, oldest/newest use, the last batch's hit rates")
    i.add_argument("--json", action="store_true", help="print the same as JSON")
    _cache_dir(i)
    i.set_defaults(func=run_info)
    r = cmds.add_parser("prune", help="remove entries (never one a running batch holds)",
                        description="Remove cache entries by age, by last use or to a total size; entries "
                                    "a running batch holds are skipped. Give at least one criterion.")
    r.add_argument("--older-than", type=_age, metavar="AGE",
                   help="entries made more than AGE ago (e.g. 30d, 12h, 2w)")
    r.add_argument("--unused-since", type=_date, metavar="DATE",
                   help="entries not used since DATE (YYYY-MM-DD or YYYY-MM-DDTHH:MM)")
    r.add_argument("--max-size", metavar="SIZE",
                   help="then the least recently used until the cache fits SIZE (e.g. 2G, 500M)")
    r.add_argument("--all", action="store_true", help="every entry")
    r.add_argument("--dry-run", action="store_true", help="say what would be removed, remove nothing")
    _cache_dir(r)
    r.set_defaults(func=run_prune)
    p.set_defaults(func=lambda _args: p.print_help() or 2)


def _cache_dir(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--cache-dir", type=Path, default=None,
                        help="cache folder (default $GRADER_CACHE/builds or ~/.cache/grader/builds)")


def _age(text: str) -> float:
    m = _AGE.match(text)
    if not m:
        raise argparse.ArgumentTypeError(f"expected an age such as 30d, 12h or 2w, got {text!r}")
    return float(m.group(1)) * _AGE_S[m.group(2)]


def _date(text: str) -> float:
    try:
        return dt.datetime.fromisoformat(text).timestamp()
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a date such as 2025-01-31 or 2025-01-31T18:00, "
                                         f"got {text!r}") from None


def _when(t: float | None) -> str:
    return dt.datetime.fromtimestamp(t).strftime("%Y-%m-%d %H:%M") if t else "-"


def _folder(args: argparse.Namespace) -> Path:
    return Path(args.cache_dir or default_cache_dir())


def run_info(args: argparse.Namespace) -> int:
    cache = _folder(args)
    doc = info(cache)
    doc["cap_bytes"] = max_size()
    if args.json:
        print(json.dumps(doc, indent=1))
        return 0
    print(f"cache: {cache}" + ("" if cache.is_dir() else "  (does not exist yet)"))
    print(f"  {'kind':<14} {'entries':>7} {'size':>10}  {'oldest use':<16}  {'newest use':<16}")
    for kind, k in doc["kinds"].items():
        print(f"  {kind:<14} {k['entries']:>7} {human(k['bytes']):>10}  {_when(k['oldest_use']):<16}  "
              f"{_when(k['newest_use']):<16}")
    cap = doc["cap_bytes"]
    print(f"  {'total':<14} {doc['entries']:>7} {human(doc['total_bytes']):>10}  "
          f"cap {human(cap) if cap else 'none'} (--cache-max-size, $GRADER_CACHE_MAX_SIZE)")
    last = doc["last_batch"]
    if last:
        print(f"last batch, ended {_when(last.get('finished'))}, {last.get('submissions', 0)} submissions: "
              f"builds {hit_rate(last.get('builds_hit', 0), last.get('builds_missed', 0))} from the cache, "
              f"recordings {hit_rate(last.get('recordings_hit', 0), last.get('recordings_missed', 0))} reused, "
              f"{last.get('packages_reused', 0)} support packages taken prebuilt"
              + (f"; {last['pruned_entries']} entries pruned to the cap" if last.get("pruned_entries") else ""))
    else:
        print("last batch: none recorded in this cache")
    return 0


def run_prune(args: argparse.Namespace) -> int:
    size = parse_size(args.max_size) if args.max_size is not None else None
    if not (args.all or args.older_than is not None or args.unused_since is not None or size is not None):
        raise GraderError("say what to prune: --older-than AGE, --unused-since DATE, --max-size SIZE or --all "
                          "(entries a running batch holds are never removed).")
    cache = _folder(args)
    if not cache.is_dir():
        raise GraderError(f"{cache} does not exist: nothing to prune (--cache-dir names another cache).")
    done = prune(cache, max_size=size, unused_since=args.unused_since, older_than_s=args.older_than,
                 everything=args.all, dry_run=args.dry_run)
    verb = "would remove" if args.dry_run else "removed"
    kinds = {k: sum(1 for e in done.removed if e.kind == k) for k in KINDS}
    what = ", ".join(f"{n} {k}{'s' if n > 1 else ''}" for k, n in kinds.items() if n) or "nothing"
    print(f"{verb} {what} ({human(done.freed)}); the cache {'would hold' if args.dry_run else 'holds'} "
          f"{human(done.size_after)}")
    if done.busy:
        print(f"kept {len(done.busy)} entries a running batch holds: " +
              ", ".join(e.path.name for e in done.busy[:5]) + (" ..." if len(done.busy) > 5 else ""))
    return 0
