"""Capped output logs: a process's stdout/stderr pipe drained into a log file of bounded size.

Writing straight to a file lets one ``while True: print(...)`` fill the disk (a subscriber that
printed 200 MB left a 229 MB output folder) and, since the driver republishes every line into
the bag, the scenario process's memory. Here the grader owns the pipe: the first ``cap`` bytes
go to the log, then one line says where and why it was cut; the rest is drained without
copying (``splice`` to ``/dev/null``) so the writer never blocks on a full pipe, and counted.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Callable

DEFAULT_CAP_BYTES = 10 * 2**20
_CHUNK = 1 << 16
_DRAIN = 1 << 20


def _mib(n: int) -> str:
    return f"{n / 2**20:g} MiB"


class CappedLog:
    """Drains ``fd`` (the read end of a pipe) into ``path`` until EOF, keeping ``cap`` bytes."""

    def __init__(self, fd: int, path: Path, cap: int, *, stream: str,
                 on_cut: Callable[[str, int], None] | None = None) -> None:
        self.fd, self.path, self.cap, self.stream = fd, Path(path), cap, stream
        self.on_cut = on_cut
        self.written = 0
        self.dropped = 0
        self.cut = False
        self._file = open(self.path, "ab", buffering=0)
        self._thread = threading.Thread(target=self._run, name=f"capped-{self.path.name}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while not self.cut:
                chunk = os.read(self.fd, _CHUNK)
                if not chunk:
                    return
                room = self.cap - self.written
                self._file.write(chunk[:room])
                self.written += min(room, len(chunk))
                if len(chunk) > room:
                    self.dropped += len(chunk) - room
                    self.cut = True
                    self._file.write((f"\n[grader] {self.stream} cut: the log reached its limit of "
                                      f"{_mib(self.cap)}; further output is discarded\n").encode())
                    if self.on_cut is not None:
                        try:
                            self.on_cut(self.stream, self.cap)
                        except Exception:  # noqa: BLE001 - reporting must not stop the draining
                            pass
            self._drain()
        except OSError:
            pass
        finally:
            if self.dropped:
                self._file.write(f"[grader] {self.dropped} bytes of {self.stream} discarded after the "
                                 f"{_mib(self.cap)} limit\n".encode())
            self._file.close()
            os.close(self.fd)

    def _drain(self) -> None:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            while True:
                try:
                    n = os.splice(self.fd, devnull, _DRAIN)
                except (OSError, AttributeError):
                    n = len(os.read(self.fd, _DRAIN))
                if not n:
                    return
                self.dropped += n
        finally:
            os.close(devnull)

    def join(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)

    def flush(self) -> None:
        """Unbuffered already; kept so callers can treat it like a file."""
