"""GitHub Classroom's side of a self-check: the result of ``grader check`` as an autograding runner.

GitHub Classroom's autograding workflow (the one it writes into an assignment's
``.github/workflows/classroom.yml``) runs grader steps, each leaving a step output ``result``:
base64 of a JSON document ``{"version": 1, "status": "pass"|"fail"|"error", "max_score": M,
"tests": [{"name", "status", "score", "message", "test_code", "filename", "line_no",
"execution_time"}, ...]}``. Its last step, ``classroom-resources/autograding-grading-reporter``,
reads each runner's document from the environment variable ``<STEP ID>_RESULTS``, prints the
tests, fails the run when a runner's ``status`` is ``fail`` or ``error``, and reports the points
to Classroom as two notice annotations: ``Points X/Y`` (title "Autograding complete") and
``{"totalPoints": X, "maxPoints": Y}`` (title "Autograding report"), where X is the sum of every
test's ``score`` and Y the sum of the runners' ``max_score``. Classroom reads those annotations.

:func:`runner_result` makes that document from ``grader check``'s ``result.json`` (the student
view: public items only): one test per scored automatic item with its points (partial credit
included), ``max_score`` the public automatic points, ``status`` ``fail`` while an item does not
pass, as ``grader check``'s exit code. ``grader classroom-result`` prints it as a step output.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Any

from grader.contracts.result_document import ItemEntry, ResultDocument
from grader.errors import GraderError

RUNNER_FORMAT_VERSION = 1


def _message(item: ItemEntry) -> str:
    lines = [item.feedback or ""]
    if item.hint and item.status != "pass":
        lines.append(f"Hint: {item.hint}")
    return "\n".join(line for line in lines if line).strip()


def runner_result(doc: ResultDocument, *, execution_time: float | None = None) -> dict[str, Any]:
    """The runner document for a ``result.json`` document (``grader check``'s, or any)."""
    scored = [i for i in doc.items if i.kind == "auto" and float(i.max_points or 0) > 0]
    if not scored:
        return error_result("grader graded no automatic item: see the grader check step's log")
    tests = [{"name": f"{i.id}: {i.title}", "status": "pass" if i.status == "pass" else "fail",
              "score": float(i.points or 0), "message": _message(i), "test_code": "",
              "filename": "", "line_no": 0, "execution_time": ""} for i in scored]
    return {"version": RUNNER_FORMAT_VERSION,
            "status": "pass" if all(t["status"] == "pass" for t in tests) else "fail",
            "max_score": sum(float(i.max_points) for i in scored),
            "execution_time": f"{execution_time:.1f}s" if execution_time is not None else "",
            "tests": tests}


def error_result(message: str) -> dict[str, Any]:
    """A runner that could not grade: Classroom gets no points and the reporter fails the run."""
    return {"version": RUNNER_FORMAT_VERSION, "status": "error", "max_score": 0,
            "tests": [{"name": "grader check", "status": "error", "score": 0, "message": message,
                       "test_code": "", "filename": "", "line_no": 0, "execution_time": ""}]}


def points(runner: dict[str, Any]) -> tuple[float, float]:
    """(total, maximum) as the reporter computes what it sends to Classroom."""
    return sum(float(t.get("score") or 0) for t in runner["tests"]), float(runner.get("max_score") or 0)


def step_output(result_json: Path | None) -> tuple[str, dict[str, Any]]:
    """``result=<base64>`` for ``$GITHUB_OUTPUT``, and the document. A missing or unreadable
    ``result.json`` (grader check did not get that far) gives an ``error`` runner."""
    if result_json is None or not Path(result_json).is_file():
        runner = error_result(f"no {result_json}: grader check did not finish (see its step's log)")
    else:
        try:
            doc = ResultDocument.read(result_json)
        except (OSError, ValueError) as exc:
            raise GraderError(f"{result_json} is not a grader result.json: {exc}") from None
        runner = runner_result(doc)
    encoded = base64.b64encode(json.dumps(runner, ensure_ascii=False).encode()).decode()
    return f"result={encoded}", runner
