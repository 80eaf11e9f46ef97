"""The cache folder as entries: what it holds (``grader cache info``), pruning it (``grader cache
prune``) and the size cap every batch enforces when it ends.

Measured after grading ~130 submissions of four labs: 590 MB in 226 entries, ~4.5 MB a
submission (build areas with their ``build/`` trees most of it, recordings 136 MB), so a semester
of four labs, 200 students and a few regrades is several GB. Hence a cap (``DEFAULT_MAX_SIZE``,
5 GB; ``--cache-max-size`` or ``$GRADER_CACHE_MAX_SIZE``, ``0`` for none), enforced least recently
used first when a batch (``grader grade``, ``grader check``) ends.

An entry is removed only with every lock of it taken without waiting (``grader.cache.locks``):
one a running batch holds (a build area whose installs its scenarios run, a recording being
made or copied) is skipped and stays. Sizes are disk usage (allocated blocks, as ``du``).
Kinds: ``build`` (a submission's build area), ``support build`` (a build area a support package
is taken from, ``packages/*.json``), ``recording``, ``temporary`` (staging folders and half-written
entries a grader left when it was killed: removed once their process is gone or after a day).
"""

from __future__ import annotations

import json
import os
import threading
import re
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from grader.cache import locks
from grader.errors import GraderError

