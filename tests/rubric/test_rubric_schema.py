"""Schema errors name file, line and field; every problem is reported in one run."""

from __future__ import annotations

from pathlib import Path

import pytest

from pydantic import ValidationError

from grader.errors import GraderError
from grader.rubric import RubricError, load_rubric

F = "rubrics/x.yaml"

BASE = """
lab: demo-lab
title: Demo lab
scenarios:
  ex1_publisher:
    steps:
      - {id: run, wait: 1}
items:
  - id: a
    title: Item A
    section: {exercise: 1}
    points: 3
    scenario: ex1_publisher
    analyzer: topic_type
"""


def test_base_rubric_is_valid(write_rubric):
    rubric = load_rubric(write_rubric(BASE))
    assert rubric.lab == "demo-lab"
    assert rubric.item("a").points == 3.0
    assert rubric.item("a").scenario == ("ex1_publisher",)
    assert rubric.item("a").partial.mode == "linear"          # default
    assert rubric.scenarios["ex1_publisher"].steps[0].limit_s == 1.0
    assert rubric.source.is_absolute()


def test_malformed_yaml_names_file_and_line(problems):
    text = BASE + "  - id: [unclosed\n"
    out = problems(text)
    assert len(out) == 1
    assert out[0].startswith(f"{F}:")
    assert "YAML syntax error" in out[0]
    line = int(out[0].split(":")[1])
    assert line >= len(BASE.strip().splitlines())   # at or after the broken line, not line 1


def test_wrong_type_message_is_exact(problems, line_of):
    text = BASE.replace("points: 3", "points: ten")
    assert problems(text) == [
        f"{F}:{line_of(text, 'points: ten')}: items[0].points: expected a number >= 0, got 'ten'"]


def test_negative_and_boolean_points_are_rejected(problems):
    assert "expected a number >= 0, got -1" in problems(BASE.replace("points: 3", "points: -1"))[0]
    assert "got True" in problems(BASE.replace("points: 3", "points: yes"))[0]


def test_unknown_key_suggests_the_right_one(problems, line_of):
    text = BASE.replace("points: 3", "pionts: 3")
    out = problems(text)
    assert f"{F}:{line_of(text, 'pionts')}: items[0].pionts: unknown key 'pionts' " \
           f"(did you mean 'points'?)" in out
    # and the now-missing required key is reported too, at the item's line
    assert any("items[0].points" in p and "required key is missing" in p for p in out)


def test_unknown_top_level_key_without_close_match_lists_allowed(problems):
    out = problems(BASE + "zzz: 1\n")
    assert len(out) == 1 and "unknown key 'zzz' (allowed: schema, lab, title" in out[0]


def test_missing_scenario_reference(problems, line_of):
    text = BASE.replace("scenario: ex1_publisher", "scenario: ex1_publsher")
    assert problems(text) == [
        f"{F}:{line_of(text, 'scenario: ex1_publsher')}: items[0].scenario: unknown scenario "
        f"'ex1_publsher' (did you mean 'ex1_publisher'?)"]


def test_bad_section_total(problems, line_of):
    text = BASE + """
sections:
  - {section: {exercise: 1}, title: Random numbers, points: 20}
"""
    assert problems(text) == [
        f"{F}:{line_of(text, 'section: {exercise: 1}, title')}: sections[0].points: section "
        f"'exercise 1' declares 20 points but its items add up to 3"]


def test_item_section_missing_from_table(problems):
    text = BASE.replace("{exercise: 1}", "{exercise: 2}") + """
sections:
  - {section: {exercise: 1}, points: 0}
"""
    out = problems(text)
    assert any("items[0].section: section 'exercise 2' is not in the sections table "
               "(did you mean 'exercise 1'?)" in p for p in out)


def test_total_mismatch(problems, line_of):
    text = "total: 100\n" + BASE.lstrip("\n")
    assert problems(text) == [f"{F}:1: total: total is 100 but the items add up to 3"]


def test_every_problem_is_reported_sorted_by_line(problems):
    text = (BASE.replace("points: 3", "points: ten")
                .replace("analyzer: topic_type", "analyzer: Topic Type")
                .replace("title: Demo lab", "title: 42")
                .replace("wait: 1", "wait: 0"))
    out = problems(text)
    assert len(out) == 4
    lines = [int(p.split(":")[1]) for p in out]
    assert lines == sorted(lines)
    assert any("title: expected text (quote it), got 42" in p for p in out)
    assert any("steps[0].wait: expected a number > 0, got 0" in p for p in out)
    assert any("items[0].analyzer" in p for p in out)


