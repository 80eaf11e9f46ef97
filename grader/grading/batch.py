"""A batch: many submissions graded within one budget of concurrent scenarios (``Slots``).

``grade_batch`` is what ``grader grade`` runs after choosing the submissions; it is also the
Python API for grading several labs at once within one budget (the fixture test grades every
lab's fixtures side by side this way). Ctrl-C cancels what has not started and stops running
scenarios cleanly (their bags are finalised); finished submissions and ``grades.csv`` are kept.
When it ends, the cache is brought under its size cap and the batch's hit counts are kept
(``grader.cache.store.end_batch``).

A submission whose timing items could not be measured because the grading machine starved
their recordings (``Result.starved``, ``grader.grading.starvation``) is graded again once the
batch is done, one submission and one scenario at a time, in real time (``rerun_starved``,
``grader.grading.starvation.REGRADE_TIME_SCALE``): the machine is then as quiet as this batch
can make it, and a stall is shortest in simulated time. With reuse on, its recordings made at
1x and not starved are reused (a starved recording is never kept for reuse); the new result
replaces the old.

Nothing here prints: what ``grader grade`` says on stderr while a batch runs (the class view
not rewritten, the cache's cap enforced, the starved submissions graded again) goes to
``on_notice``, one sentence each.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any, Callable

from grader.errors import GraderError
from grader.grading.schedule import Slots
from grader.grading.starvation import REGRADE_TIME_SCALE
from grader.cache import default_cache_dir
from grader.cache.store import end_batch
from grader.scenario import cancel_all
from grader.workspace.source import submission_id


def grade_batch(submissions: list, rubric: Any, out: Path, *, slots: Slots,
                cache_dir: Path | None = None, reuse: bool = True,
                on_done: Callable[[str, Any, str | None], None] | None = None,
                progress: Callable[[str], None] | None = None, time_scale: float | None = None,
                due_override: dict | None = None, cache_max_size: str | None = None,
                on_notice: Callable[[str], None] | None = None) -> dict[str, str]:
    """Grade ``submissions`` (paths, or grader.intake Arrivals with their ids and records) into
    ``out``; returns ``{submission id: why it has no result}``.

    ``on_done(id, graded or None, error or None)`` is called as each one finishes; ``progress``
    gets status lines when there is a single submission; ``time_scale`` as for
    ``grade_submission``; ``due_override``: ``--due`` (replaces the late policy's due date).
    ``grades.csv``/``index.html`` are rewritten after each submission, so they are current even
    if the batch is interrupted. ``cache_max_size``: the cache's cap (``5G``; default
    ``$GRADER_CACHE_MAX_SIZE`` or 5 GB). ``on_notice`` gets what the batch has to say (a warning,
    the cache's cap enforced, a regrade of starved submissions), one sentence each.
    """
    say = on_notice or _quiet
    from grader.grading.outputs import write_batch_outputs  # noqa: PLC0415 - grading.outputs loads pandas, numpy (424 ms CPU), only on this path
    from grader.grading.pipeline import grade_submission  # noqa: PLC0415 - grading.pipeline loads pandas, numpy (424 ms CPU), only on this path

    out.mkdir(parents=True, exist_ok=True)
    failures: dict[str, str] = {}
    uses: list[dict[str, int]] = []
    graded_now: dict[str, Any] = {}
    # (id, what to grade, arrival record or None)
    todo = [(s.id, s.path, s.record()) if hasattr(s, "record") else (submission_id(s), s, None)
            for s in submissions]
    # more submissions in flight than slots: one builds or analyzes while others' scenarios run
    with ThreadPoolExecutor(max_workers=slots.n + 1) as pool:
        futures = {pool.submit(grade_submission, path, rubric, out, cache_dir=cache_dir, sid=sid,
                               progress=progress if len(todo) == 1 else None, slots=slots,
                               reuse=reuse, time_scale=time_scale, intake=record,
                               due_override=due_override): sid for sid, path, record in todo}
        try:
            for fut in as_completed(futures):
                sid = futures[fut]
                try:
                    graded, error = fut.result(), None
                except GraderError as exc:
                    graded, error = None, str(exc)
                except KeyboardInterrupt:
                    graded, error = None, "interrupted before it finished (no result written)"
                if error or graded is None:
                    failures[sid] = error or "no result"
                else:
                    uses.append(graded.cache)
                    graded_now[sid] = graded
                if on_done:
                    on_done(sid, graded, error)
                try:
                    write_batch_outputs(out, rubric)
                except GraderError as exc:      # the class view waits; grading goes on
                    say(f"warning: grades.csv/index.html not updated: {exc}")
        except KeyboardInterrupt:
            for f in futures:
                f.cancel()
            cancel_all()          # running scenarios finalize their bags and stop
            raise
    failures.update(rerun_starved(graded_now, todo, rubric, out, cache_dir=cache_dir, reuse=reuse,
                                  due_override=due_override, on_done=on_done, on_notice=say))
    ended = end_batch(Path(cache_dir or default_cache_dir()), uses, cache_max_size)
    if ended.get("message"):
        say(str(ended["message"]))
    return failures


def _quiet(_text: str) -> None:
    """No one listens to a batch's notices."""


def rerun_starved(graded: dict[str, Any], todo: list[tuple[str, Any, Any]], rubric: Any, out: Path, *,
                  cache_dir: Path | None, reuse: bool, due_override: dict | None,
                  on_done: Callable[[str, Any, str | None], None] | None,
                  on_notice: Callable[[str], None] | None = None) -> dict[str, str]:
    """Grade again, one at a time, each submission of ``graded`` whose result has starved timing
    items; returns ``{id: why it has no result}`` for those that could not be graded again (their
    earlier result went with the new attempt). The class view is rewritten after each."""
    from grader.grading.outputs import write_batch_outputs  # noqa: PLC0415 - grading.outputs loads pandas, numpy (424 ms CPU), only on this path
    from grader.grading.pipeline import grade_submission  # noqa: PLC0415 - grading.pipeline loads pandas, numpy (424 ms CPU), only on this path

    say = on_notice or _quiet
    again = [(sid, path, record) for sid, path, record in todo if sid in graded and graded[sid].result.starved]
    if again:
        say(f"{len(again)} submission(s) had timing items the grading machine was too busy to measure; "
            "recording their scenarios again, one at a time, in real time")
    failures: dict[str, str] = {}
    for sid, path, record in again:
        try:
            regraded = grade_submission(path, rubric, out, cache_dir=cache_dir, sid=sid, slots=Slots(1),
                                        reuse=reuse, time_scale=REGRADE_TIME_SCALE, intake=record,
                                        due_override=due_override)
        except GraderError as exc:
            failures[sid] = f"graded again (timing not measured the first time), but: {exc}"
            if on_done:
                on_done(sid, None, failures[sid])
            continue
        if regraded.result.starved:
            say(f"{sid}: still not measured on a starved machine: {', '.join(regraded.result.starved)} "
                "(the class view lists it; `grader grade --only " + sid + "` later)")
        if on_done:
            on_done(sid, regraded, None)
        write_batch_outputs(out, rubric)
    return failures
