"""The offline half of grading: a submission's scenario folders (bags and records) in, one
finding per rubric item out. It needs no ROS, so ``grader regrade`` recomputes a grade on any
machine from the bags alone (``grader.grading.pipeline`` runs the scenarios and calls it).

Each item's analyzer runs on each of its scenarios' frames (a repeated scenario: on each run,
combined by ``grader.grading.repeat``); a lost point gets the student's node's own failure (not
started, crashed, returned) as its reason; an item on several scenarios takes the worst.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence, cast

from grader.contracts.scenario_record import ScenarioRecord
from grader.contracts.output_folder import BAG_DIR, CANVAS_PNG, SCENARIO_JSON, SCENARIOS_DIR
from grader.analyze import timing, Finding
from grader.analyze._common import events, own_exits, stdout_lines
from grader.errors import GraderError
from grader.grading.repeat import exact_lockstep, outcome, repeated_finding, run_folders, settled
from grader.grading.starvation import recorded_scale, starvation
from grader.contracts.events import Graph, LimitHit, NodeUnavailable, StepStart
from grader import analyze
from grader.analyze.contract import check_contract
from grader.analyze.plugins import load_rubric_files
from grader.bag.frames import load_bag_meta, load_frames, canvas_frame
from grader.rubric.contract import merge_mismatches
from grader.rubric.score import worst_finding
from grader.similarity.behaviour import write_fingerprint

if TYPE_CHECKING:
    from grader.analyze import Finding
    from grader.rubric.schema import Item, Rubric


def scenario_frames(scenario_dir: Path) -> dict:
    """Frames of one scenario's bag plus ``__meta__`` (topic, type, count, publishers)."""
    import pandas as pd  # noqa: PLC0415 - pandas: 424 ms CPU to import, paid only on this path

    bag = scenario_dir / BAG_DIR
    if not bag.exists():
        return {"__meta__": pd.DataFrame(columns=["topic", "type", "count", "publishers"])}
    record_file = scenario_dir / SCENARIO_JSON
    record = ScenarioRecord.read(record_file) if record_file.exists() else None
    # a run on simulated time is read in simulated seconds (grader.bag.timebase): the bag's own
    # metadata says so (sealed with it); the record speaks only for a bag never finalised
    used = record.time_scale.used if record is not None and record.time_scale is not None else None
    finalized = (bag / "metadata.yaml").exists()
    locked = not finalized and record is not None and record.lockstep is not None and bool(record.lockstep.used)
    frames = load_frames(bag, time_scale=None if finalized or not used or locked else float(used),
                         lockstep=locked)
    meta = load_bag_meta(bag)
    publishers: dict[str, set[str]] = {}
    for snapshot in events(frames, Graph):
        for topic, nodes in snapshot.publishers.items():
            publishers.setdefault(topic, set()).update(nodes)
    frames["__meta__"] = pd.DataFrame(
        [{"topic": n, "type": t.type, "count": t.count, "publishers": sorted(publishers.get(n, set()))}
         for n, t in meta.topics.items()], columns=["topic", "type", "count", "publishers"])
    canvas = scenario_dir / CANVAS_PNG
    if canvas.exists():
        frames["__canvas__"] = canvas_frame(canvas)
    if record is not None:
        frames["__meta__"].attrs["scenario"] = record               # the starvation checks read it
    return frames


def _unavailable_nodes(frames: dict) -> list[str]:
    return [f"{e.process}: {e.error.splitlines()[0] if e.error else 'not available'}"
            for e in events(frames, NodeUnavailable)]


