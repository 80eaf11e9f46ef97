"""Gradescope's side of a grade: ``results.json`` from a Result, and the autograder run itself.

Gradescope runs ``/autograder/run_autograder`` once per submission in a fresh container, with the
student's files in ``/autograder/submission``, and reads ``/autograder/results/results.json``
(format: ``gradescope.schema.json`` beside this file, written from Gradescope's "Autograder
Specifications"). ``run_autograder`` calls ``grader gradescope-run``, which grades the submission
with the same pipeline as ``grader grade`` (``grade_submission``, every item, hidden ones too),
keeps grader's own result.json and report.html next to it, and converts the Result:

* one test per automatic item (auto, advisory, integrity); manual items are left out, they stay
  Gradescope manual questions;
* visibility: public items ``visible``, hidden items ``after_published``, integrity flags
  ``hidden`` (worth no points; for the staff);
* ``output``: the feedback, the hint and the measured value; ``tags``: the item's section.

A submission that cannot be graded at all (empty, no ROS package) still gets a valid results.json
with score 0 and the reason, instead of Gradescope's "The autograder failed to execute correctly".
A submission with timing items the grading machine was too busy to measure (``Result.starved``)
is graded once more, in real time (``REGRADE_TIME_SCALE``), before ``results.json`` is written; what is still not measured scores 0 and
its ``output`` says so.

Student code runs in the same sandbox as in ``grader grade`` (``grader.sandbox``): ``setup.sh``
installs bubblewrap, and :func:`prepare_image` (``grader gradescope-setup``, run by ``setup.sh``
when the image is built) builds the rubric's support packages into ``ROOT/grader-cache`` and lists
the protections active in the image. In the jail, a student process runs as an unprivileged user
and sees none of ``ROOT/source`` (the rubric, hidden items and thresholds), ``ROOT/results``,
``ROOT/grader-out`` or the grader package; the grader's venv is read-only. Only this process,
outside the jail, writes ``results.json``.
"""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path
from typing import Any, Mapping

from grader.errors import GraderError
from grader.api import load_rubric
from grader.api.batch import REGRADE_TIME_SCALE, build_support, is_archive
from grader.api.machine import protections

SCHEMA = Path(__file__).resolve().parent / "gradescope.schema.json"
#: the folder under the autograder root where grader keeps its own outputs (result.json, bags)
WORK_DIR = "grader-out"
#: the build cache made when the image is built (the rubric's support packages, compiled once)
CACHE_DIR = "grader-cache"
SUBMISSION_ID = "submission"


def visibility(item) -> str:
    if item.kind == "integrity":
        return "hidden"
    return "visible" if item.public else "after_published"


def _measured(value: Any) -> str:
    """The item's headline value as one short line."""
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else str(value)
    if isinstance(value, (dict, list, tuple)):
        from grader.contracts.jsonable import jsonable  # noqa: PLC0415 - contracts.jsonable loads pandas, numpy (424 ms CPU), only on this path

        text = json.dumps(jsonable(value), ensure_ascii=False)
        return text if len(text) <= 400 else text[:397] + "..."
    return str(value)


def test_output(item) -> str:
    lines = [item.feedback.strip()] if item.feedback else []
    if item.hint and item.status != "pass":
        lines.append(f"Hint: {item.hint.strip()}")
    if item.value is not None:
        lines.append(f"Measured: {_measured(item.value)}")
    return "\n".join(lines)


def test_entry(item) -> dict[str, Any]:
    return {
        "name": f"{item.id}: {item.title}",
        "name_format": "text",
        "score": float(item.points or 0.0),
        "max_score": float(item.max_points),
        "status": "passed" if item.status == "pass" else "failed",
        "output": test_output(item),
        "output_format": "text",
        "visibility": visibility(item),
        "tags": [item.section.key],
        "extra_data": {"item": item.id, "kind": item.kind, "status": item.status},
    }


def _manual_note(rubric) -> str:
    manual = [i for i in rubric.items if i.kind == "manual"]
    if not manual:
        return ""
    points = sum(i.points for i in manual)
    return (f"The {points:g} points of {', '.join(i.id for i in manual)} are graded by the course "
            "staff, not by this autograder.")


def results_document(result, rubric, *, problems: list[str], build_ok: bool,
                     execution_time: float) -> dict[str, Any]:
    """results.json for a graded submission (``result`` of grade_submission, all items)."""
    tests = [test_entry(i) for i in result.items if i.kind != "manual"]
    lines = [f"{rubric.title}: {result.auto_score:g}/{result.auto_max:g} points from the autograder."]
    if not build_ok:
        lines.append("Some of your packages did not build; the items that need them score 0.")
    lines += [f"Problem: {p}" for p in problems]
    if result.starved:
        lines.append(f"Not measured: {', '.join(result.starved)}: the grading machine was too busy to measure "
                     "their timing twice in a row (they score 0 for now); ask your instructor to regrade.")
    if any(t["visibility"] == "after_published" for t in tests):
        lines.append("Some checks stay hidden until the grades are published.")
    if note := _manual_note(rubric):
        lines.append(note)
    return {
        "score": float(result.auto_score),
        "execution_time": int(round(execution_time)),
        "output": "\n".join(lines),
        "output_format": "text",
        "test_output_format": "text",
        "test_name_format": "text",
        "stdout_visibility": "hidden",
        "extra_data": {"lab": rubric.lab, "auto_max": float(result.auto_max)},
        "tests": tests,
    }


