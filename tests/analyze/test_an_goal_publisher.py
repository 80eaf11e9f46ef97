"""Exercise 2 goal publisher: typed goals appear on /turtle1/goal; a malformed line is survived."""

from __future__ import annotations

import pandas as pd

from analyze_synth import T0, check, events_frame, frame, stdout_frame, with_meta
from grader.analyze import get

LINES = [(T0 + 2.0, "2.0,7.0"), (T0 + 4.0, "hello"), (T0 + 6.0, "8.0,3.0")]


def _frames(published, exit_t=None, traceback=False, lines=LINES) -> dict:
    ev = [(T0, "scenario_start", {})] + [(t, "stdin_line", {"process": "goal_publisher", "line": ln})
                                         for t, ln in lines]
    if exit_t is not None:
        ev.append((exit_t, "process_exit", {"process": "goal_publisher", "returncode": 1}))
    ev.append((T0 + 10, "scenario_end", {}))
    fr = {"/grader/events": events_frame(sorted(ev, key=lambda r: r[0]))}
    if published:
        fr["/turtle1/goal"] = frame([p[0] for p in published], **{
            "data[0]": [p[1] for p in published], "data[1]": [p[2] for p in published],
            "data.len": [p[3] if len(p) > 3 else 2 for p in published]})
    out = [(T0 + 1.0, "goal_publisher", "stdout", "Goal Position x,y: ")]
    if traceback:
        out += [(T0 + 4.1, "goal_publisher", "stderr", "Traceback (most recent call last):"),
                (T0 + 4.1, "goal_publisher", "stderr", '  File "goal_publisher.py", line 30, in main'),
                (T0 + 4.1, "goal_publisher", "stderr", "ValueError: not enough values to unpack (expected 2, got 1)")]
    fr["/grader/stdout"] = stdout_frame(out)
    return with_meta(fr)


GOOD = [(T0 + 2.01, 2.0, 7.0), (T0 + 6.01, 8.0, 3.0)]


def test_both_goals_in_order() -> None:
    fr = _frames(GOOD)
    f = check(get("goal_publisher")(fr, {}))
    assert f.status == "pass" and f.evidence["found_in_order"] == 2
    assert f.evidence["expected"] == [[2.0, 7.0], [8.0, 3.0]]
    f = check(get("goal_publisher_robust")(fr, {}))
    assert f.status == "pass" and f.evidence["malformed_line"] == "hello"


def test_crash_on_malformed_line() -> None:
    """A crash on the malformed line costs the robustness item; the goals typed after it are not
    also counted against publishing (the lab text's own goal publisher crashes there)."""
    fr = _frames(GOOD[:1], exit_t=T0 + 4.1, traceback=True)
    f = check(get("goal_publisher")(fr, {}))
    assert f.status == "pass" and f.evidence["expected"] == [[2.0, 7.0]], f.evidence
    assert f.evidence["after_malformed"] == {"line": "hello", "not_counted": ["8.0,3.0"]}
    assert "stopped on the malformed line 'hello'" in f.feedback
    f = check(get("goal_publisher_robust")(fr, {}))
    assert f.status == "fail" and "ValueError" in f.feedback and "try/except" in f.feedback


def test_a_dying_node_gets_one_grade_whenever_the_next_line_reaches_it() -> None:
    """Issue 22 (bench_flake): the node crashed on the malformed line; the next line, typed 1 s
    later, reached it while it was still dying in one run (1 of 2 goals: partial) and found it gone
    in the others (pass). Wherever the exit falls against the next line, both items agree."""
    seen = set()
    for exit_t in (T0 + 4.3, T0 + 5.9, T0 + 6.2, T0 + 7.5):
        for delivered in (True, False):
            fr = _frames(GOOD[:1], exit_t=exit_t, traceback=True, lines=LINES[:2])
            extra = events_frame([(T0 + 6.0, "stdin_line", {"process": "goal_publisher", "line": "8.0,3.0",
                                                            "delivered": delivered})])
            fr["/grader/events"] = pd.concat([fr["/grader/events"], extra]).sort_index()
            a = check(get("goal_publisher")(fr, {}))
            b = check(get("goal_publisher_robust")(fr, {}))
            seen.add((a.status, a.fraction, b.status, b.fraction))
    assert seen == {("pass", 1.0, "fail", 0.0)}, seen


