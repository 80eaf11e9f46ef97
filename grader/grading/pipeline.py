"""One submission through every layer: build → scenarios (bags) → analyze → score → report.

``grader.grading.analysis.analyze_bags`` is the offline half: it needs only the scenario folders
(bags + records), so ``grader regrade`` recomputes a grade on any machine without ROS.
"""

from __future__ import annotations

import resource
import shutil
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable

from grader.errors import GraderError
from grader.grading.analysis import analyze_bags, settles_check
from grader.grading.graded import GradedSubmission
from grader.grading.repeat import run_until_settled
from grader.grading.timescale import expected_rates, machine_time_scale
from grader.report.replay import write_replay
from grader.scenario import children_cpu_s
from grader.bag.frames import load_bag_meta
from grader.cache.locks import Holds
from grader.cache.store import submission_cache_use
from grader.grading.outputs import write_submission_outputs
from grader.grading.provenance import scenario_recordings
from grader.grading.reuse import record_or_reuse
from grader.grading.schedule import Slots
from grader.intake.apply import apply_intake
from grader.intake.model import read_record, write_record
from grader.contracts.result_document import ResultDocument
from grader.contracts.scenario_record import ScenarioRecord
from grader.contracts.run_records import ClockUse, EarlyEnd, ReusedRecording
from grader.contracts.output_folder import SCENARIOS_DIR, SubmissionFolder
from grader.report.result import previous_summary, read_document
from grader.report.seal import input_digests, mac_ok, changed_inputs
from grader.rubric.score import score
from grader.scores.store import apply_saved_manual_scores, manual_scores_kept
from grader.similarity.files import snapshot
from grader.workspace import build_workspace
from grader.workspace.build import default_cache_dir
from grader.workspace.source import submission_id

if TYPE_CHECKING:
    from grader.grading.schedule import Slots
    from grader.rubric.schema import Item, Rubric
    from grader.scenario.model import Scenario


def early_ends(record: ScenarioRecord, scenario: Any) -> list[dict]:
    """The steps of a scenario record that ended once their outcome was decided (``ended_by:
    decided``), with the step's limit, for the result and its notes."""
    limits = {step.id: step.limit_s for step in scenario.steps}
    return [{"step": st.id, "at_s": st.duration_s, "limit_s": limits.get(st.id),
             "reason": st.detail.get("ended_early")}
            for st in record.steps if st.ended_by == "decided"]


def _or_zero(record: ScenarioRecord, key: str) -> float:
    """A timing of the record: 0.0 when it has none (a record cut short: no ``active_s``)."""
    value = getattr(record, key)
    return 0.0 if key not in record.model_fields_set else value


def selected_items(rubric: Rubric, public_only: bool) -> list[Item]:
    return [i for i in rubric.items if i.automatic and (i.public or not public_only)]


def needed_scenarios(items: Iterable) -> list[str]:
    seen: list[str] = []
    for item in items:
        for sc in item.scenario:
            if sc not in seen:
                seen.append(sc)
    return seen


def thread_cpu_s() -> float:
    """CPU seconds of the calling thread (a batch grades submissions side by side in threads)."""
    usage = resource.getrusage(resource.RUSAGE_THREAD)
    return usage.ru_utime + usage.ru_stime