DEFAULT_MAX_SIZE = 5 * 10**9
MAX_SIZE_ENV = "GRADER_CACHE_MAX_SIZE"
LAST_BATCH = "last_batch.json"
RECORDINGS = "recordings"
PACKAGES = "packages"
STALE_TEMPORARY_S = 24 * 3600
KINDS = ("build", "support build", "recording", "temporary")
_TEMP = re.compile(r"^\.(?:staging|support)-(\d+)-|^\..*?\.(\d+)(?:\.\d+)?\.tmp$")
_UNITS = {"": 1, "b": 1, "k": 10**3, "kb": 10**3, "m": 10**6, "mb": 10**6, "g": 10**9, "gb": 10**9,
          "t": 10**12, "tb": 10**12, "kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40}


@dataclass
class Entry:
    """One removable thing in the cache folder."""

    kind: str
    path: Path
    locks: tuple[Path, ...]      # taken exclusively (without waiting) before removal; unlinked with it
    size: int
    created: float
    last_used: float
    removable: bool = True       # temporary entries of a running process are not


@dataclass
class Pruned:
    """What a prune removed, and what it left because a running batch holds it."""

    removed: list[Entry] = field(default_factory=list)
    busy: list[Entry] = field(default_factory=list)
    size_after: int = 0

    @property
    def freed(self) -> int:
        return sum(e.size for e in self.removed)


def parse_size(text: str) -> int:
    """``5G``, ``500MB``, ``1.5GiB``, ``0`` -> bytes."""
    m = re.fullmatch(r"\s*([0-9]+(?:\.[0-9]+)?)\s*([A-Za-z]*)\s*", str(text))
    unit = m.group(2).lower() if m else None
    if m is None or unit not in _UNITS:
        raise GraderError(f"cannot read {text!r} as a size: write e.g. 5G, 500M, 2GiB or 0 (bytes)")
    return int(float(m.group(1)) * _UNITS[unit])


def human(size: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(size) < 1000 or unit == "TB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1000
    return f"{size:.1f} TB"


def max_size(option: str | None = None) -> int | None:
    """The cap: ``option`` (``--cache-max-size``), else ``$GRADER_CACHE_MAX_SIZE``, else 5 GB;
    None when it is 0 (no cap)."""
    text = option if option is not None else os.environ.get(MAX_SIZE_ENV)
    size = DEFAULT_MAX_SIZE if text in (None, "") else parse_size(text)
    return size or None


def disk_usage(path: Path) -> int:
    """Allocated bytes of a file or folder tree (symlinks not followed)."""
    try:
        st = os.lstat(path)
    except OSError:
        return 0
    total = st.st_blocks * 512
    if not os.path.isdir(path) or os.path.islink(path):
        return total
    stack = [str(path)]
    while stack:
        try:
            with os.scandir(stack.pop()) as it:
                for d in it:
                    try:
                        s = d.stat(follow_symlinks=False)
                    except OSError:
                        continue
                    total += s.st_blocks * 512
                    if d.is_dir(follow_symlinks=False):
                        stack.append(d.path)
        except OSError:
            continue
    return total


def _mtime(*paths: Path) -> float:
    for p in paths:
        try:
            return p.stat().st_mtime
        except OSError:
            continue
    return 0.0


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _support_roots(cache: Path) -> set[str]:
    roots = set()
    for f in (cache / PACKAGES).glob("*.json"):
        try:
            roots.add(Path(json.loads(f.read_text())["root"]).name)
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return roots


def _temporary(path: Path, now: float) -> Entry | None:
    m = _TEMP.match(path.name)
    if not m:
        return None
    pid = int(m.group(1) or m.group(2))
    mtime = _mtime(path)
    removable = not _alive(pid) or now - mtime > STALE_TEMPORARY_S
    return Entry("temporary", path, (), disk_usage(path), mtime, mtime, removable)


def entries(cache: Path) -> list[Entry]:
    """Every entry of the cache folder ``cache`` (build areas, recordings, temporary folders)."""
    cache = Path(cache)
    out: list[Entry] = []
    if not cache.is_dir():
        return out
    now = time.time()
    support = _support_roots(cache)
    for path in sorted(cache.iterdir()):
        if path.name.startswith("."):
            if (temp := _temporary(path, now)) is not None:
                out.append(temp)
        elif path.is_dir() and path.name not in (RECORDINGS, PACKAGES):
            result = path / "result.json"
            use, build = locks.use_lock(path), locks.build_lock(path)
            out.append(Entry("support build" if path.name in support else "build", path, (use, build),
                             disk_usage(path), _mtime(result, path), _mtime(use, result, path)))
    recordings = cache / RECORDINGS
    for path in sorted(recordings.iterdir()) if recordings.is_dir() else []:
        if path.name.startswith("."):
            if (temp := _temporary(path, now)) is not None:
                out.append(temp)
        elif path.is_dir():
            lock, source = recordings / f"{path.name}.lock", path / "source.json"
            out.append(Entry("recording", path, (lock,), disk_usage(path), _mtime(source, path),
                             _mtime(lock, source, path)))
    for path in sorted((cache / PACKAGES).glob(".*.tmp")):
        if (temp := _temporary(path, now)) is not None:
            out.append(temp)
    return out


def _remove(entry: Entry, dry_run: bool = False) -> bool:
    """Remove ``entry`` if no one holds it: every lock taken without waiting, then the entry
    and its lock files go (unlinked while held: see ``grader.cache.locks.acquire``).
    ``dry_run``: only whether it could be."""
    if not entry.removable:
        return False
    held: list[int] = []
    try:
        for lock in entry.locks:
            fd = locks.acquire(lock, wait=False) if lock.exists() or not dry_run else -1
            if fd is None:
                return False
            if fd >= 0:
                held.append(fd)
        if dry_run:
            return True
        if entry.path.is_dir() and not entry.path.is_symlink():
            shutil.rmtree(entry.path, ignore_errors=True)
        else:
            entry.path.unlink(missing_ok=True)
        for lock in entry.locks:
            lock.unlink(missing_ok=True)
        return True
    finally:
        for fd in held:
            locks.release(fd)


def _tidy(cache: Path) -> None:
    """Drop what points at nothing: support-package records of removed build areas, and lock
    files without their entry (taken first, so no one is using them)."""
    for f in (cache / PACKAGES).glob("*.json"):
        try:
            root = Path(json.loads(f.read_text())["root"])
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if not (root / "result.json").is_file():
            f.unlink(missing_ok=True)
    for lock in [*cache.glob("*.lock"), *cache.glob("*.use"), *(cache / RECORDINGS).glob("*.lock")]:
        if not lock.with_suffix("").exists():
            fd = locks.acquire(lock, wait=False)
            if fd is not None:
                try:
                    if not lock.with_suffix("").exists():
                        lock.unlink(missing_ok=True)
                finally:
                    locks.release(fd)


def prune(cache: Path, *, max_size: int | None = None, unused_since: float | None = None,
          older_than_s: float | None = None, everything: bool = False, dry_run: bool = False) -> Pruned:
    """Remove the entries not used since ``unused_since`` (epoch s), created more than
    ``older_than_s`` ago, or all (``everything``); then the least recently used until the
    cache is at most ``max_size`` bytes. Stale temporary folders always go; entries a running
    batch holds stay (``Pruned.busy``)."""
    cache = Path(cache)
    now = time.time()
    found = entries(cache)
    report = Pruned()
    doomed = [e for e in found if e.kind == "temporary" or everything
              or (unused_since is not None and e.last_used < unused_since)
              or (older_than_s is not None and now - e.created > older_than_s)]
    keep = [e for e in found if e not in doomed]
    if max_size is not None:
        total = sum(e.size for e in keep)
        for e in sorted(keep, key=lambda e: e.last_used):      # least recently used first
            if total <= max_size:
                break
            doomed.append(e)
            total -= e.size
    for e in doomed:
        if not e.removable:
            continue
        if _remove(e, dry_run):
            report.removed.append(e)
        else:
            report.busy.append(e)
    if not dry_run:
        _tidy(cache)
    gone = {id(e) for e in report.removed}
    report.size_after = sum(e.size for e in found if id(e) not in gone)
    return report


def enforce_cap(cache: Path, cap: int | None) -> Pruned | None:
    """The end of a batch: least recently used entries go until the cache fits ``cap``."""
    return prune(cache, max_size=cap) if cap else None


def info(cache: Path) -> dict[str, Any]:
    """Per kind: entries, bytes, oldest and newest last use; the total; the last batch's hits."""
    kinds: dict[str, dict[str, Any]] = {}
    found = entries(cache)
    for kind in KINDS:
        group = [e for e in found if e.kind == kind]
        kinds[kind] = {"entries": len(group), "bytes": sum(e.size for e in group),
                       "oldest_use": min((e.last_used for e in group), default=None),
                       "newest_use": max((e.last_used for e in group), default=None)}
    return {"cache": str(cache), "kinds": kinds, "total_bytes": sum(e.size for e in found),
            "entries": len(found), "last_batch": last_batch(cache)}


# -- hit counts of a batch -----------------------------------------------------------------

def submission_cache_use(build: Any, recordings: dict[str, dict], reuse: bool) -> dict[str, int]:
    """One graded submission's cache hits and misses (``GradedSubmission.cache``)."""
    use = {"builds_hit": int(bool(build and build.cached)), "builds_missed": int(bool(build and not build.cached)),
           "packages_reused": sum(1 for p in (build.packages.values() if build else ()) if p.reused_from)}
    if reuse:
        keyed = [r for r in recordings.values() if r.get("key")]
        use["recordings_hit"] = sum(1 for r in keyed if r.get("reused_from"))
        use["recordings_missed"] = len(keyed) - use["recordings_hit"]
    return use


def record_batch(cache: Path, uses: Iterable[dict[str, int]], pruned: Pruned | None) -> dict[str, Any]:
    """Write ``last_batch.json`` (atomically: concurrent batches each write a whole one)."""
    totals: dict[str, int] = {}
    n = 0
    for use in uses:
        n += 1
        for k, v in use.items():
            totals[k] = totals.get(k, 0) + int(v)
    doc = {"finished": time.time(), "submissions": n, **totals}
    if pruned is not None:
        doc.update(pruned_entries=len(pruned.removed), pruned_bytes=pruned.freed,
                   held_entries=len(pruned.busy), size_after=pruned.size_after)
    cache = Path(cache)
    cache.mkdir(parents=True, exist_ok=True)
    tmp = cache / f".{LAST_BATCH}.{os.getpid()}.{threading.get_ident()}.tmp"   # batches in threads too
    tmp.write_text(json.dumps(doc, indent=1))
    os.replace(tmp, cache / LAST_BATCH)
    return doc


def last_batch(cache: Path) -> dict[str, Any] | None:
    try:
        return json.loads((Path(cache) / LAST_BATCH).read_text())
    except (OSError, ValueError):
        return None


def hit_rate(hit: int, missed: int) -> str:
    return f"{hit}/{hit + missed} ({100 * hit / (hit + missed):.0f}%)" if hit + missed else "none looked up"


def end_batch(cache: Path, uses: Iterable[dict[str, int]], cap_option: str | None = None) -> dict[str, Any]:
    """What every batch does when it ends: the cap enforced (least recently used first), the
    hit counts written; returns them, with ``cap`` and a ``message`` when entries were removed
    or the cap could not be reached."""
    cap = max_size(cap_option)
    pruned = enforce_cap(cache, cap)
    doc = record_batch(cache, uses, pruned)
    doc["cap"] = cap
    if pruned is not None and cap is not None and (pruned.removed or pruned.size_after > cap):
        held = (f"; {len(pruned.busy)} entries held by running batches stay" if pruned.busy else "")
        doc["message"] = (f"cache {cache} over its {human(cap)} cap: removed {len(pruned.removed)} least "
                          f"recently used entries ({human(pruned.freed)}), now {human(pruned.size_after)}{held}")
    return doc