def not_graded_document(rubric, reason: str, *, execution_time: float) -> dict[str, Any]:
    """results.json when nothing could be graded: 0 points, the reason on every test."""
    tests = []
    for item in rubric.items:
        if item.kind == "manual":
            continue
        tests.append({"name": f"{item.id}: {item.title}", "name_format": "text", "score": 0.0,
                      "max_score": float(item.points), "status": "failed",
                      "output": f"Not graded: {reason}", "output_format": "text",
                      "visibility": visibility(item), "tags": [item.section.key],
                      "extra_data": {"item": item.id, "kind": item.kind, "status": "error"}})
    return {"score": 0.0, "execution_time": int(round(execution_time)),
            "output": f"The autograder could not grade this submission: {reason}",
            "output_format": "text", "test_output_format": "text", "test_name_format": "text",
            "stdout_visibility": "hidden", "extra_data": {"lab": rubric.lab}, "tests": tests}


def find_submission(folder: Path) -> Path:
    """What to grade in Gradescope's submission folder: the folder itself (workspace, packages,
    a repository), or the one archive a student uploaded without unpacking."""
    if not folder.is_dir() or not any(p.is_file() for p in folder.rglob("*")):
        raise GraderError("the submission is empty: upload your workspace's src/ folder or your "
                          "package folders (a .zip of them works too).")
    if any(folder.rglob("package.xml")):
        return folder
    archives = [p for p in folder.iterdir() if is_archive(p)]
    if len(archives) == 1:
        return archives[0]
    raise GraderError("no ROS package (package.xml) in the submission: upload your workspace's "
                      "src/ folder or your package folders (a .zip of them works too).")


def write_json(path: Path, doc: Mapping[str, Any]) -> None:
    from grader.api.pipeline import atomic_write  # noqa: PLC0415 - api.pipeline loads grading.pipeline, pandas, numpy (424 ms CPU), only on this path

    atomic_write(path, json.dumps(doc, indent=1, allow_nan=False, ensure_ascii=False) + "\n")


def prepare_image(root: Path, rubric_path: Path, *, cache_dir: Path | None = None) -> dict[str, Any]:
    """At image build: compile the rubric's support packages into the image's build cache (so no
    submission compiles them again) and say which sandbox protections the image gives student
    code. Raises GraderError when a support package does not build (the instructor's files)."""
    rubric = load_rubric(rubric_path)
    cache = Path(cache_dir or Path(root) / CACHE_DIR)
    cache.mkdir(parents=True, exist_ok=True)
    built = build_support(dict(rubric.support), cache) if rubric.support else None
    if built is not None and not built.ok:
        raise GraderError("the rubric's support packages did not build: " + "; ".join(
            f"{n}: {built.packages[n].reason}" for n in built.failed))
    return {"cache": cache, "support": sorted(built.packages) if built else [],
            "cached": bool(built and built.cached), "protections": protections()}


def run(root: Path, rubric_path: Path, *, cache_dir: Path | None = None) -> dict[str, Any]:
    """Grade ``root/submission`` and write ``root/results/results.json``; returns the document.
    ``cache_dir`` defaults to the image's ``root/grader-cache`` (support packages pre-built)."""
    from grader.api.pipeline import grade_submission  # noqa: PLC0415 - api.pipeline loads grading.pipeline, pandas, numpy (424 ms CPU), only on this path

    t0 = time.monotonic()
    root = Path(root)
    cache_dir = cache_dir or root / CACHE_DIR
    rubric = load_rubric(rubric_path)      # a broken bundle is the instructor's error: no results
    try:
        submission = find_submission(root / "submission")
        graded = grade_submission(submission, rubric, root / WORK_DIR, cache_dir=cache_dir, sid=SUBMISSION_ID,
                                  progress=lambda msg: print(msg, flush=True))
        if graded.result.starved:       # recorded again before the student sees a grade
            print(f"timing of {', '.join(graded.result.starved)} not measured (the machine was starved): "
                  "recording again", flush=True)
            graded = grade_submission(submission, rubric, root / WORK_DIR, cache_dir=cache_dir, sid=SUBMISSION_ID,
                                      time_scale=REGRADE_TIME_SCALE, progress=lambda msg: print(msg, flush=True))
        doc = results_document(graded.result, rubric, problems=graded.errors, build_ok=graded.build_ok,
                               execution_time=time.monotonic() - t0)
    except GraderError as exc:
        doc = not_graded_document(rubric, str(exc), execution_time=time.monotonic() - t0)
    write_json(root / "results" / "results.json", doc)
    return doc


def default_root() -> Path:
    return Path(os.environ.get("GRADER_AUTOGRADER_ROOT", "/autograder"))