def _crashed_nodes(frames: dict) -> list[str]:
    """Student processes that exited on their own, with the last line of what they printed: a
    non-zero exit is a crash; exit code 0 means its main returned (it stopped spinning)."""
    lines = stdout_lines(frames)
    last_line = {process: str(raw).strip() for process, raw in zip(lines["process"], lines["raw"])
                 if str(raw).strip()}
    limits = [e.detail or e.limit for e in events(frames, LimitHit)]
    starts = sorted((s.t, s.step) for s in events(frames, StepStart))
    out = []
    for e in own_exits(frames):
        name = e.process or "?"
        tail = last_line.get(name, "")
        code = e.returncode
        # the step it died in: the rubric's scenario description says what that step sends
        step = [s for t, s in starts if t <= e.t]
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
    Otherwise an item about timing that lost points on a recording the grading machine starved
    is an error saying so (``starved_timing``).
    """
    finding = analyze.run(cast(str, item.analyzer), frames, dict(item.params))
    if finding.status not in ("fail", "error", "partial"):
        return finding      # only a lost point needs the events and output parsed for a reason
    missing = _unavailable_nodes(frames)
    crashed = _crashed_nodes(frames)
    if not missing and not crashed:          # a node that died explains its own lost points
        return starved_timing(item, finding, frames) or finding
    why = (["Could not run " + "; ".join(missing).rstrip(".") + "."] if missing else []) + \
          (["Node stopped: " + "; ".join(crashed).rstrip(".") + "."] if crashed else [])
    finding.feedback = (finding.feedback + " " + " ".join(why)).strip()
    finding.evidence = {**finding.evidence, "unavailable_nodes": missing, "crashed_nodes": crashed}
    if finding.status == "error" and item.kind != "integrity":
        finding.status, finding.fraction = "fail", 0.0
    return finding


def starved_timing(item: Item, finding: Finding, frames: dict) -> Finding | None:
    """``finding`` as an ``error`` when it lost points on timing that the grading machine's
    starvation of this recording explains (``grader.grading.starvation``): the measurement is
    of the machine, not of the code. None when the item does not depend on timing, the
    recording was not starved, or the student's own processes starved it."""
    words = timing(item.analyzer, item.timing)
    meta = frames.get("__meta__")
    record = meta.attrs.get("scenario") if meta is not None else None
    if finding.status not in ("fail", "partial") or not words or not isinstance(record, ScenarioRecord):
        return None
    scale = recorded_scale(record)
    found = starvation(record, scale=scale)
    if found is None or found.own:
        return None
    measured = finding.feedback.strip()
    return replace(finding, status="error", fraction=0.0,
                   feedback=(f"Not measured: the grading machine was too busy to measure {words} on this "
                             f"recording ({found.reason}), so it says nothing about your code; it needs a new "
                             f"recording on a quieter machine."
                             + (f" What this recording showed: {measured}" if measured else "")),
                   evidence={**finding.evidence, "starved": found.reason, "starved_status": finding.status}
                   | ({"starved_at_scale": scale} if scale > 1 else {}))


def combine_findings(item: Item, per_scenario: list, scenarios: Sequence[str] = ()) -> Finding | None:
    """One finding for an item run on several scenarios: the worst one counts (of equals, the
    first listed). With ``scenarios`` (their ids, in order), its ``decided`` lists how each
    scenario came out, so an item whose worst is one run still says it had repeated ones too.

    An integrity check is judged on the scenarios where it could run: a scenario in which the
    student's node never started (or recorded nothing to check) gives no evidence either way, so
    its "could not check" error does not hide the verdict of the others. Without that, whether the
    flag showed up would depend on how long the simulator ran before the empty scenario ended.
    """
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
                 unusable: dict[str, str] | None = None,
                 on_frames: Callable[[Path, Any], None] | None = None) -> tuple[Findings, list[str]]:
    """Run every item's analyzer on its scenario bags (offline). Returns findings and problems.
    ``unusable``: scenario -> why its recording must not be graded (changed since grading, not
    finalised): its items become errors saying so. ``on_frames(scenario folder, frames)``: called
    once per recording read, while its frames are in memory (the report's replay data)."""
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
    if on_frames is not None:
        for sc, frames in frames_cache.items():
            if not isinstance(frames, Exception):
                try:
                    on_frames(sub_out / SCENARIOS_DIR / sc, frames)
                except Exception as exc:  # noqa: BLE001 - a report's extra never costs a grade
                    problems.append(f"scenario {sc}: replay data not written ({type(exc).__name__}: {exc})")
    return findings, problems


def _fingerprint(sub_out: Path, frames_cache: dict[str, Any], problems: list[str]) -> None:
    """Each read scenario's behaviour fingerprint (grader.similarity) next to its bag, while its
    frames are in memory: a class is then compared without reading its bags again."""
    for sc, frames in frames_cache.items():
        if isinstance(frames, Exception):
            continue
        try:
            write_fingerprint(sub_out / SCENARIOS_DIR / sc, frames)
        except Exception as exc:  # noqa: BLE001 - similarity never costs a grade
            problems.append(f"scenario {sc}: behaviour fingerprint not written ({type(exc).__name__}: {exc})")


def settles_check(items: list, planned: int, by: str = "median") -> Callable[[list[Path]], bool] | None:
    """For a scenario run ``planned`` > 1 times: whether the runs recorded so far (their folders)
    settle every one of its ``items`` (``by``: the median or the worst); None for a scenario that
    runs once."""
    if planned <= 1:
        return None

    def check(folders: list[Path]) -> bool:
        if by == "median" and 2 * len(folders) <= planned:
            return False            # no majority yet: not worth reading the bags
        try:
            frames = [scenario_frames(f) for f in folders]
        except GraderError:
            return False
        return settled([[outcome(analyze_item(item, fr)) for fr in frames] for item in items], planned, by)

    return check