def test_duplicate_yaml_key(problems, line_of):
    text = BASE + """
  - id: a
    title: Again
    section: report
    points: 1
    kind: manual
    kind: manual
"""
    assert problems(text) == [f"{F}:{line_of(text, 'kind: manual', 1)}: items[1].kind: duplicate "
                              f"key (first given on line {line_of(text, 'kind: manual')})"]


def test_duplicate_item_id_alone(problems, line_of):
    text = BASE + """
  - {id: a, title: Again, section: report, points: 1, kind: manual}
"""
    assert problems(text) == [
        f"{F}:{line_of(text, 'id: a, title: Again')}: items[1].id: duplicate item id 'a' "
        f"(first at items[0])"]


@pytest.mark.parametrize("extra, message", [
    ("    kind: advisory\n", "items[0].points: advisory items carry no points"),
    ("    kind: manual\n", "items[0].scenario: manual items are graded by a person"),
    ("    partial: {steps: [[0.5, 0.5], [0.9, 1.0]]}\n", "thresholds must decrease: 0.9 follows 0.5"),
    ("    partial: {steps: [[0.9, 0.5], [0.5, 1.0]]}\n", "credit must not grow"),
    ("    partial: half\n", "items[0].partial: expected one of linear, none, steps, got 'half'"),
    ("    feedback: {pass: 'rate {value:.2f', fail: x}\n", "items[0].feedback.pass: invalid template"),
    ("    feedback: {pass: 'positional {}'}\n", "placeholders need a name"),
    ("    public: maybe\n", "items[0].public: expected true or false, got 'maybe'"),
    ("    kind: bonus\n", "items[0].kind: expected one of auto, manual, advisory, integrity, got 'bonus'"),
])
def test_item_rules(problems, extra, message):
    out = problems(BASE + extra)
    assert any(message in p for p in out), out


def test_feedback_typo_has_no_wrong_suggestion(problems):
    out = problems(BASE + "    feedback: {fial: hi}\n")
    assert any("unknown key 'fial' (did you mean 'fail'?)" in p for p in out)


def test_auto_item_with_zero_points_points_to_advisory(problems):
    out = problems(BASE.replace("points: 3", "points: 0"))
    assert out[0].endswith("items[0].points: auto items need points > 0; use kind: advisory "
                           "for a 0-point check")


def test_empty_file_and_non_mapping(problems):
    assert problems("") == [f"{F}:1: the rubric is empty"]
    assert problems("- 1\n- 2\n") == [f"{F}:1: expected a mapping, got a list"]


def test_unknown_analyzer_checked_when_registry_given(problems, write_rubric):
    out = problems(BASE.replace("topic_type", "topic_typ"), analyzers={"topic_type", "publish_rate"})
    assert out[0].endswith("items[0].analyzer: unknown analyzer 'topic_typ' (did you mean 'topic_type'?)")
    # without a registry, any well-formed name is accepted
    load_rubric(write_rubric(BASE.replace("topic_type", "topic_typ"), name="y.yaml"), analyzers=None)


def test_analyzer_parameters_checked_against_the_registry(problems, line_of, write_rubric):
    text = BASE + "    params: {topc: /random_numbers, type: std_msgs/msg/String}\n"
    assert problems(text) == [
        f"{F}:{line_of(text, 'topc')}: items[0].params.topc: analyzer 'topic_type' takes no "
        f"parameter 'topc' (did you mean 'topic'?)"]
    assert problems(text, analyzers={"topic_type": ["topic"]})[0].endswith("(did you mean 'topic'?)")
    out = problems(text.replace("topc", "topic"), analyzers={"topic_type": ["topic"]})
    assert out[0].endswith("takes no parameter 'type' (accepted: topic)")
    assert load_rubric(write_rubric(text, name="z.yaml"), analyzers=None).item("a").params["topc"]


def test_registry_lists_analyzers_with_their_parameters():
    from grader.rubric.load import registered_analyzers
    registry = registered_analyzers()
    assert registry is not None and "expected_hz" in registry["publish_rate"]


def test_rubric_error_is_a_grader_error(write_rubric):
    with pytest.raises(GraderError):
        load_rubric(write_rubric("lab: [\n"))
    with pytest.raises(GraderError, match="not found"):
        load_rubric(Path("rubrics/nope.yaml"))


# -- scenarios --------------------------------------------------------------------------------

SCEN = """
lab: demo-lab
title: Demo
scenarios:
  s1:
    processes:
      - {name: server, package: pkg_a, executable: server_node}
      - {name: client, package: pkg_a, executable: client_node, autostart: false}
    steps:
      - id: first
        action: {name: /turtle_goal, type: pkg_a/action/Go, goal: {x: 1}}
        until: action_done
        timeout: 10
      - {id: later, start: client, until: {condition: output, process: client, pattern: "ok"}, timeout: 5}
    limits: {wall_s: 20}
items:
  - {id: a, title: A, section: {exercise: 1}, points: 1, scenario: s1, analyzer: topic_type}
"""


