"""A recording made while the machine starved the scenario of CPU is made again.

A scenario runs in real time. On a saturated machine its processes are runnable but wait for a
CPU: the simulator's ticks come late and in bursts, a student's 30 Hz timer fires at 20 Hz, and
the grade measures the machine instead of the code. Measured on this shared 2-core machine
(``cpu_wait`` in scenario.json, :mod:`grader.scenario.cpuwait`), the correct first_nodes circle
scenario twice in a row: the simulator waited 1.02 s per second of its life for a CPU and the
reference failed `circle.period` and `circle.keeps_moving`; the next run it waited 0.20 s per
second and passed everything (0.10 at load 20 with nothing else of ours running).

The simulator is the probe: the grader's own process with the same small load in every scenario,
so its wait share says how starved the run was whatever the student's code does (a student's
node may spin a core on purpose); without a simulator, the scenario process is (``PROBES``).
Above the probe's limit the recording is made again, up to ``RETRIES`` times ``PAUSE_S``
apart; a scenario starved every time keeps its last recording, and the result says so in its
problems (re-grade that submission when the machine is quiet). The problem names both causes: a
Lab 3 server without ``self.rate.sleep()`` starved the simulator (1.0-1.8 s per s) in all 9
recordings of three gradings of it, and "the machine was too busy" alone was not true there; its
processes' own CPU time does not tell the two apart (0.56 s per s for it, up to 0.63 for servers
that starved nothing: bench_flake's Lab 3 class).

A CPU quota (a container's, ``grader.sandbox.allotment``) starves a recording without a long
run queue: the whole grader group is throttled. Its own counter says so (``cpu_quota`` in the
record: the seconds the quota held the group back while the scenario was recorded); above
``QUOTA_THROTTLED_MAX`` s per s the recording is starved too.

The limits are those of a 1x recording; above them a recording is made again, and one at K x
(``--time-scale``) goes again at 1x (``grader.grading.timescale.too_busy_for``). But at K x a
stall of the same wall length is K times as long in simulated time, which is what the items
measure: the first_nodes greeting_timer fixture (correct: a 0.1 s controller timer) at 4x beside
a busy suite, its simulator waiting 0.43 s per second (under the 1x limit), sent two commands
1.16 s of simulated time apart and failed `circle.keeps_moving` (turtlesim's 1 s command
timeout); at 1x the same wait is a 0.29 s gap. So a timing item that lost points on a K x
recording is judged against a K-th of the limits (``starvation(record, scale=K)``): above them
it is an error, recorded again at 1x. A pass stands (starvation only costs), so the loaded
machine's K x recordings are kept: at 4x beside make test the simulator waited 0.21-0.46 s per
second (10th-90th percentile of 283), above the K-th nearly always.

Who starved it decides what a starved recording costs (``Starvation.own``): where the student's
processes took most of the CPUs the grader has (``OWN_CPU_SHARE``, CPU s per s, of at most one
CPU, their sandbox's quota) or hit that quota, the student's code did it (a loop that never
sleeps) and its grade stands, as measured. Otherwise the grading machine did, and an item whose
verdict depends on timing cannot lose its points on that recording (``grader.grading.analysis``):
it is an ``error`` saying so, and ``grader grade`` records it again at the end of the batch.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from dataclasses import dataclass
from typing import Callable

from grader.contracts.output_folder import SCENARIO_JSON
from grader.contracts.scenario_record import ScenarioRecord
from grader.sandbox import allotment

RETRIES = 2
PAUSE_S = 5.0
#: the probe process of ``cpu_wait`` (the first present is used), what to call it, and the
#: largest share of its lifetime it may wait for a CPU (s per s, summed over its threads). A
#: scenario without a simulator (Lab 3's subscriber, fed by a replay) has the grader's own
#: scenario process, whose threads (executor, recorder) wait more for the same load: measured
#: over 502 overloaded recordings that have both, it waited a median 1.4 s per s (10th-90th
#: percentile 0.94-1.67) when the simulator waited 0.4-0.6
PROBES = {"turtlesim": ("the simulator", 0.5), "scenario": ("the grader's scenario process", 1.5)}


#: s per s of a recording that the grader's CPU quota may hold its group back (the kernel's
#: throttled time, summed over the CPUs the group ran on): Lab 3's controller scenario, two side
#: by side under 0.5 CPU, was held back 0.28-0.39 s per s and alone 0.08
QUOTA_THROTTLED_MAX = 0.25
#: the student's processes' CPU s per s (of the least of 1 CPU and the CPUs the grader has) at
#: or above which a starved recording is their own doing: a loop that never sleeps takes its
#: whole quota (1.0); the Lab 3 reference's nodes take 0.03-0.08 (benchmarks/bench_executor.py)
OWN_CPU_SHARE = 0.8

#: the time scale a result with starved timing items is recorded again at (``grader grade`` at
#: the end of its batch, the Gradescope run, a self-check whose starved items were at K x): at
#: 1x a stall of the machine is shortest in simulated time, and the run needs a K-th of the CPU
REGRADE_TIME_SCALE = 1.0


@dataclass(frozen=True)
class Starvation:
    """Why a recording is not a measurement of the code, and whether the code itself did it."""

    reason: str
    own: bool = False


def recorded_scale(record: ScenarioRecord) -> float:
    """How many times faster than real time the recording ran (``time_scale.used``; 1 without)."""
    ts = record.time_scale
    used = ts.used if ts is not None and "used" in ts.model_fields_set else 1.0
    return max(1.0, float(used)) if isinstance(used, (int, float)) else 1.0


def _bound(most: float, scale: float) -> str:
    return f"at most {most:g}" if scale == 1.0 else f"at most {most:g} at {scale:g}x: {most * scale:g} at 1x"


def _probe_waited(record: ScenarioRecord, scale: float) -> str | None:
    waits = record.cpu_wait or {}
    name = next((n for n in PROBES if n in waits), None)
    if name is None:
        return None
    what, at_1x = PROBES[name]
    most = at_1x / scale
    share = (waits[name] or {}).get("wait_share")
    if isinstance(share, (int, float)) and share > most:
        return f"{what} waited {share:.2f} s per second for a CPU ({_bound(most, scale)})"
    return None


def _quota_throttled(record: ScenarioRecord, scale: float) -> str | None:
    quota = record.cpu_quota or {}
    held, wall = quota.get("throttled_s"), quota.get("wall_s")
    if not isinstance(held, (int, float)) or not wall:
        return None
    share = held / wall
    most = QUOTA_THROTTLED_MAX / scale
    if share > most:
        return (f"the grading machine's CPU quota ({quota.get('cpus', 0):g} CPU) held the grader back "
                f"{share:.2f} s per second ({_bound(most, scale)})")
    return None


def _students_busy(record: ScenarioRecord) -> str | None:
    """The student's processes took the CPUs themselves (None: they did not)."""
    waits = record.cpu_wait or {}
    cpu = sum(float((w or {}).get("cpu_s") or 0.0) for n, w in waits.items() if n not in PROBES)
    alive = max((float((w or {}).get("alive_s") or 0.0) for n, w in waits.items() if n not in PROBES), default=0.0)
    capacity = min(1.0, float((record.cpu_quota or {}).get("cpus") or 1.0))
    if alive > 0 and cpu / alive >= OWN_CPU_SHARE * capacity:
        return f"the submission's own processes used {cpu / alive:.2f} CPU s per second"
    throttled = ((record.sandbox or {}).get("counters") or {}).get("cpu_throttled_s", 0.0)
    if throttled and throttled >= 1.0:
        return f"the submission's own processes were held at their CPU limit for {throttled:.1f} s"
    return None


