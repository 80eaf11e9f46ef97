"""The batch's slots: --jobs is an upper bound; beyond the cores a slot waits for the CPUs to
have room (so a saturated machine grades at --jobs 8 as at --jobs 2). Pure: fake pressure and clock."""

from __future__ import annotations

import threading
import time

import pytest

from grader.grading import schedule
from grader.grading.schedule import Slots, cpu_pressure


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def take(slots: Slots, n: int) -> tuple[list[threading.Event], list[threading.Thread]]:
    """Start ``n`` threads that each hold a slot until released; returns their release events."""
    release = [threading.Event() for _ in range(n)]

    def hold(ev: threading.Event) -> None:
        with slots.taken():
            ev.wait(5)

    threads = [threading.Thread(target=hold, args=(ev,), daemon=True) for ev in release]
    for t in threads:
        t.start()
    return release, threads


def settle() -> None:
    time.sleep(0.1)


def test_slots_beyond_the_cores_wait_for_room_and_ramp_up() -> None:
    pressure = [99.0]
    clock = Clock()
    slots = Slots(8, pressure=lambda: pressure[0], cores=2, clock=clock, poll_s=0.01)
    release, threads = take(slots, 4)
    settle()
    assert slots.active == 2                       # saturated: one per core, as --jobs 2
    pressure[0] = 10.0
    settle()
    assert slots.active == 3                       # room: one more ...
    settle()
    assert slots.active == 3                       # ... and the next only RAMP_S later
    clock.t += schedule.RAMP_S
    settle()
    assert slots.active == 4 and slots.peak == 4
    for ev in release:
        ev.set()
    for t in threads:
        t.join(2)
    assert slots.active == 0 and slots.deferred_s > 0


def test_within_the_cores_slots_never_wait_and_the_budget_still_bounds() -> None:
    slots = Slots(2, pressure=lambda: 100.0, cores=4, poll_s=0.01)
    release, threads = take(slots, 3)
    settle()
    assert slots.active == 2                       # --jobs 2 bounds it, pressure or not
    for ev in release:
        ev.set()
    for t in threads:
        t.join(2)
    with pytest.raises(ValueError):
        Slots(0)


def test_cpu_pressure_reads_psi_or_falls_back_to_the_load(tmp_path, monkeypatch) -> None:
    psi = tmp_path / "cpu"
    psi.write_text("some avg10=12.50 avg60=3.00 avg300=1.00 total=1\nfull avg10=0.00 avg60=0.00 avg300=0.00 total=0\n")
    monkeypatch.setattr(schedule, "PRESSURE_FILE", str(psi))
    assert cpu_pressure() == 12.5
    monkeypatch.setattr(schedule, "PRESSURE_FILE", str(tmp_path / "absent"))
    assert 0.0 <= cpu_pressure()
