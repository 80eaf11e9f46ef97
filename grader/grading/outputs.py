"""Writing a graded submission (result.json, report.html) and a batch (grades.csv, index.html),
and the self-check table `grader check` prints (its lines: the engine prints nothing)."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any

from grader import __version__, analyze
from grader.contracts.output_folder import CANVAS_PNG, SCENARIOS_DIR, SubmissionFolder
from grader.report.replay import replays
from grader.grading.provenance import by_other_grader, notes, scenario_recordings
from grader.grading.repeat import scenario_of
from grader.grading.timescale import describe, describe_lockstep
from grader.report.batch import load_results, write_batch
from grader.report.html import write_html
from grader.report.readable import item_params, measured_sentence
from grader.report.result import write_result
from grader.rosenv import ros_info
from grader.sandbox.scenario import recorded_summary

if TYPE_CHECKING:
    from grader.grading.graded import GradedSubmission
    from grader.rubric.schema import Rubric


def versions() -> dict[str, str]:
    info = ros_info()
    return {"grader": __version__, "ros": f"{info['distro']} ({info['mode']})", "rclpy": info["rclpy"],
            "rmw": info["rmw"], "python": info["python"]}


def _canvases(sub_out: Path) -> dict[str, str]:
    """Each scenario's canvas (of its first run when it ran more than once)."""
    return {p.parent.name: str(p) for p in sorted(sub_out.glob(f"{SCENARIOS_DIR}/*/{CANVAS_PNG}"))
            if scenario_of(p.parent.name) == p.parent.name}


def effective_params(rubric: Rubric) -> dict[str, dict]:
    """item id -> the analyzer's parameters as run (defaults merged with the rubric's), for the
    report's thresholds when a result does not record its own."""
    out = {}
    for item in rubric.items:
        if item.analyzer:
            try:
                out[item.id] = analyze.effective_params(item.analyzer, item.params)
            except Exception:  # noqa: BLE001 - an unknown analyzer is reported by the item itself
                out[item.id] = dict(item.params)
    return out


def write_submission_outputs(graded: GradedSubmission, rubric: Rubric, *, public_only: bool, inputs: dict[str, str] | None = None) -> None:
    """result.json (+ build, errors, timings, previous grading) and report.html for one submission."""
    ver = versions()
    # which protections student code ran under, and each limit it reached (from the scenario
    # records, so a regrade reports the grading run): a line each in errors and the report
    sandbox = recorded_summary(sorted(p for p in SubmissionFolder(graded.out).scenarios.glob("*") if p.is_dir()))
    problems = list(graded.errors)
    if sandbox is not None:
        # a self-check runs the student's own code on their own machine: no isolation warning there
        if sandbox.get("warning") and not public_only:
            problems.append(f"sandbox: {sandbox['warning']}")
        problems += [f"limit reached: {hit}" for hit in sandbox.get("limits_hit", [])]
    problems = list(dict.fromkeys(problems))         # a regrade that keeps stored errors adds none twice
    extra: dict[str, Any] = {"build": {"ok": graded.build_ok, "failed": graded.build_failed},
             "errors": problems, "timings": graded.timings,
             "scenarios": sorted(p.name for p in SubmissionFolder(graded.out).scenarios.glob("*") if p.is_dir()),
             "scenarios_reused": {sc: r.to_json() for sc, r in graded.reused.items()}}
    if sandbox is not None:
        extra["sandbox"] = sandbox
    if graded.previous is not None:
        extra["previous"] = graded.previous.model_dump(mode="json")
    # the key and maker of each recording, and those another grader made (a regrade after an
    # upgrade, or a recording reused from before it): instructors are told, students are not
    recordings = graded.recordings or scenario_recordings(graded.out)
    other = by_other_grader(recordings) if recordings else {}
    extra["recordings"] = {sc: r.to_json() for sc, r in recordings.items()}
    if other:
        extra["recordings_by_other_grader"] = other
    intake = graded.intake.public() if graded.intake is not None else None
    if intake:
        extra["intake"] = intake           # who and when, as the LMS said (grader.intake)
    if rubric.analyzers:        # the rubric's own analyzer files: a page redrawn later draws their figures
        extra["analyzer_files"] = [str(p) for p in rubric.analyzers]
    time_scales = _time_scales(graded)
    if time_scales:                 # --time-scale or lockstep: how each scenario ran, and why not
        extra["time_scale"] = time_scales
    ended_early = _ended_early(graded)
    if ended_early:                 # steps ended once their outcome was decided
        extra["ended_early"] = ended_early
    out_dir, sid = graded.out.parent, graded.out.name
    write_result(out_dir, sid, graded.result, versions=ver, extra=extra, inputs=inputs)
    write_html(out_dir, sid, graded.result, versions=ver, canvas_png=_canvases(graded.out) or None,
               problems=problems, params=effective_params(rubric),
               notes=time_scale_notes(time_scales) + early_end_notes(ended_early)
               + ([] if public_only else notes(other, recordings)),
               intake=intake, replays=replays(graded.out),
               item_scenarios={item.id: list(item.scenario) for item in rubric.items})


def _time_scales(graded: GradedSubmission) -> dict[str, dict[str, Any]]:
    """result.json's ``time_scale`` (and what the notes read): each scenario's clock as JSON."""
    return {sc: ts.to_json() for sc, ts in graded.time_scales.items()}


