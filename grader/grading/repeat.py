"""Repeated runs of a scenario (``repeat: N`` in the rubric) and the median that grades them.

Most items are decided by one run: the scenario's placements hold the turtle still until a goal
is handed over, and the analyzers judge quantities that do not depend on scheduling (a command
computed from a placed pose, a rate over seconds). An item that stays sensitive to a few
milliseconds (a deadline its submission meets by a hair, a chaotic controller's arrival) gets a
scenario that runs N times (N odd); each item of the scenario is graded by the median of its N
findings, and the result says so (``decided``: runs, how many agreed, every run's outcome).

Runs stop early once the median is settled: when more than half of the planned runs agree on
every item of the scenario, further runs cannot move the median (``repeat: 3`` costs two runs
when they agree, three when they do not).

``repeat_by: worst`` grades each item by its worst run instead: for what must work every time
the node starts. The case is a request sent before DDS has matched the service (chase's
``/spawn`` after a ``wait_for_service`` that does not wait): on a quiet machine it was lost in
23 of 23 runs, under a load of 9-16 it was answered in 6 of 36, so the median of 3 would pay
such code in about 7 % of gradings, the worst of 3 in about 0.5 % (0.17 cubed). Its runs stop
at the first run that fails every item (nothing can be lower); code that works costs every run.

A scenario that ran on lockstep simulated time with every tick quiet (:mod:`grader.scenario.lockstep`)
is not run again: its runs would be the same run. Its items say ``decided``: one lockstep run.

Folders: run 1 is ``scenarios/<id>/`` as for any scenario; run k is ``scenarios/<id>.run<k>/``
(a scenario id has no dot), so a regrade finds every run on disk.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from grader.contracts.output_folder import SCENARIO_JSON
from grader.contracts.scenario_record import ScenarioRecord
from grader.rubric.score import _RANK

RUN_SUFFIX = ".run"
_RUN = re.compile(r"^(?P<id>[A-Za-z0-9_-]+)\.run(?P<k>[2-9][0-9]*)$")


def run_folder(scenarios_dir: Path, sc_id: str, k: int) -> Path:
    """Where run ``k`` (1-based) of scenario ``sc_id`` is recorded."""
    return scenarios_dir / (sc_id if k == 1 else f"{sc_id}{RUN_SUFFIX}{k}")


def run_folders(scenarios_dir: Path, sc_id: str) -> list[Path]:
    """The recorded runs of ``sc_id``, run 1 first (only run 1 when it was not repeated)."""
    more = []
    if scenarios_dir.is_dir():
        for p in scenarios_dir.iterdir():
            m = _RUN.match(p.name)
            if m and m["id"] == sc_id and p.is_dir():
                more.append((int(m["k"]), p))
    return [scenarios_dir / sc_id] + [p for _, p in sorted(more)]


def scenario_of(folder_name: str) -> str:
    """The scenario id of a run folder's name (``ex3_action.run2`` -> ``ex3_action``)."""
    m = _RUN.match(folder_name)
    return m["id"] if m else folder_name


def outcome(finding: Any) -> tuple[str, float]:
    """What a run concluded about an item, for comparing runs: status and fraction."""
    return str(finding.status), round(float(finding.fraction), 4)


#: the lowest outcome a run can have: the worst of the runs cannot go below it
LOWEST = ("fail", 0.0)


def settled(outcomes_per_item: Iterable[Sequence[tuple[str, float]]], planned: int, by: str = "median") -> bool:
    """True when the runs so far decide every item, whatever the remaining ones would say: for
    the median, more than half of the ``planned`` runs share one outcome; for the worst, a run
    has the lowest outcome (fail, 0)."""
    if by == "worst":
        return all(LOWEST in lst for lst in outcomes_per_item)
    return all(lst and Counter(lst).most_common(1)[0][1] * 2 > planned for lst in outcomes_per_item)


def lockstep_record_exact(record: ScenarioRecord) -> bool:
    """A record of a lockstep run with every tick quiet and no wait cut short by its wall-time
    limit: running it again repeats it exactly."""
    return record.exact_lockstep


def exact_lockstep(folder: Path) -> bool:
    """Whether the recorded run in ``folder`` (its scenario.json) was an exact lockstep run."""
    try:
        return ScenarioRecord.read(Path(folder) / SCENARIO_JSON).exact_lockstep
    except (OSError, ValueError):
        return False


def run_until_settled(record_one: Callable[[int, Path], ScenarioRecord], scenarios_dir: Path, sc_id: str,
                      planned: int, settles: Callable[[list[Path]], bool] | None) -> ScenarioRecord:
    """Record run 1, 2, ... of a scenario (``record_one(k, folder)``) until ``planned`` runs, or
    until ``settles`` says the runs so far decide every item. The record: the first
    run's, with every run's errors and the times of all of them (``runs``: how many)."""
    records: list[ScenarioRecord] = []
    for k in range(1, planned + 1):
        records.append(record_one(k, run_folder(scenarios_dir, sc_id, k)))
        if k == 1 and lockstep_record_exact(records[0]):
            break
        if settles is not None and k < planned and \
                settles([run_folder(scenarios_dir, sc_id, i) for i in range(1, k + 1)]):
            break
    if len(records) == 1:
        return records[0]
    return records[0].amended({
        "errors": [f"run {k}: {e}" if k > 1 else e for k, r in enumerate(records, 1) for e in r.errors],
        "parent_wall_s": round(sum(float(r.parent_wall_s or 0.0) for r in records), 3),
        "active_s": round(sum(float(r.active_s or 0.0) for r in records), 3),
        "runs": len(records)})


def repeated_finding(findings: Sequence[Any], planned: int, lockstep: bool = False, by: str = "median") -> Any:
    """One item's finding over its runs: the median (by fraction, then status: fail < partial <
    error < pass), or the lowest (``by="worst"``), with ``decided`` saying how it was decided
    (``repeat_by``: the scenario's field, ``median`` or ``worst``). One finding: itself,
    ``decided`` = one run (``lockstep``: one exact lockstep run, which a repetition repeats)."""
    if len(findings) == 1 and lockstep:
        return replace(findings[0], decided={"by": "one lockstep run", "runs": 1, "stable": True})
    if len(findings) == 1 and planned <= 1:
        return replace(findings[0], decided={"by": "one run", "runs": 1})
    order = sorted(range(len(findings)),
                   key=lambda i: (round(float(findings[i].fraction), 4), _RANK.get(str(findings[i].status), 2)))
    chosen = findings[order[0] if by == "worst" else order[(len(order) - 1) // 2]]
    mine = outcome(chosen)
    agree = sum(1 for f in findings if outcome(f) == mine)
    decided = {
        "by": f"{by} of repeated runs", "repeat_by": by, "runs": len(findings), "planned": planned, "agree": agree,
        "stable": agree == len(findings),
        "outcomes": [{"run": i + 1, "status": f.status, "fraction": round(float(f.fraction), 4),
                      "value": f.value} for i, f in enumerate(findings)],
    }
    return replace(chosen, decided=decided)
