"""``grader rubric audit RUBRIC``: mutation testing of a rubric.

A rubric is only as good as the bugs it can see. The audit mutates the lab's reference solution
(``grader.audit.mutate``: a flipped sign, a doubled constant, swapped arguments, a renamed
topic, a dropped publish...), grades every mutant with the ordinary pipeline (build, scenarios,
bags, analyzers, rubric) and sorts them:

* **killed**: the mutant lost at least one automatic point;
* **equivalent**: full marks, and the rubric's ``equivalent_mutants`` says why the mutated code
  is still correct;
* **surviving** (a blind spot): full marks and no such record. Its diff is in the report: either
  the rubric (or an analyzer) cannot tell that bug from a correct solution, or the mutant is
  correct and its reason belongs in the rubric;
* **error**: the mutant could not be graded (the grader's problem, not the mutant's).

The reference itself is graded first and must earn every automatic point (otherwise "lost a
point" would mean nothing). Mutants are graded as one batch (``grader.grading.batch``) within
``--jobs`` slots, with recording reuse: a mutant that does not touch the packages a scenario
runs gets the reference's recording of it, so only the scenarios it can change are run.
Files the rubric's handout gives out unchanged are the lab's own code, not the student's, and
are not mutated. Outputs in ``OUT``: ``workspaces/<id>/`` (each mutated copy),
``graded/<id>/`` (the usual result.json, report.html and bags; ``graded/index.html`` is the
class view of the mutants), ``audit.json`` and ``audit.md``.
"""

from __future__ import annotations

import filecmp
import shutil
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from grader.audit.mutate import COPY_IGNORE, Mutant, mutants, sample, source_files
from grader.audit.outcome import AuditReport, Outcome
from grader.audit.report import write_report
from grader.contracts.result_document import ResultDocument
from grader.contracts.output_folder import OutputFolder, SubmissionFolder
from grader.errors import GraderError
from grader.api import load_rubric
from grader.api.batch import Slots, find_packages, grade_batch, machine_time_scale
from grader.api.rubrics import ScenarioRun, display_path

if TYPE_CHECKING:
    from grader.api.batch import GradedSubmission

REFERENCE_ID = "reference"
_EPS = 1e-6


def find_reference(rubric: Any, explicit: Path | None) -> Path:
    """The reference solution: ``explicit``, else ``reference/`` beside the rubric's handout,
    else ``fixtures/submissions/<rubric file name>/reference`` of the rubric's checkout."""
    if explicit is not None:
        if not Path(explicit).is_dir():
            raise GraderError(f"--reference {explicit}: not a folder (give the reference solution's workspace)")
        return Path(explicit).resolve()
    source = Path(rubric.source)
    tried = []
    if rubric.handout is not None:
        tried.append(Path(rubric.handout).parent / "reference")
    tried.append(source.parent.parent / "fixtures" / "submissions" / source.stem / "reference")
    for path in tried:
        if path.is_dir():
            return path.resolve()
    raise GraderError(f"no reference solution found for {source.name} (looked in "
                      f"{', '.join(str(p) for p in tried)}); give it with --reference PATH")


def given_files(reference: Path, handout: Path | None) -> list[str]:
    """Python files of the reference that the handout gives out byte for byte (lab code)."""
    if handout is None or not Path(handout).is_dir():
        return []
    out = []
    for path in source_files(reference):
        rel = path.relative_to(reference)
        other = Path(handout) / rel
        if other.is_file() and filecmp.cmp(path, other, shallow=False):
            out.append(rel.as_posix())
    return out


def choose(rubric: Any, reference: Path, operators: list[str] | None, n: int | None,
           seed: int, all_files: bool = False) -> tuple[list[Mutant], int, list[str]]:
    """The mutants to grade, how many were made, and the given files left out."""
    given = set() if all_files else set(given_files(reference, rubric.handout))
    everything = mutants(reference, operators)
    found = [m for m in everything if m.file not in given]
    return sample(found, n, seed), len(found), sorted({m.file for m in everything if m.file in given})