def test_scenario_base_is_valid(write_rubric):
    scenario = load_rubric(write_rubric(SCEN)).scenarios["s1"]
    assert scenario.budget_s == 15
    assert scenario.steps[0].action.goal == {"x": 1}
    assert (scenario.steps[1].until.process, scenario.steps[1].until.pattern) == ("client", "ok")


@pytest.mark.parametrize("old, new, message", [
    ("until: action_done", "until: service_done",
     "steps[0].until: 'service_done' waits for this step's service, but the step has no 'service'"),
    ("start: client", "start: clinet", "steps[1].start: no process 'clinet' in this scenario (did you mean 'client'?)"),
    ("wall_s: 20", "wall_s: 12", "limits.wall_s: the steps may take up to 15 s"),
    ("type: pkg_a/action/Go", "type: pkg_a/msg/Go", "steps[0].action.type: expected an action type"),
    ("pattern: \"ok\"", "pattern: \"(\"", "until.pattern: invalid regular expression"),
    ("until: {condition: output, process: client, pattern: \"ok\"}",
     "until: {condition: output, process: client}", "until.pattern: required key is missing"),
    ("until: {condition: output, process: client, pattern: \"ok\"}",
     "until: {condition: goal_reached, tolerance: 0.1}", "until.goal: goal_reached needs a goal"),
    ("until: {condition: output, process: client, pattern: \"ok\"}",
     "until: {condition: messages, topic: /a, tolerance: 1}",
     "until.tolerance: unknown key 'tolerance' (allowed: condition, topic, count)"),
    ("until: action_done\n        timeout: 10", "until: action_done",
     "steps[0].timeout: required key is missing (every step needs a time limit"),
    ("{name: server, package: pkg_a, executable: server_node}", "{name: server, executable: server_node}",
     "processes[0]: executable needs a package"),
    ("{name: server, package: pkg_a, executable: server_node}", "{name: sim, package: pkg_a, executable: x}",
     "processes[0].name: 'sim' is reserved"),
    ("{name: server, package: pkg_a, executable: server_node}", "{name: server, package: pkg_a}",
     "processes[0]: say how to start the process"),
    ("{name: server, package: pkg_a, executable: server_node}",
     "{name: server, package: pkg_a, executable: s, parameters: {k: {a: 1}}}",
     "processes[0].parameters.k: expected true or false, an integer, a number, text or a list"),
    ("autostart: false}", "autostart: false, stdin: [{line: 2.0, delay: 1}]}",
     "stdin[0].line: expected text (quote it), got 2.0"),
    ("start: client, ", ""
     , "processes[1]: process 'client' has autostart: false but no step starts it"),
    ("- id: first\n", "- id: first\n        place: {x: 12.0, y: 1.0, theta: 0.0}\n",
     "steps[0].place.x: expected a number >= 0 and <= 11.088889, got 12.0"),
    ("- id: first\n", "- id: first\n        place: {x: 1.0, y: 1.0}\n", "steps[0].place.theta: required key is missing"),
    ("      - {id: later,", "      - {id: pause, wait: 1, place: {x: 1, y: 1, theta: 0}}\n      - {id: later,",
     "steps[1].place: 'wait: N' is a pause on its own"),
])
def test_scenario_rules(problems, old, new, message):
    text = SCEN.replace(old, new)
    assert text != SCEN
    out = problems(text)
    assert any(message in p for p in out), out
    assert all(p.startswith(f"{F}:") and "scenarios.s1" in p for p in out), out


def test_scenario_error_line_is_the_offending_value(problems, line_of):
    text = SCEN.replace("timeout: 10", "timeout: soon")
    assert problems(text) == [f"{F}:{line_of(text, 'timeout: soon')}: scenarios.s1.steps[0].timeout: "
                              f"expected a number > 0, got 'soon'"]


def test_yaml_anchors_and_merge_keys_work(write_rubric):
    text = SCEN.replace("action: {name: /turtle_goal, type: pkg_a/action/Go, goal: {x: 1}}",
                        "action: &goal {name: /turtle_goal, type: pkg_a/action/Go, goal: {x: 1}}")
    text = text.replace("      - {id: later,", "      - {id: again, action: {<<: *goal, goal: {x: 2}}, "
                        "until: action_done, timeout: 3}\n      - {id: later,")
    scenario = load_rubric(write_rubric(text.replace("wall_s: 20", "wall_s: 30"))).scenarios["s1"]
    assert scenario.steps[1].action.name == "/turtle_goal"
    assert scenario.steps[1].action.goal == {"x": 2}


