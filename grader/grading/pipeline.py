"""One submission through every layer: build → scenarios (bags) → analyze → score → report.

``analyze_bags`` is the offline half: it needs only the scenario folders (bags + records), so
``grader regrade`` recomputes a grade on any machine without ROS.

A little over the project's ~400 lines: the one path from a submission to its result, whose
steps (build, run, analyze, score, write) share the submission's folder and problem list.
"""

from __future__ import annotations

import json
import re
import shutil
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Sequence, cast

from grader.analyze._common import events, own_exits, stdout_lines
from grader.errors import GraderError
from grader.grading.repeat import exact_lockstep, repeated_finding, run_folders, run_until_settled, settles_check
from grader.scenario.events import Event

if TYPE_CHECKING:
    from grader.analyze import Finding
    from grader.grading.schedule import Slots
    from grader.rubric.schema import Item, Rubric
    from grader.rubric.score import Result
    from grader.scenario.model import Scenario

SCENARIOS_DIR = "scenarios"


def submission_id(path: Path) -> str:
    """Folder name or archive stem, made safe for a folder and a CSV cell."""
    name = path.name
    for suffix in (".tar.gz", ".tgz", ".tar.xz", ".tar.bz2", ".tar", ".zip"):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
            break
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "submission"


def discover_submissions(root: Path) -> list[Path]:
    """A folder of submissions (one folder or archive each), or a single submission."""
    from grader.workspace.source import is_archive

    root = Path(root)
    if not root.exists():
        raise GraderError(f"{root} does not exist.")
    if is_archive(root) or (root / "src").is_dir() or (root / "package.xml").exists():
        return [root]
    subs = sorted(p for p in root.iterdir()
                  if (p.is_dir() and not p.name.startswith(".")) or is_archive(p))
    if not subs:
        raise GraderError(f"{root} holds no submissions (expected one folder or archive per student).")
    return subs


@dataclass
class GradedSubmission:
    id: str
    out: Path
    result: Result
    build_ok: bool
    build_failed: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    reused: dict[str, dict] = field(default_factory=dict)     # scenario -> where its recording came from
    recordings: dict[str, dict] = field(default_factory=dict)  # scenario -> key, made_by, reused_from
    cache: dict[str, int] = field(default_factory=dict)        # cache hits and misses (grader.cache.store)
    time_scales: dict[str, dict] = field(default_factory=dict)  # scenario -> requested/used/fallback (--time-scale)
    previous: dict | None = None      # a regrade's summary of the result it replaced (class view diff)
    intake: dict | None = None        # how it arrived: LMS ids, student, time (grader.intake)


def selected_items(rubric: Rubric, public_only: bool) -> list[Item]:
    return [i for i in rubric.items if i.automatic and (i.public or not public_only)]


def needed_scenarios(items: Iterable) -> list[str]:
    seen: list[str] = []
    for item in items:
        for sc in item.scenario:
            if sc not in seen:
                seen.append(sc)
    return seen


def scenario_frames(scenario_dir: Path) -> dict:
    """Frames of one scenario's bag plus ``__meta__`` (topic, type, count, publishers)."""
    import pandas as pd

    from grader.bag.frames import load_bag_meta, load_frames

    bag = scenario_dir / "bag"
    if not bag.exists():
        return {"__meta__": pd.DataFrame(columns=["topic", "type", "count", "publishers"])}
    record_file = scenario_dir / "scenario.json"
    record = json.loads(record_file.read_text()) if record_file.exists() else None
    # a run on simulated time is read in simulated seconds (grader.bag.timebase): the bag's own
    # metadata says so (sealed with it); the record speaks only for a bag never finalised
    used = ((record or {}).get("time_scale") or {}).get("used")
    finalized = (bag / "metadata.yaml").exists()
    locked = not finalized and bool(((record or {}).get("lockstep") or {}).get("used"))
    frames = load_frames(bag, time_scale=None if finalized or not used or locked else float(used),
                         lockstep=locked)
    meta = load_bag_meta(bag)
    publishers: dict[str, set[str]] = {}
    for ev in events(frames, Event.GRAPH):
        for topic, nodes in (ev.get("publishers") or {}).items():
            publishers.setdefault(topic, set()).update(nodes)
    frames["__meta__"] = pd.DataFrame(
        [{"topic": n, "type": t.type, "count": t.count, "publishers": sorted(publishers.get(n, set()))}
         for n, t in meta.topics.items()], columns=["topic", "type", "count", "publishers"])
    canvas = scenario_dir / "canvas.png"
    if canvas.exists():
        from grader.bag.frames import canvas_frame
        frames["__canvas__"] = canvas_frame(canvas)
    if record is not None:
        frames["__meta__"].attrs["scenario"] = record
    return frames


