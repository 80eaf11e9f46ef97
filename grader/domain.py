"""ROS_DOMAIN_ID leases: every run gets a domain no other grader process on this machine uses.

Isolation by domain (plus localhost-only discovery) is what keeps parallel grading runs from
seeing each other's topics. Leases are ``flock``-ed lock files, so they are released by the
kernel even when a grader process is SIGKILLed, and they work across unrelated processes.
"""

from __future__ import annotations

import fcntl
import os
import random
from pathlib import Path

from grader.errors import GraderError

#: Fast DDS maps a domain to UDP ports 7400 + 250 * id (+ offsets); ids above 232 overflow.
#: 0 is everyone's default domain, so never lease it.
DOMAIN_MIN = 1
DOMAIN_MAX = 99


def lock_dir() -> Path:
    base = Path(os.environ.get("GRADER_LOCK_DIR") or Path("/tmp") / f"grader-domains-{os.getuid()}")
    base.mkdir(parents=True, exist_ok=True)
    return base


class DomainLease:
    """An exclusively held ROS_DOMAIN_ID; release() (or leaving the ``with``) gives it back."""

    def __init__(self, domain_id: int, fd: int) -> None:
        self.domain_id = domain_id
        self._fd: int | None = fd

    def release(self) -> None:
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> "DomainLease":
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __repr__(self) -> str:
        return f"DomainLease({self.domain_id})"


def lease_domain(lo: int = DOMAIN_MIN, hi: int = DOMAIN_MAX) -> DomainLease:
    """Lease a free domain id in [lo, hi], starting at a random one to spread parallel runs."""
    ids = list(range(lo, hi + 1))
    start = random.randrange(len(ids))
    directory = lock_dir()
    for domain_id in ids[start:] + ids[:start]:
        fd = os.open(directory / f"{domain_id}.lock", os.O_RDWR | os.O_CREAT, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            continue
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        return DomainLease(domain_id, fd)
    raise GraderError(f"all ROS domain ids {lo}..{hi} are in use by other grader runs; "
                      "lower the number of parallel jobs (--jobs) and try again.")