def grade_submission(path: Path, rubric: Rubric, out_root: Path, *, cache_dir: Path | None = None,
                     public_only: bool = False, sid: str | None = None,
                     progress: Callable[[str], None] | None = None, slots: Slots | None = None,
                     reuse: bool = True, time_scale: float | None = None, intake: dict | None = None,
                     due_override: dict | None = None) -> GradedSubmission:
    """Build, run the needed scenarios (side by side, within ``slots``), analyze and score one
    submission; writes its folder. ``reuse``: copy a scenario's recording when everything it
    runs is identical to an earlier run (see grader.grading.reuse). ``time_scale`` > 1: run
    scenarios that may on simulated time, that much faster (see grader.grading.timescale); None:
    the machine's default (``grader.grading.timescale.machine_time_scale``).
    ``intake``: how it arrived (grader.intake: ids, student, time), kept in ``intake.json``; with
    the rubric's late policy (its due date replaced by ``due_override``) it sets the penalty."""
    time_scale = machine_time_scale(time_scale)
    slots = slots or Slots(1)
    sid = sid or submission_id(Path(path))
    out = _fresh_folder(Path(out_root) / sid, intake, due_override)
    timings: dict[str, float] = {}
    say = progress or (lambda _msg: None)

    say(f"{sid}: building")
    holds = Holds()          # the build areas this submission runs stay out of a prune's reach
    build, errors = _build(Path(path), rubric, out, cache_dir, slots, holds, timings)

    items = selected_items(rubric, public_only)
    recordings = (Path(cache_dir or default_cache_dir()) / "recordings") if reuse else None
    with holds:
        ran = _run_scenarios(sid, rubric, items, build, out, slots, recordings, time_scale, timings, say)
    errors += ran.errors
    recordings_made = scenario_recordings(out)

    say(f"{sid}: analyzing")
    t2, cpu2 = time.monotonic(), thread_cpu_s()
    findings, problems = analyze_bags(rubric, items, out, on_frames=write_replay)
    errors += problems
    result, kept = apply_saved_manual_scores(out, score(rubric, findings))
    timings.update(analysis_s=round(time.monotonic() - t2, 2), analysis_cpu_s=round(thread_cpu_s() - cpu2, 2))
    errors += kept
    result, late_notes = apply_intake(out, rubric, result)
    errors += late_notes
    if public_only:
        result = result.for_student()
    graded = GradedSubmission(sid, out, result, build_ok=bool(build and build.ok),
                              build_failed=list(build.failed) if build else ["(no build)"],
                              errors=errors, timings=timings,
                              reused={sc: ReusedRecording.model_validate(r) for sc, r in ran.reused.items()},
                              time_scales={sc: ClockUse.model_validate(t) for sc, t in ran.time_scales.items()},
                              ended_early={sc: [EarlyEnd.model_validate(e) for e in ends]
                                           for sc, ends in ran.ended_early.items()},
                              recordings=recordings_made,
                              cache=submission_cache_use(build, {sc: r.to_json() for sc, r in recordings_made.items()},
                                                         reuse),
                              intake=read_record(out))
    write_outputs(graded, rubric, public_only=public_only)
    return graded


def _fresh_folder(out: Path, intake: dict | None, due_override: dict | None) -> Path:
    """The submission's output folder, emptied (the TA's merged manual scores kept), with its
    intake record."""
    with manual_scores_kept(out):          # a re-grade keeps the TA's merged manual scores
        if out.exists():
            shutil.rmtree(out)
        out.mkdir(parents=True)
    if intake is not None:
        write_record(out, intake, due_override)
    return out


def _build(path: Path, rubric: Rubric, out: Path, cache_dir: Path | None, slots: Slots, holds: Any,
           timings: dict[str, float]) -> tuple[Any, list[str]]:
    """Build the workspace in a slot (None when it could not be built at all), its log and the
    source snapshot in ``out``; the problems to report."""
    t0 = time.monotonic()
    build = None
    errors: list[str] = []
    try:
        with slots.taken():
            build = build_workspace(path, cache_dir=cache_dir, support=dict(rubric.support), holds=holds)
        shutil.copy(build.build_log, out / "build.log") if build.build_log.exists() else None
        snapshot(build.root / "src", out)          # the source files grader similarity compares
        errors += [f"submission: {w}" for w in build.warnings]
        if not build.ok:
            errors += [f"package {n} did not build ({build.packages[n].status}):\n{build.packages[n].log_excerpt}"
                       for n in build.failed]
    except GraderError as exc:
        errors.append(f"build: {exc}")
        (out / "build.log").write_text(str(exc) + "\n")
    timings["build_s"] = round(time.monotonic() - t0, 2)
    return build, errors