def run_audit(rubric_path: Path, out: Path, *, reference: Path | None = None, jobs: int = 2,
              time_scale: float | None = None, reuse: bool = True, cache_dir: Path | None = None,
              sample_n: int | None = None, operators: list[str] | None = None, seed: int = 0,
              only: list[str] | None = None, all_files: bool = False, resume: bool = False,
              regrade: bool = False, say: Callable[[str], None] = print) -> AuditReport:
    """Mutate the reference, grade the reference and every chosen mutant, classify them and
    write ``audit.json`` and ``audit.md`` into ``out``. ``regrade``: grade the recordings
    already in ``out`` again with the rubric as it is now (offline: after changing items,
    parameters or analyzers; a mutant whose scenario changed must be run again)."""
    from grader.api.pipeline import grade_submission  # noqa: PLC0415 - api.pipeline loads grading.pipeline, pandas, numpy (424 ms CPU), only on this path

    time_scale = machine_time_scale(time_scale)

    rubric = load_rubric(rubric_path)
    ref = find_reference(rubric, reference)
    chosen, made, given = _choose_only(rubric, ref, operators, sample_n, seed, all_files, only)
    out = Path(out).resolve()
    workspaces, graded = out / "workspaces", out / "graded"
    workspaces.mkdir(parents=True, exist_ok=True)
    say(_plan_line(rubric.lab, made, ref, given, len(chosen), regrade, jobs, time_scale))
    slots = Slots(jobs)
    t0 = time.monotonic()
    rubric = _with_untouched_support(rubric, ref, chosen)

    if regrade:
        _regrade_all(rubric, graded, [REFERENCE_ID] + [m.id for m in chosen], say)
    ref_copy = workspaces / REFERENCE_ID
    if not regrade:
        _fresh_copy(ref, ref_copy)
    if not ((resume or regrade) and OutputFolder(graded).submission(REFERENCE_ID).result_json.exists()):
        say(f"grading the reference ({REFERENCE_ID})")
        grade_submission(ref_copy, rubric, graded, cache_dir=cache_dir, sid=REFERENCE_ID, slots=slots,
                         reuse=reuse, time_scale=time_scale)
    baseline = _read_result(graded / REFERENCE_ID)
    ref_wall = round(time.monotonic() - t0, 1)
    _check_reference(baseline, ref, graded)

    todo = _write_mutants(chosen, workspaces, graded, resume or regrade)
    failures = _grade_mutants(todo, len(chosen), rubric, graded, slots, cache_dir, reuse, time_scale, say)
    equivalents = {e.mutant: e.reason for e in rubric.equivalent_mutants}
    outcomes = [_outcome(m, graded / m.id, failures.get(m.id), equivalents) for m in chosen]
    report = AuditReport(rubric=display_path(Path(rubric_path).resolve()), lab=rubric.lab, reference=display_path(ref),
                         operators=list(operators or []), made=made, given_files=given, sample=sample_n,
                         seed=seed, time_scale=time_scale, jobs=jobs, outcomes=outcomes,
                         wall_s=round(time.monotonic() - t0, 1), reference_wall_s=ref_wall, regraded=regrade)
    if sample_n is None and not operators and not only:
        every = {m.id for m in mutants(ref)}
        report.stale_equivalents = sorted(set(equivalents) - every)

    write_report(report, out)
    return report


def _choose_only(rubric: Any, ref: Path, operators: list[str] | None, sample_n: int | None, seed: int,
                 all_files: bool, only: list[str] | None) -> tuple[list[Mutant], int, list[str]]:
    """``choose`` as a GraderError, narrowed to ``--only``: the audit's choosing stage in one place."""
    try:
        chosen, made, given = choose(rubric, ref, operators, sample_n, seed, all_files)
    except ValueError as exc:
        raise GraderError(str(exc)) from None
    if only:
        missing = sorted(set(only) - {m.id for m in chosen})
        if missing:
            raise GraderError(f"no mutant {', '.join(missing)} among the {len(chosen)} chosen "
                              "(ids come from an earlier report; check --operators/--sample)")
        chosen = [m for m in chosen if m.id in set(only)]
    return chosen, made, given


def _plan_line(lab: str, made: int, ref: Path, given: list[str], n_chosen: int, regrade: bool, jobs: int,
               time_scale: float) -> str:
    """The audit's opening line (what is mutated and how it is graded), kept out of the run's flow."""
    return (f"{lab}: {made} mutants of {display_path(ref)}"
            + (f" ({len(given)} given file(s) left out)" if given else "")
            + (f"; regrading the {n_chosen} recorded" if regrade else
               f"; grading {n_chosen} at --jobs {jobs}, --time-scale {time_scale:g}"))


def _check_reference(baseline: ResultDocument, ref: Path, graded: Path) -> None:
    """Refuse a reference short of full automatic marks: a mutant's lost point would mean nothing."""
    lost = _lost(baseline)
    if lost:
        raise GraderError(f"the reference solution {ref} does not earn every automatic point "
                          f"({baseline.auto_score:g}/{baseline.auto_max:g}: "
                          + ", ".join(f"{k} -{v:g}" for k, v in lost.items())
                          + f"; see {graded / REFERENCE_ID / 'report.html'}); a mutation audit needs a reference "
                          "at full marks: fix the rubric or the reference first")


def _write_mutants(chosen: list[Mutant], workspaces: Path, graded: Path, keep_graded: bool) -> list[Path]:
    """Write each mutant still to grade into a fresh workspace (``keep_graded``: skip those with a result)."""
    todo = []
    for m in chosen:
        dest = workspaces / m.id
        if keep_graded and OutputFolder(graded).submission(m.id).result_json.exists():
            continue
        if dest.exists():
            shutil.rmtree(dest)
        m.write(dest)
        todo.append(dest)
    return todo


