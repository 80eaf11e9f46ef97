"""text_messages with a judged window (``after_step``, ``max_messages``): the same share of a run
is judged whichever of a publisher's first messages reached the bag (issue 22)."""

from __future__ import annotations

from analyze_synth import T0, check, events_frame, frame, with_meta
from grader.analyze import get

PARAMS = {"topic": "/robot_news", "pattern": r"^Hello robot (\d+)$", "min_count": 3, "counting": True,
          "after_step": "listen", "max_messages": 5}


def _frames(texts: list[str], recorded_from: int = 0, step_at: float = 2.1, with_pub_t: bool = True) -> dict:
    """A 2 Hz publisher's messages (the first at T0 + 0.5 s); the recorder has the ones from
    ``recorded_from`` on; the ``listen`` step begins at T0 + ``step_at``."""
    sent = [T0 + 0.5 * (k + 1) for k in range(len(texts))]
    keep = slice(recorded_from, None)
    cols = {"data": texts[keep]}
    if with_pub_t:
        cols["pub_t"] = sent[keep]
    news = frame([t + 0.003 for t in sent[keep]], **cols)
    ev = events_frame([(T0 + 0.01, "scenario_start", {}), (T0 + step_at - 1.5, "step_start", {"step": "settle"}),
                       (T0 + step_at, "step_start", {"step": "listen"})])
    return with_meta({"/robot_news": news, "/grader/events": ev}, types={"/robot_news": "std_msgs/msg/String",
                                                                         "/grader/events": "std_msgs/msg/String"})


def test_a_counter_counting_down_gets_the_same_grade_whichever_first_messages_were_recorded() -> None:
    down = [f"Hello robot {-k}" for k in range(12)]          # "Hello robot 0" is the only match
    outcomes = set()
    for recorded_from in (0, 1, 2):
        f = check(get("text_messages")(_frames(down, recorded_from), PARAMS))
        outcomes.add((f.status, f.fraction, f.evidence["messages"]))
    assert outcomes == {("fail", 0.0, 5)}
    # judged over the whole bag (the old rubric), the first message decided it
    whole = {k: v for k, v in PARAMS.items() if k not in ("after_step", "max_messages")}
    got = {check(get("text_messages")(_frames(down, r), whole)).fraction for r in (0, 2)}
    assert len(got) == 2


def test_a_correct_publisher_passes_on_the_messages_after_the_step() -> None:
    up = [f"Hello robot {k}" for k in range(12)]
    for recorded_from in (0, 3):
        f = check(get("text_messages")(_frames(up, recorded_from), PARAMS))
        assert f.status == "pass" and f.evidence["counter"] == [4, 5, 6, 7, 8], f.evidence
        assert "after step 'listen'" in f.evidence["judged"]


def test_without_send_times_the_receive_times_decide() -> None:
    up = [f"Hello robot {k}" for k in range(12)]
    f = check(get("text_messages")(_frames(up, with_pub_t=False), PARAMS))
    assert f.status == "pass" and f.evidence["counter"][0] == 4


def test_too_few_messages_after_the_step_say_so() -> None:
    f = check(get("text_messages")(_frames([f"Hello robot {k}" for k in range(5)]), PARAMS))
    assert f.status == "fail" and "Only 1 message(s) on /robot_news while the grader listened" in f.feedback


def test_a_step_the_bag_does_not_have_is_a_rubric_error() -> None:
    f = get("text_messages")(_frames(["Hello robot 0"]), {**PARAMS, "after_step": "nope"})
    assert f.status == "error" and "no step 'nope'" in f.feedback