def _unavailable_nodes(frames: dict) -> list[str]:
    return [f"{e.get('process')}: {str(e.get('error', '')).splitlines()[0] if e.get('error') else 'not available'}"
            for e in events(frames, Event.NODE_UNAVAILABLE)]


def _crashed_nodes(frames: dict) -> list[str]:
    """Student processes that exited on their own, with the last line of what they printed: a
    non-zero exit is a crash; exit code 0 means its main returned (it stopped spinning)."""
    lines = stdout_lines(frames)
    last_line = {process: str(raw).strip() for process, raw in zip(lines["process"], lines["raw"])
                 if str(raw).strip()}
    limits = [str(e.get("detail") or e.get("limit") or e.get("what") or "") for e in events(frames, Event.LIMIT_HIT)]
    starts = sorted((e["t"], str(e["step"])) for e in events(frames, Event.STEP_START)     # every event has a t
                    if e.get("step") is not None)
    out = []
    for e in own_exits(frames):
        name = e.get("process", "?")
        tail = last_line.get(name, "")
        code = e.get("returncode")
        # the step it died in: the rubric's scenario description says what that step sends
        step = [s for t, s in starts if t <= e["t"]]
        when = f" during step '{step[-1]}'" if step else ""
        what = (f"{name} returned on its own (exit code 0){when} while the scenario ran: does it keep spinning?"
                if code == 0 else f"{name} crashed (exit code {code}){when}")
        out.append(what + (f" ({tail[:160]})" if tail else ""))
    if out and limits:
        out.append("limit reached: " + "; ".join(dict.fromkeys(m for m in limits if m)))
    return out


def analyze_item(item: Item, frames: dict) -> Finding:
    """One item's analyzer on one scenario's frames (never raises).

    When the analysis could not happen because the student's node did not run (it could not be
    built or started, or it crashed), that is the student's failure (0 points) with the reason
    in the feedback, not a grader error. A partial finding gets the crash too: a controller that
    died before the last goal must read that it died (and in which step), not only "goal 4 not
    reached". Integrity checks are the exception: code that never ran
    did nothing suspicious, so for them "could not check" stays an error (see `combine_findings`).
    """
    from grader import analyze

    finding = analyze.run(cast(str, item.analyzer), frames, dict(item.params))
    if finding.status not in ("fail", "error", "partial"):
        return finding      # only a lost point needs the events and output parsed for a reason
    missing = _unavailable_nodes(frames)
    crashed = _crashed_nodes(frames)
    if missing or crashed:
        why = (["Could not run " + "; ".join(missing).rstrip(".") + "."] if missing else []) + \
              (["Node stopped: " + "; ".join(crashed).rstrip(".") + "."] if crashed else [])
        finding.feedback = (finding.feedback + " " + " ".join(why)).strip()
        finding.evidence = {**finding.evidence, "unavailable_nodes": missing, "crashed_nodes": crashed}
        if finding.status == "error" and item.kind != "integrity":
            finding.status, finding.fraction = "fail", 0.0
    return finding


def combine_findings(item: Item, per_scenario: list, scenarios: Sequence[str] = ()) -> Finding | None:
    """One finding for an item run on several scenarios: the worst one counts (of equals, the
    first listed). With ``scenarios`` (their ids, in order), its ``decided`` lists how each
    scenario came out, so an item whose worst is one run still says it had repeated ones too.

    An integrity check is judged on the scenarios where it could run: a scenario in which the
    student's node never started (or recorded nothing to check) gives no evidence either way, so
    its "could not check" error does not hide the verdict of the others. Without that, whether the
    flag showed up would depend on how long the simulator ran before the empty scenario ended.
    """
    from grader.rubric.score import worst_finding

    each = [{"scenario": sc, "by": (f.decided or {}).get("by", "one run"), "runs": (f.decided or {}).get("runs", 1),
             "stable": (f.decided or {}).get("stable", True), "status": f.status}
            | ({"repeat_by": f.decided["repeat_by"]} if "repeat_by" in (f.decided or {}) else {})
            for sc, f in zip(scenarios, per_scenario) if f is not None]
    if item.kind == "integrity":
        checked = [f for f in per_scenario if f is not None and f.status != "error"]
        per_scenario = checked or per_scenario
    chosen = cast("Finding | None", worst_finding(per_scenario)) if per_scenario else None
    if chosen is not None and len(each) > 1:
        chosen = replace(chosen, decided={**(chosen.decided or {}), "scenarios": each})
    return chosen


