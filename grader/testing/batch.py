"""A graded batch folder built from recorded bags alone (no build, no ROS): what ``grader regrade``
does, for tests and benchmarks of the reports.

``recorded_batch(bags_root, out, rubric)`` lays out ``out/<submission>/scenarios/<scenario>/``
as ``grader grade`` would (linking each recorded scenario folder: ``bag/`` and
``scenario.json``), regrades every submission from its bags and writes the batch files
(grades.csv, index.html). The committed Lab 3 bags are in ``fixtures/bags/lab3/<submission>/``.
``recorded_intake`` does the same for the submissions of an intake (grader.intake: a Canvas
download, a Gradescope export...), under their ids and with their arrival records, so the late
policy and the LMS ids go through the reports and exports as in a real grading.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from grader.testing.bags import FIXTURE_BAGS

LAB3_BAGS = FIXTURE_BAGS / "lab3"


def layout(bags_root: Path, out: Path, only: list[str] | None = None) -> list[str]:
    """Link ``bags_root/<sub>/<scenario>`` into ``out/<sub>/scenarios/<scenario>``; the ids."""
    ids = []
    for sub in sorted(p for p in Path(bags_root).iterdir() if p.is_dir()):
        if only and sub.name not in only:
            continue
        scenarios = [sc for sc in sorted(sub.iterdir()) if (sc / "bag").is_dir()]
        if not scenarios:
            continue
        for sc in scenarios:
            target = out / sub.name / "scenarios" / sc.name
            target.mkdir(parents=True, exist_ok=True)
            for entry in sc.iterdir():
                link = target / entry.name
                if not link.exists():
                    os.symlink(entry.resolve(), link)
        ids.append(sub.name)
    return ids


def recorded_batch(bags_root: Path, out: Path, rubric: Any, only: list[str] | None = None) -> list[Any]:
    """Regrade every submission laid out from ``bags_root`` into ``out``; the GradedSubmissions.
    Items whose scenario has no recording come out "not checked" (error)."""
    from grader.grading.outputs import write_batch_outputs  # noqa: PLC0415 - grading.outputs loads pandas, numpy (424 ms CPU), only on this path
    from grader.grading.pipeline import regrade_submission  # noqa: PLC0415 - grading.pipeline loads pandas, numpy (424 ms CPU), only on this path

    graded = [regrade_submission(out / sid, rubric) for sid in layout(bags_root, out, only)]
    write_batch_outputs(out, rubric)
    return graded


def recorded_intake(arrivals: list[Any], bags: dict[str, Path], out: Path, rubric: Any,
                    due_override: dict | None = None) -> list[Any]:
    """What ``grader grade`` does with an intake (grader.intake), with recorded bags standing in
    for the build and the scenarios: each gradable arrival's recordings (``bags[arrival.id]``, a
    folder of ``<scenario>/bag``) are laid out under its id with its arrival record, then
    regraded. The GradedSubmissions."""
    from grader.grading.outputs import write_batch_outputs  # noqa: PLC0415 - grading.outputs loads pandas, numpy (424 ms CPU), only on this path
    from grader.grading.pipeline import regrade_submission  # noqa: PLC0415 - grading.pipeline loads pandas, numpy (424 ms CPU), only on this path
    from grader.intake.model import write_record  # noqa: PLC0415 - intake.model loads pandas, numpy (424 ms CPU), only on this path

    graded = []
    for arrival in (a for a in arrivals if a.gradable):
        source = Path(bags[arrival.id])
        for sc in sorted(p for p in source.iterdir() if (p / "bag").is_dir()):
            target = out / arrival.id / "scenarios" / sc.name
            target.mkdir(parents=True, exist_ok=True)
            for entry in sc.iterdir():
                if not (target / entry.name).exists():
                    os.symlink(entry.resolve(), target / entry.name)
        write_record(out / arrival.id, arrival.record(), due_override)
        graded.append(regrade_submission(out / arrival.id, rubric))
    write_batch_outputs(out, rubric)
    return graded
