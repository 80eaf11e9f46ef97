"""All files or none: outputs are first written into a staging folder inside OUT, then moved
into place; if any move fails (or the user presses Ctrl-C), the files already moved are put
back as they were.

The staging folder sits inside OUT so every move is a same-filesystem ``os.replace`` (atomic
per file), and each replaced file is first hard-linked to a backup, so the target always
exists. A SIGKILL in the middle of the moves can leave some files new and some old; re-running
the same merge then finishes the job (a merge is idempotent).
"""

from __future__ import annotations

import fcntl
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from grader.errors import GraderError

@contextmanager
def locked(out: Path) -> Iterator[None]:
    """One merge at a time per OUT: an exclusive lock on the folder itself (no lock file left
    behind; the kernel releases it if we die)."""
    fd = os.open(out, os.O_RDONLY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise GraderError(f"another `grader scores merge` is running on {out}; wait for it "
                              "to finish") from None
        yield
    finally:
        os.close(fd)


@contextmanager
def staging(out: Path) -> Iterator[Path]:
    """A fresh folder inside ``out`` for the new files; removed afterwards in every case."""
    stage = Path(tempfile.mkdtemp(prefix=".grader-stage-", dir=out))
    try:
        yield stage
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def changed_files(stage: Path, out: Path) -> list[Path]:
    """Staged files (relative paths) whose content differs from what ``out`` already has."""
    changed = []
    for path in sorted(p for p in stage.rglob("*") if p.is_file()):
        rel = path.relative_to(stage)
        target = out / rel
        if not target.is_file() or target.read_bytes() != path.read_bytes():
            changed.append(rel)
    return changed


def commit(stage: Path, out: Path, files: list[Path]) -> list[Path]:
    """Move ``files`` (relative to ``stage``) into ``out``, in the given order, all or none.
    Returns the target paths."""
    backups = stage.parent / f"{stage.name}.old"
    done: list[tuple[Path, Path | None]] = []
    try:
        for rel in files:
            target = out / rel
            backup = None
            if target.exists():
                backup = backups / rel
                backup.parent.mkdir(parents=True, exist_ok=True)
                try:
                    os.link(target, backup)
                except OSError:                    # a filesystem without hard links
                    shutil.copy2(target, backup)
            target.parent.mkdir(parents=True, exist_ok=True)
            _move(stage / rel, target)
            done.append((target, backup))
    except BaseException:
        for target, backup in reversed(done):
            if backup is not None:
                os.replace(backup, target)
            else:
                target.unlink(missing_ok=True)
        raise
    finally:
        shutil.rmtree(backups, ignore_errors=True)
    return [target for target, _ in done]


def _move(src: Path, dst: Path) -> None:
    os.replace(src, dst)