class Findings(dict):
    """Item id -> finding, plus ``contract``: the contract names each scenario's recording shows
    under another name (``grader.rubric.contract.Mismatch``; scoring blocks the items that
    depend on them). A dict, so callers that only want the findings need not change."""

    contract: tuple = ()


def analyze_bags(rubric: Rubric, items: list[Item], sub_out: Path,
                 unusable: dict[str, str] | None = None) -> tuple[Findings, list[str]]:
    """Run every item's analyzer on its scenario bags (offline). Returns findings and problems.
    ``unusable``: scenario -> why its recording must not be graded (changed since grading, not
    finalised): its items become errors saying so."""
    from grader.analyze import Finding
    from grader.analyze.contract import check_contract
    from grader.rubric.contract import merge_mismatches
    from grader.analyze.plugins import load_rubric_files

    load_rubric_files(rubric)       # its own analyzer files (done by load_rubric already; idempotent)

    frames_cache: dict[str, dict | Exception] = {}
    problems: list[str] = []
    unusable = unusable or {}

    def frames_for(sc: str) -> dict | Exception:          # sc: a run's folder name (the scenario id for its first run)
        if sc not in frames_cache:
            if sc in unusable:
                frames_cache[sc] = GraderError(unusable[sc])
                problems.append(f"scenario {sc}: {unusable[sc]}")
                return frames_cache[sc]
            try:
                frames_cache[sc] = scenario_frames(sub_out / SCENARIOS_DIR / sc)
            except GraderError as exc:
                frames_cache[sc] = exc
                problems.append(f"scenario {sc}: {exc}")
        return frames_cache[sc]

    findings = Findings()
    for item in items:
        per_scenario = []
        for sc in item.scenario:
            per_run = []
            for folder in run_folders(sub_out / SCENARIOS_DIR, sc):      # one, or a repeated scenario's runs
                frames = frames_for(folder.name)
                if isinstance(frames, Exception):
                    per_run.append(Finding(value=None, fraction=0.0, status="error",
                                           feedback=f"The recording of scenario {sc} could not be read: {frames}",
                                           evidence={}))
                else:
                    per_run.append(analyze_item(item, frames))
            scenario = rubric.scenarios.get(sc)
            per_scenario.append(repeated_finding(per_run, scenario.repeat if scenario else 1,
                                               lockstep=exact_lockstep(sub_out / SCENARIOS_DIR / sc),
                                               by=scenario.repeat_by if scenario else "median"))
        findings[item.id] = combine_findings(item, per_scenario, item.scenario)
    mismatches = {}
    for sc, frames in frames_cache.items():
        if not isinstance(frames, Exception):
            mismatches[sc] = check_contract(rubric.contract, rubric.scenario_roles(sc), frames)
    findings.contract = merge_mismatches(mismatches)
    _fingerprint(sub_out, frames_cache, problems)
    return findings, problems


def _fingerprint(sub_out: Path, frames_cache: dict[str, Any], problems: list[str]) -> None:
    """Each read scenario's behaviour fingerprint (grader.similarity) next to its bag, while its
    frames are in memory: a class is then compared without reading its bags again."""
    from grader.similarity.behaviour import write_fingerprint

    for sc, frames in frames_cache.items():
        if isinstance(frames, Exception):
            continue
        try:
            write_fingerprint(sub_out / SCENARIOS_DIR / sc, frames)
        except Exception as exc:  # noqa: BLE001 - similarity never costs a grade
            problems.append(f"scenario {sc}: behaviour fingerprint not written ({type(exc).__name__}: {exc})")