def test_check_files_for_support_and_bags(write_rubric, tmp_path):
    text = BASE + "support:\n  my_interfaces: ../fixtures/my_interfaces\n"
    path = write_rubric(text)
    with pytest.raises(RubricError) as info:
        load_rubric(path)
    assert "support.my_interfaces: support package 'my_interfaces': no package.xml" in str(info.value)
    pkg = tmp_path / "fixtures" / "my_interfaces"
    pkg.mkdir(parents=True)
    (pkg / "package.xml").write_text("<package/>")
    rubric = load_rubric(path)
    assert rubric.support_paths() == {"my_interfaces": pkg.resolve()}
    assert load_rubric(path, check_files=False).support["my_interfaces"] == pkg.resolve()


def test_equivalent_mutants_are_validated_with_lines(problems, line_of, write_rubric):
    good = BASE + ("equivalent_mutants:\n"
                   "  - {mutant: swap_args-1a2b3c4d, reason: 'hypot(dy, dx) is hypot(dx, dy)'}\n")
    rubric = load_rubric(write_rubric(good))
    assert rubric.equivalent_mutants[0].mutant == "swap_args-1a2b3c4d"
    shapes = BASE + ("equivalent_mutants:\n"
                     "  - {mutant: flip_sign-xyz, reason: x}\n"
                     "  - {mutant: drop_call-00000000, reason: '  '}\n"
                     "  - {mutant: drop_call-00000001}\n")
    out = problems(shapes)
    assert out[0].startswith(f"{F}:{line_of(shapes, 'flip_sign-xyz')}: equivalent_mutants[0].mutant: expected "
                             "a mutant id like 'flip_sign-1a2b3c4d'")
    assert out[1].startswith(f"{F}:{line_of(shapes, 'drop_call-00000000')}: equivalent_mutants[1].reason: ")
    assert out[2] == f"{F}:{line_of(shapes, 'drop_call-00000001')}: equivalent_mutants[2].reason: required key is missing"
    assert len(out) == 3
    cross = BASE + ("equivalent_mutants:\n"
                    "  - {mutant: swap_args-1a2b3c4d, reason: same}\n"
                    "  - {mutant: swap_args-1a2b3c4d, reason: same again}\n"
                    "  - {mutant: flip-00000000, reason: x}\n")
    assert problems(cross) == [
        f"{F}:{line_of(cross, 'same again')}: equivalent_mutants[1].mutant: mutant 'swap_args-1a2b3c4d' is listed "
        "twice (first at equivalent_mutants[0])",
        f"{F}:{line_of(cross, 'flip-0')}: equivalent_mutants[2].mutant: unknown mutation operator 'flip' in "
        "'flip-00000000' (known: flip_sign, scale_constant, swap_args, rename_topic, drop_call, remove_angle_wrap, "
        "change_timer_period); copy the id from grader rubric audit's report"]


GOALS = BASE.replace("ex1_publisher", "ex2_controller").replace("analyzer: topic_type", "analyzer: goals_reached")


@pytest.mark.parametrize("value, why", [
    ("-1", "Input should be greater than 0 (got -1); allowed: number, > 0"),
    ('"x"', "Input should be a valid number, unable to parse string as a number (got 'x'); allowed: number, > 0"),
])
def test_a_parameter_value_its_analyzer_refuses_is_refused_at_its_line(problems, line_of, value, why):
    """The analyzer's parameter model decides a value at load time, on the line it is written,
    with what is allowed (issue 38), instead of failing or misgrading inside the analysis."""
    text = GOALS + f"    params:\n      tol_final: 0.2\n      tol_reached: {value}\n"
    assert problems(text) == [f"{F}:{line_of(text, 'tol_reached')}: items[0].params.tol_reached: "
                              f"analyzer 'goals_reached': {why}"]
    load_rubric(Path("rubrics/x.yaml"), analyzers=None)       # no registry: values unchecked


def test_the_values_an_analyzer_runs_with_are_the_models(write_rubric):
    """What the rubric says reaches the analyzer as its model's typed attributes, and the
    finding records the values as written, defaults merged (every threshold that decided it)."""
    from grader import analyze

    model = analyze.params_model("goals_reached")
    assert model is not None
    given = model.model_validate({"tol_reached": 1, "steps": ["go"]})
    assert given.tol_reached == 1.0 and isinstance(given.tol_reached, float) and given.steps == ("go",)
    with pytest.raises(ValidationError):
        given.tol_reached = 2.0                                    # frozen: no analysis changes it
    assert analyze.effective_params("goals_reached", {"tol_reached": 1})["tol_reached"] == 1
    assert analyze.effective_params("goals_reached", {})["tol_final"] == model.model_fields["tol_final"].default