def starvation_proof_lockstep(record: ScenarioRecord) -> bool:
    """A lockstep run whose every tick waited for every process to be quiet: each node saw the
    same messages at the same simulated times however slow the machine was, so a starved CPU
    made it slower, not different (the Lab 3 reference's ex3_action under a 0.5-CPU quota:
    recorded three times, 121 s each, for nothing). Weaker than ``ScenarioRecord.exact_lockstep``
    (a repeat's rule, which also needs no wall cut and no error): a cut wait is not starvation."""
    ls = record.lockstep
    return ls is not None and bool(ls.used) and not ls.fallback and ls.quiet_timeouts == 0


def starvation(record: ScenarioRecord, scale: float = 1.0) -> Starvation | None:
    """Why the recording is not a measurement of the code (None: it is), and who caused it.
    ``scale``: the limits are a ``scale``-th of those of a 1x recording (a timing item's verdict
    on a recording made ``scale`` times faster than real time, :func:`recorded_scale`)."""
    if starvation_proof_lockstep(record):
        return None
    reason = _probe_waited(record, scale) or _quota_throttled(record, scale)
    if reason is None:
        return None
    busy = _students_busy(record)
    return Starvation(f"{reason}; {busy}" if busy else reason, own=busy is not None)


def starved(record: ScenarioRecord) -> str | None:
    """Why the recording is not a measurement of the code (None: it is)."""
    found = starvation(record)
    return found.reason if found else None