@dataclass
class ScenariosRun:
    """What a submission's scenarios left for its result besides their bags."""

    errors: list[str] = field(default_factory=list)
    reused: dict[str, dict] = field(default_factory=dict)          # recordings copied, and from where
    time_scales: dict[str, dict] = field(default_factory=dict)     # how each clock ran, and why not
    ended_early: dict[str, list[dict]] = field(default_factory=dict)


def _run_scenarios(sid: str, rubric: Rubric, items: list, build: Any, out: Path, slots: Slots,
                   recordings: Path | None, time_scale: float, timings: dict[str, float],
                   say: Callable[[str], None]) -> ScenariosRun:
    """Every scenario the items need, side by side within ``slots``, longest first (by its step
    limits, on the clock it will run on): when slots run short, a short scenario waits, not the
    one that sets the submission's wall time (at 4x Lab 3's ex2_controller has the larger budget,
    its lockstep ex3_action the longer run)."""
    ran = ScenariosRun()
    t1 = time.monotonic()
    scenario_ids = needed_scenarios(items)
    say(f"{sid}: scenarios {', '.join(scenario_ids)}")

    def expected_wall_s(sc: str) -> float:
        scenario = rubric.scenarios[sc]
        sped_up = not (scenario.lockstep or scenario.real_time)
        return scenario.budget_s / (max(1.0, time_scale) if sped_up else 1.0)

    longest_first = sorted(scenario_ids, key=lambda sc: -expected_wall_s(sc))
    with ThreadPoolExecutor(max_workers=max(1, len(scenario_ids))) as pool:
        runs = {sc_id: pool.submit(_run_one, sid, sc_id, rubric.scenarios[sc_id], build, out, slots, recordings,
                                   time_scale, expected_rates(rubric, sc_id) if time_scale > 1 else (),
                                   settles_check([i for i in items if sc_id in i.scenario], rubric.scenarios[sc_id].repeat,
                                                 rubric.scenarios[sc_id].repeat_by))
                for sc_id in longest_first}
        for sc_id in scenario_ids:
            record = runs[sc_id].result()
            timings[f"scenario:{sc_id}:wall_s"] = _or_zero(record, "parent_wall_s")
            timings[f"scenario:{sc_id}:active_s"] = _or_zero(record, "active_s")
            timings[f"scenario:{sc_id}:cpu_s"] = record.cpu_s or 0.0
            ran.errors += [f"scenario {sc_id}: {e}" for e in record.errors]
            if record.reused is not None and record.reused.to_json():
                ran.reused[sc_id] = record.reused.to_json()
            if time_scale > 1 and record.time_scale is not None and record.time_scale.to_json():
                ran.time_scales[sc_id] = record.time_scale.to_json()
            if record.lockstep is not None and record.lockstep.to_json():   # how a lockstep clock ran (and why not)
                ran.time_scales[sc_id] = {"clock": "lockstep", **record.lockstep.to_json()}
            if early := early_ends(record, rubric.scenarios[sc_id]):
                ran.ended_early[sc_id] = early
    timings["scenarios_wall_s"] = round(time.monotonic() - t1, 2)
    return ran


def _run_one(sid: str, sc_id: str, scenario: Scenario, build: Any, out: Path, slots: Slots, recordings: Path | None,
             time_scale: float = 1.0, rates: tuple = (), settles: Callable[[list[Path]], bool] | None = None
             ) -> ScenarioRecord:
    """One scenario; a repeated one (``repeat: N``) run by run until its median is settled, each
    run recorded or reused by ``grader.grading.reuse.record_or_reuse``."""
    cpu0 = children_cpu_s()
    record = run_until_settled(
        lambda k, folder: record_or_reuse(sid, sc_id, scenario, build, folder, slots, recordings, time_scale, rates,
                                          run=k),
        out / SCENARIOS_DIR, sc_id, scenario.repeat, settles)
    # every run and retry of it (this thread's), reused ones costing nothing
    return record.amended({"cpu_s": round(children_cpu_s() - cpu0, 2)})


