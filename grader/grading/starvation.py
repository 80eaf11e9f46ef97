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
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Any, Callable

RETRIES = 2
PAUSE_S = 5.0
#: the probe process of ``cpu_wait`` (the first present is used), what to call it, and the
#: largest share of its lifetime it may wait for a CPU (s per s, summed over its threads). A
#: scenario without a simulator (Lab 3's subscriber, fed by a replay) has the grader's own
#: scenario process, whose threads (executor, recorder) wait more for the same load: measured
#: over 502 overloaded recordings that have both, it waited a median 1.4 s per s (10th-90th
#: percentile 0.94-1.67) when the simulator waited 0.4-0.6
PROBES = {"turtlesim": ("the simulator", 0.5), "scenario": ("the grader's scenario process", 1.5)}


def starved(record: dict[str, Any]) -> str | None:
    """Why the recording is not a measurement of the code (None: it is)."""
    waits = record.get("cpu_wait") or {}
    name = next((n for n in PROBES if n in waits), None)
    if name is None:
        return None
    what, most = PROBES[name]
    share = (waits[name] or {}).get("wait_share")
    if isinstance(share, (int, float)) and share > most:
        return f"{what} waited {share:.2f} s per second for a CPU (at most {most:g})"
    return None


def record_unstarved(record_once: Callable[[], dict[str, Any]], folder: Path,
                     pause: Callable[[float], None] = time.sleep) -> dict[str, Any]:
    """``record_once()`` (which records into ``folder``) until a recording is not starved, at most
    1 + ``RETRIES`` times; the record says how many were starved (``starved``)."""
    reasons: list[str] = []
    for attempt in range(1 + RETRIES):
        record = record_once()
        why = starved(record)
        if why is None:
            break
        reasons.append(why)
        if attempt < RETRIES:
            shutil.rmtree(folder, ignore_errors=True)
            pause(PAUSE_S)
    if not reasons:
        return record
    kept_starved = why is not None
    record["starved"] = {"recordings": len(reasons) + (0 if kept_starved else 1), "starved": len(reasons),
                         "reasons": reasons, "kept": "starved" if kept_starved else "not starved"}
    if kept_starved:
        record.setdefault("errors", []).append(
            f"{reasons[-1]} in each of {len(reasons)} recordings: the machine was too busy, or this "
            "submission's own processes kept the CPUs busy (a loop that never sleeps); if not the "
            "latter, grade this submission again when the machine is quiet (its grade may differ)")
    path = Path(folder) / "scenario.json"
    if path.is_file():
        saved = json.loads(path.read_text())
        saved["starved"] = record["starved"]
        path.write_text(json.dumps(saved, indent=1, default=str))
    return record