def test_a_node_that_survives_the_malformed_line_owes_the_next_goal() -> None:
    f = check(get("goal_publisher")(_frames(GOOD[:1]), {}))
    assert f.status == "partial" and "8, 3" in f.feedback and "after_malformed" not in f.evidence


def test_crash_seen_only_in_the_exit_event() -> None:
    f = check(get("goal_publisher_robust")(_frames(GOOD[:1], exit_t=T0 + 4.2), {}))
    assert f.status == "fail" and "exit code 1" in f.feedback


def test_alive_but_second_goal_never_published() -> None:
    f = check(get("goal_publisher_robust")(_frames(GOOD[:1]), {}))
    assert f.status == "fail" and "never published" in f.feedback


def test_swapped_coordinates_are_explained() -> None:
    f = check(get("goal_publisher")(_frames([(T0 + 2.01, 7.0, 2.0), (T0 + 6.01, 3.0, 8.0)]), {}))
    assert f.status == "fail" and "swapped" in f.feedback


def test_wrong_order_gets_partial_credit_only_for_the_prefix() -> None:
    f = check(get("goal_publisher")(_frames([(T0 + 2.01, 8.0, 3.0), (T0 + 6.01, 2.0, 7.0)]), {}))
    assert f.status == "partial" and f.evidence["found_in_order"] == 1


def test_extra_values_are_reported() -> None:
    f = check(get("goal_publisher")(_frames([(t, x, y, 3) for t, x, y in GOOD]), {}))
    assert f.status == "pass" and "exactly [x, y]" in f.feedback


def test_no_goal_topic() -> None:
    f = check(get("goal_publisher")(_frames([]), {}))
    assert f.status == "fail" and "/turtle1/goal" in f.feedback


def test_expected_param_without_stdin_events() -> None:
    fr = with_meta({"/turtle1/goal": frame([T0 + 1, T0 + 2], **{"data[0]": [2.0, 8.0], "data[1]": [7.0, 3.0],
                                                                 "data.len": 2})})
    assert check(get("goal_publisher")(fr, {})).status == "pass"
    assert check(get("goal_publisher")(fr, {"expected": [[1.0, 1.0]]})).status == "fail"
    assert check(get("goal_publisher_robust")(fr, {})).status == "error"


def test_robust_needs_a_malformed_line() -> None:
    fr = _frames(GOOD, lines=[LINES[0], LINES[2]])
    assert check(get("goal_publisher_robust")(fr, {})).status == "error"


def test_exit_caused_by_the_grader_is_not_a_crash() -> None:
    fr = _frames(GOOD)
    ev = fr["/grader/events"]
    extra = events_frame([(T0 + 6.5, "process_exit", {"process": "goal_publisher", "returncode": -2,
                                                      "stopped_by_grader": True})])
    fr["/grader/events"] = pd.concat([ev, extra]).sort_index()
    assert check(get("goal_publisher_robust")(fr, {})).status == "pass"


def test_undelivered_line_means_the_process_was_gone() -> None:
    lines = [LINES[0], LINES[1]]
    fr = _frames(GOOD[:1], lines=lines)
    ev = fr["/grader/events"]
    extra = events_frame([(T0 + 6.0, "stdin_line", {"process": "goal_publisher", "line": "8.0,3.0",
                                                    "delivered": False})])
    fr["/grader/events"] = pd.concat([ev, extra]).sort_index()
    f = check(get("goal_publisher_robust")(fr, {}))
    assert f.status == "fail" and "had exited" in f.feedback
