"""A starved recording cannot fail a timing item (issue 36): the grading machine's own starvation
makes such an item an `error` that says why, while a rate starvation cannot explain (the machine
kept pace) still fails, a student's own busy loop is still charged, and items that do not depend
on timing are graded as usual. Real analyzers and the Lab 3 rubric on synthetic recordings."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "analyze"))

from analyze_synth import T0, frame, with_meta  # noqa: E402
from grader import analyze  # noqa: E402
from grader.contracts.scenario_record import ScenarioRecord  # noqa: E402
from grader.grading.analysis import analyze_item  # noqa: E402
from grader.report.index import render_index  # noqa: E402
from grader.rubric import load_rubric  # noqa: E402
from grader.rubric.score import score  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
RUBRIC = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")

#: the simulator waited 1.04 s per s for a CPU while the controller used a few hundredths of one
MACHINE_STARVED = {"cpu_wait": {"turtlesim": {"wait_share": 1.04, "cpu_s": 3.0, "alive_s": 40.0},
                                "controller": {"cpu_s": 1.2, "alive_s": 40.0}}}
#: the same starved simulator, the controller spinning a whole core: its own doing
SELF_STARVED = {"cpu_wait": {"turtlesim": {"wait_share": 1.04}, "controller": {"cpu_s": 39.0, "alive_s": 40.0}}}
QUIET = {"cpu_wait": {"turtlesim": {"wait_share": 0.08}, "controller": {"cpu_s": 1.2, "alive_s": 40.0}}}


def cmd_vel_at(hz: float, record: dict, seconds: float = 20.0) -> dict:
    t = T0 + np.arange(0.0, seconds, 1.0 / hz)
    frames = with_meta({"/turtle1/cmd_vel": frame(t, linear_x=np.full(len(t), 0.5), angular_z=np.zeros(len(t)))},
                       publishers={"/turtle1/cmd_vel": ["/controller"]})
    frames["__meta__"].attrs["scenario"] = ScenarioRecord.parse({"scenario": "ex2_controller", **record}, "test record")
    return frames


def test_a_starved_rate_is_not_measured_and_says_why() -> None:
    item = RUBRIC.item("ex2.control_rate")
    finding = analyze_item(item, cmd_vel_at(23.1, MACHINE_STARVED))   # the correct 30 Hz timer, starved
    assert finding.status == "error" and finding.fraction == 0.0
    assert finding.feedback.startswith("Not measured: the grading machine was too busy to measure the publish rate")
    assert "the simulator waited 1.04 s per second for a CPU" in finding.feedback
    assert "Check the timer period" not in finding.feedback.split("What this recording showed:")[0]
    assert finding.evidence["starved_status"] == "fail" and finding.evidence["rate_hz"] < 25


def test_a_rate_the_machine_cannot_explain_still_fails() -> None:
    item = RUBRIC.item("ex2.control_rate")
    # 10 Hz while the simulator kept pace: the code's own rate
    assert analyze_item(item, cmd_vel_at(10.0, QUIET)).status == "fail"
    # a controller that spins a core starved the simulator itself: charged as measured
    assert analyze_item(item, cmd_vel_at(10.0, SELF_STARVED)).status == "fail"
    # a right rate is a pass, starved or not
    assert analyze_item(item, cmd_vel_at(33.3, MACHINE_STARVED)).status == "pass"


def test_at_4x_a_wait_under_the_1x_limit_still_spares_a_timing_item() -> None:
    """At 4x a stall is four times as long in simulated time: the first_nodes greeting_timer
    fixture (correct) failed turtlesim's command timeout at 4x while its simulator waited 0.43 s
    per second, under the 1x limit (0.5)."""
    item = RUBRIC.item("ex2.control_rate")
    loaded = {"cpu_wait": {"turtlesim": {"wait_share": 0.43}, "controller": {"cpu_s": 1.2, "alive_s": 40.0}}}
    assert analyze_item(item, cmd_vel_at(23.1, loaded)).status == "fail"           # a 1x recording
    at_4x = analyze_item(item, cmd_vel_at(23.1, {**loaded, "time_scale": {"used": 4.0, "requested": 4.0}}))
    assert at_4x.status == "error", at_4x.feedback
    assert "(at most 0.125 at 4x: 0.5 at 1x)" in at_4x.feedback
    # quiet at 4x: the 10 Hz timer is the code's own
    assert analyze_item(item, cmd_vel_at(10.0, {**QUIET, "time_scale": {"used": 4.0}})).status == "fail"


def test_only_items_that_depend_on_timing_are_spared() -> None:
    timing = {i.id for i in RUBRIC.items if analyze.timing(i.analyzer, i.timing)}
    assert {"ex1.pub_rate", "ex2.control_rate", "ex3.loop_paced", "ex3.timeout"} <= timing
    assert not {"ex1.pub_topic", "ex2.turn_direction", "ex3.rejects_out_of_bounds"} & timing
    # a rubric says so for an item its analyzer does not declare, or the other way round
    assert analyze.timing("topic_type", True) == "its timing"
    assert analyze.timing("publish_rate", False) is None and analyze.timing("publish_rate") == "the publish rate"


def test_the_result_and_the_class_view_list_what_was_not_measured() -> None:
    item = RUBRIC.item("ex2.control_rate")
    finding = analyze_item(item, cmd_vel_at(23.1, MACHINE_STARVED))
    result = score(RUBRIC, {item.id: finding})
    assert list(result.starved) == ["ex2.control_rate"]
    assert "simulator waited 1.04 s" in result.starved["ex2.control_rate"]
    page = render_index({"alice": result})
    assert "Not measured: the machine was too busy" in page and 'data-item="ex2.control_rate"' in page
    measured = score(RUBRIC, {item.id: analyze_item(item, cmd_vel_at(10.0, QUIET))})
    assert not measured.starved and "Not measured" not in render_index({"bob": measured})


def test_a_result_starved_at_4x_asks_for_a_recording_in_real_time() -> None:
    """``Result.starved_faster``: the items a self-check records again at 1x (its 1x recordings were
    already made again while starved: a result starved at 1x only says so)."""
    item = RUBRIC.item("ex2.control_rate")
    loaded = {"cpu_wait": {"turtlesim": {"wait_share": 0.43}, "controller": {"cpu_s": 1.2, "alive_s": 40.0}}}
    at_4x = score(RUBRIC, {item.id: analyze_item(item, cmd_vel_at(23.1, {**loaded, "time_scale": {"used": 4.0}}))})
    assert list(at_4x.starved_faster) == list(at_4x.starved) == ["ex2.control_rate"]
    at_1x = score(RUBRIC, {item.id: analyze_item(item, cmd_vel_at(23.1, MACHINE_STARVED))})
    assert list(at_1x.starved) == ["ex2.control_rate"] and not at_1x.starved_faster