def measure_quota(record_once: Callable[[], ScenarioRecord]) -> Callable[[], ScenarioRecord]:
    """``record_once`` that also keeps, in its record, how long the grader's CPU quota held the
    grader back while it ran (``cpu_quota``; nothing without a quota)."""
    def once() -> ScenarioRecord:
        given = allotment.current()
        before, t0 = allotment.throttled_s(given), time.monotonic()
        record = record_once()
        after = allotment.throttled_s(given)
        if before is not None and after is not None:
            record = record.amended({"cpu_quota": {"cpus": given.quota_cpus, "throttled_s": round(after - before, 3),
                                                   "wall_s": round(time.monotonic() - t0, 3)}})
        return record
    return once


def record_unstarved(record_once: Callable[[], ScenarioRecord], folder: Path,
                     pause: Callable[[float], None] = time.sleep) -> ScenarioRecord:
    """``record_once()`` (which records into ``folder``) until a recording is not starved, at most
    1 + ``RETRIES`` times; the record says how many were starved (``starved``)."""
    reasons: list[str] = []
    once = measure_quota(record_once)
    for attempt in range(1 + RETRIES):
        record = once()
        found = starvation(record)
        if found is None:
            break
        reasons.append(found.reason)
        if found.own:           # the code's own loop: another recording starves alike
            break
        if attempt < RETRIES:
            shutil.rmtree(folder, ignore_errors=True)
            pause(PAUSE_S)
    if not reasons:
        _save(folder, record, "cpu_quota")
        return record
    kept_starved = found is not None
    own = bool(found is not None and found.own)
    note = {"recordings": len(reasons) + (0 if kept_starved else 1), "starved": len(reasons),
            "reasons": reasons, "kept": "starved" if kept_starved else "not starved", "own": own}
    errors = list(record.errors)
    if own:
        errors.append(f"{reasons[-1]}: this submission's own processes kept the CPUs busy (a loop that never "
                      "sleeps), so its timing was measured as it ran")
    elif kept_starved:
        errors.append(
            f"{reasons[-1]} in each of {len(reasons)} recordings: the grading machine was too busy; an item "
            "that depends on timing and lost points on this recording is not charged for them (it is an error "
            "until it is measured on a quieter machine)")
    record = record.amended({"starved": note, "errors": errors} if own or kept_starved else {"starved": note})
    _save(folder, record, "starved", "cpu_quota")
    return record


def _save(folder: Path, record: ScenarioRecord, *keys: str) -> None:
    """Copy ``keys`` of the record (those it has) into the folder's ``scenario.json``."""
    given = record.to_json()
    present = {k: given[k] for k in keys if k in given}
    if present:
        ScenarioRecord.amend(Path(folder) / SCENARIO_JSON, present)
