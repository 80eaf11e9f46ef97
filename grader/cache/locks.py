"""Locks on cache entries, and when each one was last used.

Every entry has lock files beside it (``flock``; the kernel releases them when a process dies):

* a build area ``<digest>/``: ``<digest>.lock``, held exclusively while it is built (parallel
  graders build one digest once), and ``<digest>.use``, held *shared* by every submission that
  runs the area's installs or copies packages out of it, from before it looks the area up until
  its scenarios have ended;
* a recording ``recordings/<key>/``: ``<key>.lock``, held exclusively while it is looked up,
  recorded and copied (a second submission with the same key waits for the first's recording).

``grader cache prune`` and the size cap remove an entry only after taking each of its locks
exclusively *without waiting*: an entry any running batch holds is skipped, never deleted. They
also unlink the lock files of what they remove, so a lock is taken by :func:`acquire`, which
checks after locking that the file it locked is still the one at that path (else it locks the
new one): a process that opened the old file before it was unlinked never works under a lock
nobody else can see.

Last use is the modification time of the entry's lock file (``.use`` for a build area,
``.lock`` for a recording), set with ``os.utime`` each time the entry is taken: no shared index
to rewrite, so concurrent batches on one cache never lose each other's updates.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import threading
from pathlib import Path
from typing import Iterator


def acquire(path: Path, *, shared: bool = False, wait: bool = True) -> int | None:
    """An fd holding ``flock`` on ``path`` (created if missing), or None when ``wait`` is False
    and someone else holds a conflicting lock."""
    mode = (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | (0 if wait else fcntl.LOCK_NB)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, mode)
        except BlockingIOError:
            os.close(fd)
            return None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)                   # unlinked (pruned) while we waited: lock the new file


def release(fd: int) -> None:
    os.close(fd)                       # closing the last fd of the open file drops the flock


def touch(path: Path) -> None:
    """Mark the entry whose lock file is ``path`` as used now."""
    with contextlib.suppress(OSError):
        os.utime(path)


@contextlib.contextmanager
def locked(path: Path, *, shared: bool = False) -> Iterator[None]:
    """Hold ``path``'s lock (waiting for it) for the ``with`` block."""
    fd = acquire(path, shared=shared)
    assert fd is not None
    try:
        yield
    finally:
        release(fd)


class Holds:
    """Shared locks on the entries one submission is using, released together (``close``).

    ``grade_submission`` holds its build area (and the areas it copied packages from) until its
    scenarios have ended, so no prune removes the installs a running scenario starts nodes from.
    """

    def __init__(self) -> None:
        self._fds: dict[Path, int] = {}
        self._lock = threading.Lock()

    def hold(self, lock_file: Path) -> None:
        """Take ``lock_file`` shared (waiting while a prune removes that entry) and mark it used."""
        lock_file = Path(lock_file)
        with self._lock:
            if lock_file in self._fds:
                touch(lock_file)
                return
        fd = acquire(lock_file, shared=True)
        assert fd is not None
        touch(lock_file)
        with self._lock:
            if lock_file in self._fds:
                release(fd)
            else:
                self._fds[lock_file] = fd

    def close(self) -> None:
        with self._lock:
            fds, self._fds = list(self._fds.values()), {}
        for fd in fds:
            release(fd)

    def __enter__(self) -> "Holds":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def use_lock(area: Path) -> Path:
    """The lock file a build area is held by while in use."""
    return Path(area).parent / f"{Path(area).name}.use"


def build_lock(area: Path) -> Path:
    """The lock file a build area is held by while it is built."""
    return Path(area).parent / f"{Path(area).name}.lock"
