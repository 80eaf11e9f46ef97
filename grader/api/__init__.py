"""The grader as a Python library: the functions the ``grader`` command itself calls.

Each function is the engine behind one command (as otter-grader's ``grade_submission`` is behind
``otter grade``): ``grader grade`` is :func:`grade`, ``grader check`` is :func:`check`, ``grader
regrade`` is :func:`regrade`, ``grader merge`` is :func:`merge`; the CLI only parses its
arguments and prints. So a notebook, a
course's own script or a test gets exactly what the command line gets::

    from grader import api

    rubric = api.load_rubric("rubrics/enee467_lab3.yaml")          # RubricError: file:line problems
    batch = api.grade("canvas-download.zip", rubric, "out/", jobs=2)  # build, record, analyze, score
    for graded in batch.graded:
        print(graded.id, graded.result.score, graded.result.total_max)
    api.regrade("out/", rubric)                                     # after changing a threshold
    frames = api.read_frames("out/alice/scenarios/ex1_publisher")   # topic -> pandas DataFrame
    finding = api.analyze(rubric, "ex1.pub_rate", frames)           # one item, offline

User errors raise :class:`grader.errors.GraderError` (one actionable sentence), as the CLI
reports them. Paths may be ``str`` or ``pathlib.Path``; a rubric may be a path or a loaded
:class:`~grader.rubric.schema.Rubric`. Nothing here prints: what a command says comes back as
data (:attr:`BatchResult.similarity`, :attr:`MergeResult.similarity`) or through a callback
(``grade``'s and ``check``'s ``on_notice``).

Every front-end of the grader (the ``grader`` command and its subcommands, Gradescope, Classroom,
the audit, the doctor) reaches the engine through this package and ``grader.contracts`` only
(pyproject's import-linter contract "front-ends reach the engine through grader.api"). Beside the
functions above, its modules hold what the front-ends compose themselves, each the engine's own
typed, documented names: :mod:`grader.api.rubrics` (labs, the rubric's schema, guide, contract
roles, staging), :mod:`grader.api.batch` (a batch's parts: ``grade_batch``, ``Slots``, the support
build), :mod:`grader.api.pipeline` (one submission through the pipeline, ``grader check``'s
table; loads pandas), :mod:`grader.api.similarity` (a class compared; loads pandas),
:mod:`grader.api.machine` (what ``grader doctor`` reports, its self-tests),
:mod:`grader.api.bags` (a bag's info, repair, verification; loads numpy) and
:mod:`grader.api.tools` (the recorder, replay, cache, build, simulator, scores and labs commands'
engine).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

from pydantic import ValidationError

from grader.errors import GraderError
from grader.contracts.output_folder import SCENARIOS_DIR, SubmissionFolder
from grader.cache import default_cache_dir
from grader.cache.store import end_batch
from grader.grading.batch import grade_batch
from grader.grading.schedule import Slots, default_jobs
from grader.grading.shards import in_shard, merge_outputs, write_shard_note
from grader.grading.starvation import REGRADE_TIME_SCALE
from grader.grading.timescale import machine_time_scale
from grader.labs import rubric_for_lab
from grader.rubric.load import load_rubric as load, display_path
from grader.rubric.schema import Rubric

if TYPE_CHECKING:
    import pandas as pd

    from grader.analyze import Finding
    from grader.grading.graded import GradedSubmission
    from grader.intake.batch import IntakeBatch
    from grader.intake.model import Arrival
    from grader.rubric.schema import Rubric
    from grader.scores.roster import Roster
    from grader.api.similarity import ClassComparison, Settings as SimilaritySettings

__all__ = ["BatchResult", "MergeResult", "PathLike", "analyze", "check", "grade", "load_rubric", "merge", "read_frames",
           "regrade"]

PathLike = str | os.PathLike[str]


def load_rubric(path: PathLike, *, check_files: bool = True) -> Rubric:
    """Load and validate a rubric (its own analyzer files imported, every problem listed as
    ``file:line: field: message`` in a :class:`grader.rubric.load.RubricError`)."""
    return load(path, check_files=check_files)


def _rubric(rubric: PathLike | Rubric) -> Rubric:
    from grader.analyze.plugins import load_rubric_files  # noqa: PLC0415 - analyze.plugins loads pandas, numpy (424 ms CPU), only on this path

    if isinstance(rubric, Rubric):
        load_rubric_files(rubric)          # a Rubric built without load_rubric: its analyzer files
        return rubric
    return load_rubric(rubric)


@dataclass
class BatchResult:
    """What :func:`grade` did: one GradedSubmission per graded submission (in finishing order),
    the submissions that have no result and why, the ones the intake refused, whether a
    KeyboardInterrupt stopped the batch (finished submissions are saved; ``resume=True`` goes on)
    and what comparing the class afterwards gave (None when it was not asked for or had fewer
    than two submissions to compare)."""

    out: Path
    graded: list[GradedSubmission] = field(default_factory=list)
    failures: dict[str, str] = field(default_factory=dict)
    refused: dict[str, str] = field(default_factory=dict)
    interrupted: bool = False
    similarity: ClassComparison | None = None

    @property
    def ok(self) -> bool:
        """Every submission given was graded."""
        return not (self.failures or self.refused or self.interrupted)


def due_override(rubric: Rubric, due: str | None, timezone: str | None) -> dict[str, str | None] | None:
    """``due``/``timezone`` (``grader grade --due/--timezone``) checked against the rubric's late
    policy: the override :func:`grade` passes on, or None."""
    if due is None:
        if timezone:
            raise GraderError("--timezone goes with --due (the rubric's late policy has its own time zone)")
        return None
    if rubric.late is None:
        raise GraderError(f"--due replaces the due date of the rubric's late policy, and {display_path(rubric.source)} has "
                          "none: add a late: section to the rubric (rubrics/README.md, \"Late policy\")")
    try:
        rubric.late.with_due(due, timezone)
    except ValidationError as exc:
        raise GraderError("--due: " + "; ".join(e["msg"].removeprefix("Value error, ") for e in exc.errors())) from None
    return {"due": due, "timezone": timezone}


def grade(submissions: PathLike, rubric: PathLike | Rubric, out: PathLike, *,
          jobs: int | None = None, only: Sequence[str] | None = None, shard: tuple[int, int] | None = None,
          resume: bool = False, reuse: bool = True, cache_dir: PathLike | None = None,
          time_scale: float | None = None, intake: str = "auto", roster: PathLike | None = None,
          roster_map: Sequence[str] = (), classroom_prefix: str | None = None,
          due: str | None = None, timezone: str | None = None, cache_max_size: str | None = None,
          similarity: SimilaritySettings | None = None,
          on_intake: Callable[[IntakeBatch], None] | None = None,
          on_start: Callable[[int, int], None] | None = None,
          on_done: Callable[[str, GradedSubmission | None, str | None], None] | None = None,
          progress: Callable[[str], None] | None = None,
          on_notice: Callable[[str], None] | None = None) -> BatchResult:
    """``grader grade``: build each submission, record the rubric's scenarios, analyze, score.

    ``submissions``: a Canvas download, a Gradescope export, Classroom clones (``classroom_prefix``),
    a folder of submissions or one submission (``intake`` says which when its shape does not).
    Writes ``out/<id>/`` (result.json, report.html, bags, logs), ``out/grades.csv``,
    ``out/index.html`` and ``out/intake.csv``. ``jobs``: scenarios and builds at once (default:
    twice the CPUs the grader is given: its cgroup's quota, not the host's cores); ``only``: these ids; ``shard=(k, n)``: shard k of n (``grader merge``);
    ``resume``: skip ids that have a result.json; ``reuse``: copy identical earlier recordings;
    ``time_scale`` > 1: simulated time where the rubric allows; ``roster`` (+ ``roster_map``
    ``FIELD=COLUMN`` entries): match each submission to a student; ``due``/``timezone``: replace
    the late policy's due date; ``cache_max_size`` (``5G``, ``800M``): the cache's cap, enforced
    least-recently-used at the end of the batch (default ``$GRADER_CACHE_MAX_SIZE`` or 5 GB);
    ``similarity``: compare the graded class afterwards (``grader.similarity``: source and
    behaviour, written to ``out/similarity/`` and the class view; never for a shard, which
    ``grader merge`` compares once merged). ``on_intake`` gets what was found, ``on_start(selected, done)``
    how many submissions are to be graded and how many of them already are (``resume``) before
    grading starts, ``on_done(id, graded or None, error or None)`` each finished submission,
    ``progress`` status lines of a single submission, ``on_notice`` what the command says on stderr
    while the batch runs (a warning, the cache's cap enforced, starved submissions graded again).
    """
    loaded = _rubric(rubric)
    out = Path(out)
    override = due_override(loaded, due, timezone)
    students = _read_students(roster, roster_map)
    found = _take_in(submissions, loaded, out, students, classroom_prefix, intake, on_intake)
    batch, subs = _select(found, loaded, out, submissions, only, shard)
    todo = [s for s in subs if not (resume and graded_and_measured(out / s.id))]
    if on_start is not None:
        on_start(len(subs), len(subs) - len(todo))
    _run_batch(batch, todo, loaded, out, jobs=jobs, cache_dir=cache_dir, reuse=reuse, time_scale=time_scale,
               override=override, cache_max_size=cache_max_size, on_done=on_done, progress=progress,
               on_notice=on_notice)
    if similarity is not None and not batch.interrupted and not shard:
        batch.similarity = _compare(out, loaded, similarity)
    return batch


def _compare(out: Path, loaded: Rubric, similarity: SimilaritySettings | None) -> ClassComparison | None:
    """The class compared after grading (never raises: the grades are written)."""
    from grader.api.similarity import compare_graded  # noqa: PLC0415 - api.similarity loads grading.similarity, pandas, numpy (424 ms CPU), only on this path

    return compare_graded(out, loaded, similarity)


@dataclass
class MergeResult:
    """What :func:`merge` did: the ids merged, and what comparing the merged class gave."""

    out: Path
    merged: list[str]
    similarity: ClassComparison | None = None


def merge(parts: Sequence[PathLike], out: PathLike, rubric: PathLike | Rubric, *,
          similarity: SimilaritySettings | None = None) -> MergeResult:
    """``grader merge``: copy the submissions of the shard outputs ``parts`` (``grade(...,
    shard=(k, n))``) into ``out``, rebuild ``grades.csv`` and ``index.html``, then compare the
    class (``similarity``, as for :func:`grade`). Refuses a part graded with another rubric or a
    submission two parts both hold (nothing is copied then)."""
    from grader.grading.outputs import write_batch_outputs  # noqa: PLC0415 - grading.outputs loads pandas, numpy (424 ms CPU), only on this path

    loaded = _rubric(rubric)
    where = Path(out)
    merged = merge_outputs([Path(p) for p in parts], where, loaded)
    write_batch_outputs(where, loaded)
    return MergeResult(where, merged, _compare(where, loaded, similarity))


def _read_students(roster: PathLike | None, roster_map: Sequence[str]) -> Roster | None:
    """Read ``roster`` (``--map`` needs it) before :func:`grade` writes anything, so a bad one changes nothing."""
    from grader.scores.roster import parse_mapping, read_roster  # noqa: PLC0415 - scores.roster loads pandas, numpy (424 ms CPU), only on this path

    if roster_map and not roster:
        raise GraderError("--map describes the roster's columns: give the roster with --roster")
    return read_roster(Path(roster), parse_mapping(list(roster_map)), require_submission=False) if roster else None


def _take_in(submissions: PathLike, loaded: Rubric, out: Path, students: Roster | None,
             classroom_prefix: str | None, intake: str, on_intake: Callable[[IntakeBatch], None] | None
             ) -> IntakeBatch:
    """Find what ``submissions`` holds and write ``out/intake.csv``, so the intake is on disk before grading."""
    from grader.intake.batch import WORK_DIR, read_intake  # noqa: PLC0415 - intake.batch loads pandas, numpy (424 ms CPU), only on this path
    from grader.report.result import atomic_write  # noqa: PLC0415 - report.result loads pandas, numpy (424 ms CPU), only on this path

    out.mkdir(parents=True, exist_ok=True)
    found = read_intake(Path(submissions), loaded, work=out / WORK_DIR, roster=students,
                        classroom_prefix=classroom_prefix, kind=intake)
    if on_intake is not None:
        on_intake(found)
    atomic_write(out / "intake.csv", found.csv_text())
    return found


def _select(found: IntakeBatch, loaded: Rubric, out: Path, submissions: PathLike, only: Sequence[str] | None,
            shard: tuple[int, int] | None) -> tuple[BatchResult, list[Arrival]]:
    """The submissions this run grades (``only``, ``shard``) and the BatchResult that reports on them."""
    subs = found.gradable
    batch = BatchResult(out, refused={a.original[0]: a.refused or "" for a in found.refused})
    if only:
        subs = [s for s in subs if s.id in set(only)]
        if not subs:
            raise GraderError(f"none of {', '.join(only)} is among the submissions in {submissions}.")
        batch.refused = {}
    if shard:
        subs = [s for s in subs if in_shard(s.id, *shard)]
        write_shard_note(out, loaded, *shard)
    return batch, subs


def _run_batch(batch: BatchResult, todo: list[Arrival], loaded: Rubric, out: Path, *, jobs: int | None,
               cache_dir: PathLike | None, reuse: bool, time_scale: float | None,
               override: dict[str, str | None] | None, cache_max_size: str | None,
               on_done: Callable[[str, GradedSubmission | None, str | None], None] | None,
               progress: Callable[[str], None] | None, on_notice: Callable[[str], None] | None) -> None:
    """Grade ``todo`` into ``batch``, writing the batch files even when interrupted, so finished ones are kept."""
    from grader.grading.outputs import write_batch_outputs  # noqa: PLC0415 - grading.outputs loads pandas, numpy (424 ms CPU), only on this path

    def done(sid: str, graded: GradedSubmission | None, error: str | None) -> None:
        if graded is not None:          # graded again at the end of the batch (starved): replaced
            batch.graded = [g for g in batch.graded if g.id != sid] + [graded]
        if on_done is not None:
            on_done(sid, graded, error)

    try:
        batch.failures = grade_batch(todo, loaded, out, slots=Slots(jobs or default_jobs()),
                                     cache_dir=Path(cache_dir) if cache_dir else None, reuse=reuse,
                                     on_done=done, progress=progress, time_scale=time_scale,
                                     due_override=override, cache_max_size=cache_max_size,
                                     on_notice=on_notice)
    except KeyboardInterrupt:
        batch.interrupted = True
    finally:
        write_batch_outputs(out, loaded)
    batch.interrupted = batch.interrupted or any("interrupted" in m for m in batch.failures.values())


def graded_and_measured(sub_out: Path) -> bool:
    """``--resume`` skips this submission: it has a result, and no item of it waits for a
    recording the grading machine did not starve (``Result.starved``)."""
    from grader.report.result import read_result  # noqa: PLC0415 - report.result loads pandas, numpy (424 ms CPU), only on this path

    path = SubmissionFolder(sub_out).result_json
    if not path.exists():
        return False
    try:
        return not read_result(path)[1].starved
    except GraderError:
        return False        # unreadable: graded again


def check(workspace: PathLike = ".", *, lab: str | None = None, rubric: PathLike | Rubric | None = None,
          out: PathLike | None = None, jobs: int | None = None, cache_dir: PathLike | None = None,
          reuse: bool = True, time_scale: float | None = None, cache_max_size: str | None = None,
          progress: Callable[[str], None] | None = None,
          on_notice: Callable[[str], None] | None = None) -> GradedSubmission:
    """``grader check``: a student's self-check of ``workspace`` on the lab's public items.

    The rubric is ``rubric`` or the one of ``lab`` (an id of ``grader labs``). Writes the report
    to ``out`` (default ``WORKSPACE/.grader-check``). ``graded.result`` holds each item's status.
    ``on_notice`` gets what the command says on stderr (recorded again in real time because the
    machine was too busy; the cache's cap enforced): one sentence each.
    """
    say = on_notice or (lambda _text: None)
    from grader.grading.pipeline import grade_submission  # noqa: PLC0415 - grading.pipeline loads pandas, numpy (424 ms CPU), only on this path

    if rubric is None and lab is None:
        raise GraderError("say which lab to check: --lab enee467-lab3 (or --rubric FILE).")
    loaded = _rubric(rubric if rubric is not None else rubric_for_lab(str(lab)))
    ws = Path(workspace).resolve()
    where = (Path(out) if out is not None else ws / ".grader-check").resolve()

    graded = grade_submission(ws, loaded, where, cache_dir=Path(cache_dir) if cache_dir else None,
                              public_only=True, sid="check", progress=progress,
                              slots=Slots(jobs or default_jobs(time_scale=machine_time_scale(time_scale))), reuse=reuse,
                              time_scale=time_scale)
    if graded.result.starved_faster:      # its 1x recordings were made already, three times if starved
        say(f"the machine was too busy to measure {', '.join(graded.result.starved_faster)} faster "
            "than real time: recording again in real time")
        graded = grade_submission(ws, loaded, where, cache_dir=Path(cache_dir) if cache_dir else None,
                                  public_only=True, sid="check", progress=progress, slots=Slots(1), reuse=reuse,
                                  time_scale=REGRADE_TIME_SCALE)
    ended = end_batch(Path(cache_dir or default_cache_dir()), [graded.cache], cache_max_size)
    if ended.get("message"):
        say(str(ended["message"]))
    return graded


def regrade(path: PathLike, rubric: PathLike | Rubric, *,
            on_done: Callable[[GradedSubmission], None] | None = None) -> list[GradedSubmission]:
    """``grader regrade``: recompute grades from recorded bags only (no build, no ROS).

    ``path`` is a batch (``OUT``: every ``OUT/<id>`` is regraded and the batch files rewritten)
    or one submission (``OUT/<id>``). ``on_done`` gets each one as it is regraded.
    """
    from grader.grading.outputs import write_batch_outputs  # noqa: PLC0415 - grading.outputs loads pandas, numpy (424 ms CPU), only on this path
    from grader.grading.pipeline import regrade_submission  # noqa: PLC0415 - grading.pipeline loads pandas, numpy (424 ms CPU), only on this path

    loaded = _rubric(rubric)
    path = Path(path)
    if (path / SCENARIOS_DIR).is_dir():
        graded = regrade_submission(path, loaded)
        if on_done is not None:
            on_done(graded)
        return [graded]
    subs = sorted(p for p in path.iterdir() if (p / SCENARIOS_DIR).is_dir()) if path.is_dir() else []
    if not subs:
        raise GraderError(f"{path} holds no graded submissions (no */{SCENARIOS_DIR}/ folders).")
    out: list[GradedSubmission] = []
    for sub in subs:
        out.append(regrade_submission(sub, loaded))
        if on_done is not None:
            on_done(out[-1])
    write_batch_outputs(path, loaded)
    return out


def read_frames(path: PathLike, topics: Sequence[str] | None = None) -> dict[str, pd.DataFrame]:
    """A recording as the analyzers see it: topic name -> DataFrame (index ``t``: receive time in
    seconds; message fields flattened with dots; docs/ARCHITECTURE.md, "Bag → DataFrames").

    ``path``: a scenario folder of a graded submission (``OUT/<id>/scenarios/<scenario>``; the
    frames then include ``__meta__`` and the saved canvas, exactly what its items were graded
    on) or a bag folder (rosbag2 MCAP: ``metadata.yaml`` + ``*.mcap``). ``topics`` selects topics
    of a bag (naming one the bag lacks is an error).
    """
    from grader.bag.frames import load_frames  # noqa: PLC0415 - bag.frames loads pandas, numpy (424 ms CPU), only on this path
    from grader.grading.analysis import scenario_frames  # noqa: PLC0415 - grading.analysis loads pandas, numpy (424 ms CPU), only on this path

    where = Path(path)
    if not where.exists():
        raise GraderError(f"{where} not found: give a scenario folder (OUT/<id>/scenarios/<scenario>) or a bag folder")
    if (where / "bag").is_dir() and topics is None:
        return scenario_frames(where)
    bag = where / "bag" if (where / "bag").is_dir() else where
    return load_frames(bag, list(topics) if topics is not None else None)


def analyze(rubric: PathLike | Rubric, item_id: str,
            frames: Mapping[str, pd.DataFrame] | PathLike) -> Finding:
    """One rubric item's analyzer on one recording (frames, or a folder as for
    :func:`read_frames`), as grading runs it: the item's parameters over the analyzer's
    defaults; never raises for the recording's sake (an analysis that cannot happen is an
    ``error`` finding). Scoring (partial credit, ``requires``, the contract) is not applied."""
    from grader.grading.analysis import analyze_item  # noqa: PLC0415 - grading.analysis loads pandas, numpy (424 ms CPU), only on this path

    loaded = _rubric(rubric)
    try:
        item = loaded.item(item_id)
    except KeyError:
        raise GraderError(f"rubric {loaded.lab} has no item {item_id!r}; its items: "
                          f"{', '.join(loaded.item_ids)}") from None
    if not item.analyzer:
        raise GraderError(f"item {item_id!r} is graded by a person (kind: {item.kind}): it has no analyzer")
    given = read_frames(frames) if isinstance(frames, (str, os.PathLike)) else dict(frames)
    return analyze_item(item, given)