def regrade_submission(sub_out: Path, rubric: Rubric, *, public_only: bool = False) -> GradedSubmission:
    """Recompute a submission's grade from its recorded bags only (no build, no ROS)."""
    sub_out = Path(sub_out)
    if not (sub_out / SCENARIOS_DIR).is_dir():
        raise GraderError(f"{sub_out} has no {SCENARIOS_DIR}/ folder; point at OUT/<submission> "
                          "written by `grader grade`.")

    items = selected_items(rubric, public_only)
    old, unreadable = None, []
    if SubmissionFolder(sub_out).result_json.exists():
        try:
            old = read_document(SubmissionFolder(sub_out).result_json)
        except GraderError as exc:     # damaged, or not a result.json: the bags are what a grade comes from
            unreadable = [f"{exc}; regraded from the bags as they are"]
    unusable, notes = recordings_to_refuse(sub_out, old)
    notes = unreadable or notes
    findings, problems = analyze_bags(rubric, items, sub_out, unusable, on_frames=write_replay)
    result, kept = apply_saved_manual_scores(sub_out, score(rubric, findings))   # merged manual scores
    result, late_notes = apply_intake(sub_out, rubric, result)                   # late policy, again
    problems = notes + problems + kept + late_notes
    # the seal keeps the digests of what was graded; a result without one is sealed as it is now
    inputs = old.seal.inputs if old is not None and old.seal is not None and mac_ok(old) else input_digests(sub_out)

    # the run's build/scenario problems and timings still describe the bags; keep them, and
    # which grader made each recording (provenance: another grader's are named in the report)
    graded = GradedSubmission(sub_out.name, sub_out, result, build_ok=old is None or old.build_ok,
                              build_failed=old.build.failed if old is not None and old.build is not None else [],
                              errors=list(dict.fromkeys([*(old.errors if old is not None else []), *problems])),
                              timings=old.timings if old is not None else {}, previous=previous_summary(old),
                              time_scales={sc: ClockUse.model_validate(t)
                                           for sc, t in (old.time_scale if old is not None else {}).items()},
                              ended_early={sc: [EarlyEnd.model_validate(e) for e in ends]
                                           for sc, ends in (old.ended_early if old is not None else {}).items()},
                              recordings=scenario_recordings(sub_out),
                              reused={sc: ReusedRecording.model_validate(r)
                                      for sc, r in (old.scenarios_reused if old is not None else {}).items()},
                              intake=read_record(sub_out))
    write_outputs(graded, rubric, public_only=public_only, inputs=inputs)
    return graded


def recordings_to_refuse(sub_out: Path, old: ResultDocument | None) -> tuple[dict[str, str], list[str]]:
    """Scenarios whose recordings a regrade must not grade (changed since they were graded, or
    a bag that was not finalised cleanly), with why; and notes about the seal itself."""
    refuse: dict[str, str] = {}
    notes: list[str] = []
    if old is None or old.seal is None:
        notes.append("result.json had no seal (an older grader wrote it): regraded from the bags as they are")
    elif not mac_ok(old):
        notes.append("result.json's seal does not match this grader's key (changed, or sealed on another "
                     "machine): the recorded bag digests cannot be trusted; regraded from the bags as they are")
    else:
        for rel in changed_inputs(old, sub_out):
            parts = Path(rel).parts
            if len(parts) >= 2 and parts[0] == SCENARIOS_DIR:
                refuse[parts[1]] = (f"the recording changed since it was graded ({rel} differs from the digest in "
                                    "result.json's seal); not regraded")
    for bag in sorted((sub_out / SCENARIOS_DIR).glob("*/bag")):
        sc = bag.parent.name
        if sc in refuse:
            continue
        try:
            meta = load_bag_meta(bag)
        except GraderError as exc:
            refuse[sc] = f"the bag cannot be read: {exc}"
            continue
        if not meta.finalized:
            refuse[sc] = ("the bag was not finalised cleanly (a cut or crashed recording): not regraded; "
                          "`grader bag repair` recovers what it can")
    return refuse, notes


def write_outputs(graded: GradedSubmission, rubric: Rubric, *, public_only: bool,
                  inputs: dict[str, str] | None = None) -> None:
    write_submission_outputs(graded, rubric, public_only=public_only, inputs=inputs)