def _grade_mutants(todo: list[Path], total: int, rubric: Any, graded: Path, slots: Slots, cache_dir: Path | None,
                   reuse: bool, time_scale: float, say: Callable[[str], None]) -> dict[str, str]:
    """Grade the written mutants as one batch, saying each verdict as it lands; why each one failed."""
    done_count = [total - len(todo)]

    def on_done(sid: str, graded_mutant: GradedSubmission | None, error: str | None) -> None:
        done_count[0] += 1
        verdict = (f"ERROR {error}" if error or graded_mutant is None else
                   f"{graded_mutant.result.auto_score:g}/{graded_mutant.result.auto_max:g}")
        say(f"[{done_count[0]}/{total}] {sid}: {verdict}")

    failures: dict[str, str] = {}
    if todo:
        failures = grade_batch(todo, rubric, graded, slots=slots, cache_dir=cache_dir, reuse=reuse,
                               on_done=on_done, time_scale=time_scale, on_notice=_notice)
    return failures


def _notice(text: str) -> None:
    """What the batch of mutants says (the cache's cap, a starved mutant graded again): stderr, as
    ``grader grade`` says it."""
    print(f"grader: {text}", file=sys.stderr)


def _with_untouched_support(rubric: Any, reference: Path, chosen: list[Mutant]) -> Any:
    """The rubric, with the reference's packages that no chosen mutant changes added to its
    ``support``: they are built once (grader.workspace.package_cache) instead of once per
    mutant (an interface package costs ~15 s of CPU to build). Grading is the same: a
    submission's byte-identical copy of a support package takes the support build."""
    touched = {m.file for m in chosen}
    extra = {}
    for pkg in find_packages(reference):
        rel = Path(pkg.path).resolve().relative_to(reference).as_posix()
        if pkg.name not in rubric.support and not any(f == rel or f.startswith(rel + "/") for f in touched):
            extra[pkg.name] = Path(pkg.path).resolve()
    return rubric.model_copy(update={"support": {**rubric.support, **extra}}) if extra else rubric


def _regrade_all(rubric: Any, graded: Path, ids: list[str], say: Callable[[str], None]) -> None:
    """Analyze and score the recorded mutants again (no ROS); refuse recordings of a scenario
    that is not the rubric's any more."""
    from grader.api.pipeline import SCENARIOS_DIR, regrade_submission  # noqa: PLC0415 - api.pipeline loads grading.pipeline, pandas, numpy (424 ms CPU), only on this path

    stale = []
    for sid in ids:
        folder = graded / sid
        if not (folder / SCENARIOS_DIR).is_dir():
            continue          # never graded: graded now, below
        for sc_id, scenario in rubric.scenarios.items():
            run_json = SubmissionFolder(folder).scenario(sc_id).run_json
            if run_json.is_file():
                recorded = ScenarioRun.model_validate_json(run_json.read_text()).scenario
                if recorded != scenario:
                    stale.append(f"{sid} ({sc_id})")
    if stale:
        raise GraderError(f"--regrade: the rubric's scenarios changed since these were recorded: "
                          f"{', '.join(stale[:5])}{' ...' if len(stale) > 5 else ''}; run the audit again "
                          "without --regrade (or into a new folder)")
    for sid in ids:
        if (graded / sid / SCENARIOS_DIR).is_dir():
            regrade_submission(graded / sid, rubric)
    say(f"regraded {len(ids)} recordings with the rubric as it is now")


def _fresh_copy(src: Path, dest: Path) -> None:
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(src, dest, ignore=shutil.ignore_patterns(*COPY_IGNORE), symlinks=True)


def _read_result(folder: Path) -> ResultDocument:
    path = SubmissionFolder(folder).result_json
    if not path.is_file():
        raise GraderError(f"{folder.name} has no result.json (grading did not finish)")
    try:
        return ResultDocument.read(path)
    except (OSError, ValueError) as exc:
        raise GraderError(str(exc)) from None


def _lost(doc: ResultDocument) -> dict[str, float]:
    """Automatic points an item did not earn, by item id."""
    out = {}
    for item in doc.items:
        if item.kind == "auto":
            gone = float(item.max_points or 0) - float(item.points or 0)
            if gone > _EPS:
                out[item.id] = round(gone, 3)
    return out


def _outcome(m: Mutant, folder: Path, failure: str | None, equivalents: dict[str, str]) -> Outcome:
    base = Outcome(mutant=m.summary(), diff=m.diff, status="error")
    try:
        doc = _read_result(folder)
    except GraderError as exc:
        base.error = failure or str(exc)
        return base
    timings = doc.timings
    base.wall_s = round(float(timings.get("build_s", 0)) + float(timings.get("scenarios_wall_s", 0)), 1)
    base.auto_score, base.auto_max = doc.auto_score, doc.auto_max
    base.lost = _lost(doc)
    if base.lost:
        base.status = "killed"
    elif m.id in equivalents:
        base.status, base.reason = "equivalent", equivalents[m.id]
    else:
        base.status = "surviving"
    return base
