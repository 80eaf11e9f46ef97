"""How much runs at once: a budget of concurrent scenarios (and builds) shared by a batch.

Scenarios are independent (each has its own simulator, recorder and graph), and most of their
time is real time (the turtle driving, replay pacing), not CPU. So the unit of parallelism is the
scenario, not the submission: ``--jobs N`` lets N scenarios (or builds) run at once across the
whole batch, and one submission's scenarios run side by side when slots are free. A self-check
then takes about as long as its longest scenario instead of the sum.
"""

from __future__ import annotations

import contextlib
import os
import threading
from typing import Iterator


def default_jobs() -> int:
    """Concurrent scenarios when the user does not say: scenarios mostly wait on real time,
    so twice the cores, at least 2."""
    return max(2, 2 * (os.cpu_count() or 1))


class Slots:
    """A counting semaphore with a name for what it bounds."""

    def __init__(self, n: int) -> None:
        if n < 1:
            raise ValueError("a batch needs at least one slot")
        self.n = n
        self._sem = threading.BoundedSemaphore(n)

    @contextlib.contextmanager
    def taken(self) -> Iterator[None]:
        with self._sem:
            yield