def grade_submission(path: Path, rubric: Rubric, out_root: Path, *, cache_dir: Path | None = None,
                     public_only: bool = False, sid: str | None = None,
                     progress: Callable[[str], None] | None = None, slots: Slots | None = None,
                     reuse: bool = True, time_scale: float = 1.0, intake: dict | None = None,
                     due_override: dict | None = None) -> GradedSubmission:
    """Build, run the needed scenarios (side by side, within ``slots``), analyze and score one
    submission; writes its folder. ``reuse``: copy a scenario's recording when everything it
    runs is identical to an earlier run (see grader.grading.reuse). ``time_scale`` > 1: run
    scenarios that may on simulated time, that much faster (see grader.grading.timescale).
    ``intake``: how it arrived (grader.intake: ids, student, time), kept in ``intake.json``; with
    the rubric's late policy (its due date replaced by ``due_override``) it sets the penalty."""
    from grader.cache.locks import Holds
    from grader.cache.store import submission_cache_use
    from grader.grading.provenance import scenario_recordings
    from grader.grading.timescale import expected_rates
    from grader.intake.apply import apply_intake
    from grader.intake.model import public_record, write_record

    from grader.grading.schedule import Slots
    from grader.rubric.score import score
    from grader.scores.store import apply_saved_manual_scores, manual_scores_kept
    from grader.similarity.files import snapshot
    from grader.workspace import build_workspace
    from grader.workspace.build import default_cache_dir

    slots = slots or Slots(1)
    sid = sid or submission_id(Path(path))
    out = Path(out_root) / sid
    with manual_scores_kept(out):          # a re-grade keeps the TA's merged manual scores
        if out.exists():
            shutil.rmtree(out)
        out.mkdir(parents=True)
    if intake is not None:
        write_record(out, intake, due_override)
    timings: dict[str, float] = {}
    errors: list[str] = []
    say = progress or (lambda _msg: None)

    say(f"{sid}: building")
    t0 = time.monotonic()
    build = None
    holds = Holds()          # the build areas this submission runs stay out of a prune's reach
    try:
        with slots.taken():
            build = build_workspace(Path(path), cache_dir=cache_dir, support=dict(rubric.support), holds=holds)
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

    items = selected_items(rubric, public_only)
    recordings = (Path(cache_dir or default_cache_dir()) / "recordings") if reuse else None
    reused: dict[str, dict] = {}
    time_scales: dict[str, dict] = {}
    t1 = time.monotonic()
    scenario_ids = needed_scenarios(items)
    say(f"{sid}: scenarios {', '.join(scenario_ids)}")
    # longest first (by its step limits): when slots run short, a short scenario waits, not the
    # one that sets the submission's wall time
    longest_first = sorted(scenario_ids, key=lambda sc: -rubric.scenarios[sc].budget_s)
    with holds, ThreadPoolExecutor(max_workers=max(1, len(scenario_ids))) as pool:
        runs = {sc_id: pool.submit(_run_one, sid, sc_id, rubric.scenarios[sc_id], build, out, slots, recordings,
                                   time_scale, expected_rates(rubric, sc_id) if time_scale > 1 else (),
                                   settles_check([i for i in items if sc_id in i.scenario], rubric.scenarios[sc_id].repeat,
                                                 rubric.scenarios[sc_id].repeat_by))
                for sc_id in longest_first}
        for sc_id in scenario_ids:
            record = runs[sc_id].result()
            timings[f"scenario:{sc_id}:wall_s"] = record.get("parent_wall_s", 0.0)
            timings[f"scenario:{sc_id}:active_s"] = record.get("active_s", 0.0)
            errors += [f"scenario {sc_id}: {e}" for e in record.get("errors", [])]
            if record.get("reused"):
                reused[sc_id] = record["reused"]
            if time_scale > 1 and record.get("time_scale"):
                time_scales[sc_id] = record["time_scale"]
            if record.get("lockstep"):        # how a lockstep scenario's clock ran (and why not)
                time_scales[sc_id] = {"clock": "lockstep", **record["lockstep"]}
    timings["scenarios_wall_s"] = round(time.monotonic() - t1, 2)
    recordings_made = scenario_recordings(out)

    say(f"{sid}: analyzing")
    findings, problems = analyze_bags(rubric, items, out)
    errors += problems
    result, kept = apply_saved_manual_scores(out, score(rubric, findings))
    errors += kept
    result, late_notes = apply_intake(out, rubric, result)
    errors += late_notes
    if public_only:
        result = result.for_student()
    graded = GradedSubmission(sid, out, result, build_ok=bool(build and build.ok),
                              build_failed=list(build.failed) if build else ["(no build)"],
                              errors=errors, timings=timings, reused=reused, time_scales=time_scales,
                              recordings=recordings_made,
                              cache=submission_cache_use(build, recordings_made, reuse),
                              intake=public_record(out))
    write_outputs(graded, rubric, public_only=public_only)
    return graded