def _ended_early(graded: GradedSubmission) -> dict[str, list[dict[str, Any]]]:
    """result.json's ``ended_early``: each scenario's steps ended once decided, as JSON."""
    return {sc: [e.to_json() for e in ends] for sc, ends in graded.ended_early.items()}


def write_batch_outputs(out: Path, rubric: Rubric) -> None:
    """grades.csv and index.html rebuilt from every OUT/*/result.json on disk (so parallel,
    resumed and regraded submissions all count)."""
    if load_results(out, rubric):
        write_batch(out, rubric)


def check_table(graded: GradedSubmission, rubric: Rubric) -> tuple[bool, list[str]]:
    """The self-check table, as the lines ``grader check`` prints (the engine prints nothing);
    True when every public auto item passed."""
    out: list[str] = []
    result = graded.result
    rows = [i for i in result.items if i.kind != "manual"]
    width = max((len(i.id) for i in rows), default=10)
    out.append(f"\n{rubric.title}: self-check ({result.auto_score:g}/{result.auto_max:g} points on public items)\n")
    for m in result.contract:
        blocks = f" Blocks: {', '.join(m.blocks)}." if m.blocks else ""
        for k, line in enumerate(_wrap(m.feedback + blocks, 92)):
            out.append(f"  {'NAME' if k == 0 else '    '}  {line}")
    if result.contract:
        out.append("")
    ok = True
    marks = {"pass": "PASS", "partial": "PART", "fail": "FAIL", "error": "ERR "}

    params = effective_params(rubric)
    for item in rows:
        mark = marks.get(item.status, item.status.upper()[:4])
        pts = "" if item.kind in ("advisory", "integrity") else f"{(item.points or 0):g}/{item.max_points:g}"
        label = "warn" if item.kind == "advisory" and item.status != "pass" else mark
        out.append(f"  {label:4}  {item.id:<{width}}  {pts:>7}  {item.title}")
        if item.status != "pass":
            # what was measured against what was expected, then the feedback and the hint
            lead = measured_sentence(item, item_params(item, params.get(item.id)), student_view=True)
            text = (lead + " " + (item.feedback or "")).strip()
            if item.hint:
                text = (text + " Hint: " + item.hint).strip()
            for line in _wrap(text, 92):
                out.append(f"        {line}")
        if item.kind == "auto" and item.status != "pass":
            ok = False
    for sc_id, src in (getattr(graded, "reused", {}) or {}).items():
        out.append(f"\n  note: scenario {sc_id} was not run again: nothing it runs changed since "
                   f"{src.get('recorded', 'an earlier run')} (its recording was reused; --no-reuse runs it)")
    for line in time_scale_notes(_time_scales(graded)) + early_end_notes(_ended_early(graded)):
        out.append(f"\n  note: {line}")
    for err in graded.errors:
        out.append(f"\n  problem: {err.splitlines()[0]}")
    out.append("\nAll public checks pass." if ok else "\nSome checks do not pass yet (see above).")
    return ok, out


def contract_lines(rubric: Rubric) -> list[str]:
    """What the lab fixes, before a self-check runs: the names to use exactly (the lines ``grader
    check`` prints; none when the lab fixes no names)."""
    out: list[str] = []
    lines = rubric.contract.lines()
    if not lines:
        return out
    out.append(f"{rubric.title}\nNames this lab fixes (use them exactly; everything else is found by what it does):")
    width = max(len(what) for what, _, _, _ in lines)
    names = max(len(name) for _, name, _, _ in lines)
    for what, name, use, _why in lines:
        out.append(f"  {what:<{width}}  {name:<{names}}  {use}".rstrip())
    out.append("")
    return out


def early_end_notes(ended_early: dict[str, list[dict]]) -> list[str]:
    """One line per step that ended before its limit because its outcome was decided."""
    return [f"scenario {sc}, step {e['step']} ended after {e.get('at_s') or 0:g} s of its {e.get('limit_s') or 0:g} s: "
            f"{e['reason']}" for sc, ends in sorted(ended_early.items()) for e in ends]


def time_scale_notes(time_scales: dict[str, dict]) -> list[str]:
    """How the scenarios ran under --time-scale: the fast ones in one line, each fallback with
    its reason."""
    locked = {sc: ts for sc, ts in time_scales.items() if ts.get("clock") == "lockstep"}
    time_scales = {sc: ts for sc, ts in time_scales.items() if sc not in locked}
    fast = sorted(sc for sc, ts in time_scales.items() if float(ts.get("used", 1)) > 1)
    notes = []
    if fast:
        used = {float(time_scales[sc]["used"]) for sc in fast}
        speed = f"{used.pop():g}x faster" if len(used) == 1 else "faster"
        notes.append(f"scenario{'s' if len(fast) > 1 else ''} {', '.join(fast)} ran {speed} than real time "
                     "(on simulated time)")
    notes += [describe(sc, ts) for sc, ts in sorted(time_scales.items()) if float(ts.get("used", 1)) <= 1]
    return notes + [describe_lockstep(sc, ts) for sc, ts in sorted(locked.items())]


def _wrap(text: str, width: int) -> list[str]:
    return textwrap.wrap(text, width) or []