def _run_one(sid: str, sc_id: str, scenario: Scenario, build: Any, out: Path, slots: Slots, recordings: Path | None,
             time_scale: float = 1.0, rates: tuple = (), settles: Callable[[list[Path]], bool] | None = None) -> dict:
    """One scenario; a repeated one (``repeat: N``) run by run until its median is settled, each
    run recorded or reused by ``grader.grading.reuse.record_or_reuse``."""
    from grader.grading.reuse import record_or_reuse

    return run_until_settled(
        lambda k, folder: record_or_reuse(sid, sc_id, scenario, build, folder, slots, recordings, time_scale, rates,
                                          run=k),
        out / SCENARIOS_DIR, sc_id, scenario.repeat, settles)


def regrade_submission(sub_out: Path, rubric: Rubric, *, public_only: bool = False) -> GradedSubmission:
    """Recompute a submission's grade from its recorded bags only (no build, no ROS)."""
    from grader.rubric.score import score
    from grader.intake.apply import apply_intake
    from grader.intake.model import public_record
    from grader.scores.store import apply_saved_manual_scores

    sub_out = Path(sub_out)
    if not (sub_out / SCENARIOS_DIR).is_dir():
        raise GraderError(f"{sub_out} has no {SCENARIOS_DIR}/ folder; point at OUT/<submission> "
                          "written by `grader grade`.")
    from grader.grading.provenance import scenario_recordings
    from grader.report.result import previous_summary
    from grader.report.seal import input_digests, mac_ok

    items = selected_items(rubric, public_only)
    old: dict = {}
    if (sub_out / "result.json").exists():
        old = json.loads((sub_out / "result.json").read_text())
    unusable, notes = recordings_to_refuse(sub_out, old)
    findings, problems = analyze_bags(rubric, items, sub_out, unusable)
    result, kept = apply_saved_manual_scores(sub_out, score(rubric, findings))   # merged manual scores
    result, late_notes = apply_intake(sub_out, rubric, result)                   # late policy, again
    problems = notes + problems + kept + late_notes
    # the seal keeps the digests of what was graded; a result without one is sealed as it is now
    recorded = (old.get("seal") or {}).get("inputs")
    inputs = recorded if recorded is not None and mac_ok(old) else input_digests(sub_out)

    # the run's build/scenario problems and timings still describe the bags; keep them, and
    # which grader made each recording (provenance: another grader's are named in the report)
    graded = GradedSubmission(sub_out.name, sub_out, result, build_ok=old.get("build", {}).get("ok", True),
                              build_failed=old.get("build", {}).get("failed", []),
                              errors=list(dict.fromkeys([*old.get("errors", []), *problems])),
                              timings=old.get("timings", {}), previous=previous_summary(old),
                              time_scales=old.get("time_scale", {}), recordings=scenario_recordings(sub_out),
                              reused=old.get("scenarios_reused") or {}, intake=public_record(sub_out))
    write_outputs(graded, rubric, public_only=public_only, inputs=inputs)
    return graded


def recordings_to_refuse(sub_out: Path, old: dict) -> tuple[dict[str, str], list[str]]:
    """Scenarios whose recordings a regrade must not grade (changed since they were graded, or
    a bag that was not finalised cleanly), with why; and notes about the seal itself."""
    from grader.bag.frames import load_bag_meta
    from grader.report.seal import changed_inputs, mac_ok

    refuse: dict[str, str] = {}
    notes: list[str] = []
    if old.get("seal") is None:
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
    from grader.grading.outputs import write_submission_outputs

    write_submission_outputs(graded, rubric, public_only=public_only, inputs=inputs)
