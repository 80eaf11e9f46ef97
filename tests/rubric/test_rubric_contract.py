"""The rubric's contract: names declared once, referred to as $role, errors with their line;
which items depend on which names; a mismatch blocks the failing items that depend on it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grader.analyze import Finding
from grader.report.result import result_from_dict, result_to_dict
from grader.rubric import load_rubric, score
from grader.contracts.contract import Mismatch

REPO = Path(__file__).resolve().parents[2]
F = "rubrics/x.yaml"

BASE = """
lab: demo-lab
title: Demo lab
contract:
  packages:
    pkg: {name: my_first_package, why: the lab text}
  executables:
    subscriber: {package: $pkg, name: number_subscriber}
  nodes:
    greeter_node: /my_first_node
  topics:
    news: {name: /robot_news, type: std_msgs/msg/String}
scenarios:
  news:
    sim: false
    processes:
      - {name: subscriber, executable: $subscriber}
    steps:
      - {id: startup, until: {condition: advertised, topic: $news}, timeout: 5}
      - id: say
        publish: {topic: $news, msg: {data: hi}}
        timeout: 1
  hello:
    sim: false
    processes:
      - {name: node, package: $pkg, module: my_first_package.hello:main}
    steps:
      - {id: run, wait: 1}
items:
  - id: heard
    title: ${subscriber} logs what it hears on ${news}
    section: {part: 1}
    points: 3
    scenario: news
    analyzer: heard_messages
    params: {topic: $news}
  - id: greeting
    title: the greeting
    section: {part: 1}
    points: 2
    scenario: hello
    analyzer: logged
    params: {logger: $greeter_node, pattern: hello}
  - id: name
    title: the node's name
    section: {part: 1}
    points: 1
    scenario: hello
    analyzer: nodes_running
    params: {nodes: [$greeter_node]}
"""


def test_references_become_the_contract_names(write_rubric) -> None:
    r = load_rubric(write_rubric(BASE))
    proc = r.scenarios["news"].processes[0]
    assert (proc.package, proc.executable) == ("my_first_package", "number_subscriber")   # package derived
    assert r.scenarios["news"].steps[0].until.topic == "/robot_news"
    assert r.scenarios["news"].steps[1].publish.type == "std_msgs/msg/String"              # type derived
    assert r.item("heard").title == "number_subscriber logs what it hears on /robot_news"
    assert r.item("greeting").params == {"logger": "/my_first_node", "pattern": "hello"}
    assert r.contract.nodes["greeter_node"].name == "/my_first_node"                       # the short form
    assert [line[:2] for line in r.contract.lines()] == [
        ("package", "my_first_package"), ("executable", "number_subscriber"), ("node", "/my_first_node"),
        ("topic", "/robot_news")]


def test_the_four_rubrics_declare_what_their_lab_text_fixes() -> None:
    names = {p.stem: {n for _, n, _, _ in load_rubric(p).contract.lines()}
             for p in sorted((REPO / "rubrics").glob("*.yaml"))}
    assert names["first_nodes"] == {"my_first_package", "my_first_node", "number_publisher", "number_subscriber",
                                    "turtle_controller", "/my_first_node", "/robot_news"}
    assert names["goal_setter"] == {"turtle_goal", "/turtlesim", "/goal_setter", "/turtle_controller", "/goal",
                                    "/set_goal"}
    assert {"/random_numbers", "/turtle1/goal", "/turtle_goal", "random_numbers", "simple_subscriber"} <= \
        names["enee467_lab3"]
    assert names["wall_pen"] == {"my_robot_controller", "turtle_controller"}


def test_lab3_resolves_to_the_same_scenarios_as_literal_names() -> None:
    """The contract changes how names are written, not what runs (recordings stay reusable)."""
    r = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
    ex3 = r.scenarios["ex3_action"]
    assert ex3.processes[0].package == "turtle_controller_server"
    assert ex3.steps[3].action.type == "turtle_control_interfaces/action/SendGoal"
    assert r.scenarios["ex2_controller"].goal_topic == "/turtle1/goal"


def test_unknown_role_wrong_kind_and_duplicate_role_have_their_lines(problems, line_of) -> None:
    text = (BASE.replace("params: {topic: $news}", "params: {topic: $nwes}")
            .replace("- {name: subscriber, executable: $subscriber}", "- {name: subscriber, executable: $news}")
            .replace("    greeter_node: /my_first_node", "    greeter_node: /my_first_node\n    news: /x"))
    out = problems(text)
    assert f"{F}:{line_of(text, 'topic: $nwes')}: items[0].params.topic: $nwes is not in the contract " \
           "(did you mean 'news'?)" in out[0] + "".join(out)
    # `news` is declared twice: as a node first, so the topic is refused, and `$news` is that node
    assert any(f"{F}:{line_of(text, 'executable: $news')}: scenarios.news.processes[0].executable: $news is a "
               "node of the contract; this key needs an executable" in p for p in out)
    assert any(f"{F}:{line_of(text, 'news: {name: /robot_news')}: contract.topics.news: role 'news' is already a node" in p for p in out)


def test_a_process_package_that_contradicts_its_executable(problems) -> None:
    text = BASE.replace("- {name: subscriber, executable: $subscriber}",
                        "- {name: subscriber, package: other_pkg, executable: $subscriber}")
    assert any("$subscriber is executable 'number_subscriber' of package 'my_first_package'; this process "
               "says package 'other_pkg'" in p for p in problems(text))


def test_dependencies_are_derived(write_rubric) -> None:
    r = load_rubric(write_rubric(BASE))
    assert r.item_roles(r.item("heard"), "news") == {"pkg", "subscriber", "news"}
    assert r.item_roles(r.item("greeting"), "hello") == {"pkg", "greeter_node"}
    assert r.scenario_roles("hello") == {"pkg", "greeter_node"}


def _finding(status: str, fraction: float = 0.0, feedback: str = "own words") -> Finding:
    return Finding(value=None, fraction=fraction, status=status, feedback=feedback)


def test_a_mismatch_blocks_the_failing_items_that_depend_on_it(write_rubric) -> None:
    r = load_rubric(write_rubric(BASE))
    node = Mismatch(role="greeter_node", kind="nodes", expected="/my_first_node", found=("/hello",),
                    feedback="Your node is called /hello; this lab asks for /my_first_node.", scenarios=("hello",))
    news = Mismatch(role="news", kind="topics", expected="/robot_news", found=("/news",),
                    feedback="The topic ...", scenarios=("hello",))      # seen in another scenario than `heard`'s
    result = score(r, {"greeting": _finding("fail", feedback="was printed"), "name": _finding("fail"),
                       "heard": _finding("fail")}, contract=[node, news])
    greeting, name, heard = (result.item(i) for i in ("greeting", "name", "heard"))
    assert greeting.status == name.status == "fail" and greeting.points == 0
    assert greeting.feedback == node.feedback and name.feedback == node.feedback
    assert greeting.evidence["blocked_by"] == ["greeter_node"] and greeting.evidence["own_feedback"] == "was printed"
    assert heard.feedback == "own words"                  # the topic mismatch was in another scenario
    assert [(m.role, m.blocks) for m in result.contract] == [("greeter_node", ("greeting", "name")), ("news", ())]
    # items that pass or partly pass anyway keep their result
    kept = score(r, {"greeting": _finding("pass", 1.0), "name": _finding("partial", 0.5)}, contract=[node])
    assert kept.item("greeting").status == "pass" and kept.item("name").points == 0.5
    assert kept.contract[0].blocks == ()


def test_the_contract_round_trips_through_result_json(write_rubric) -> None:
    r = load_rubric(write_rubric(BASE))
    m = Mismatch(role="greeter_node", kind="nodes", expected="/my_first_node", found=("/hello",),
                 feedback="Your node is called /hello; this lab asks for /my_first_node.", scenarios=("hello",))
    result = score(r, {"name": _finding("fail")}, contract=[m])
    doc = json.loads(json.dumps(result_to_dict(result, "s")))
    # `greeting` had no finding (its analysis did not run): it depends on the name too
    assert doc["contract"][0]["blocks"] == ["greeting", "name"] and doc["contract"][0]["found"] == ["/hello"]
    assert result_from_dict(doc).contract == result.contract


def test_the_contract_goes_to_the_report_and_the_check_table(write_rubric) -> None:
    from pathlib import Path

    from grader.grading.graded import GradedSubmission
    from grader.grading.outputs import check_table, contract_lines
    from grader.report.html import render_html

    r = load_rubric(write_rubric(BASE))
    m = Mismatch(role="greeter_node", kind="nodes", expected="/my_first_node", found=("/hello",),
                 feedback="Your node is called /hello; this lab asks for /my_first_node.", scenarios=("hello",))
    result = score(r, {"name": _finding("fail")}, contract=[m])
    page = render_html(result, "s")
    assert 'id="contract"' in page and "Your node is called /hello" in page and 'href="#item-name"' in page
    graded = GradedSubmission(id="s", out=Path("unused"), result=result.for_student(), build_ok=True)
    ok, table = check_table(graded, r)
    out = "\n".join(contract_lines(r) + table)
    assert not ok
    assert "executable  number_subscriber  ros2 run my_first_package number_subscriber" in out
    assert "NAME Your node is called /hello; this lab asks for /my_first_node. Blocks: greeting, name." in \
        " ".join(out.split())


@pytest.mark.parametrize("rubric", sorted((REPO / "rubrics").glob("*.yaml")), ids=lambda p: p.name)
def test_no_literal_contract_name_is_left_in_items_and_scenarios(rubric: Path) -> None:
    """A contract name is written once: items and scenarios use $role (the loader resolves them)."""
    import yaml

    data = yaml.safe_load(rubric.read_text())
    names = {n for _, n, _, _ in load_rubric(rubric).contract.lines()}
    names |= {n.lstrip("/") for n in names}
    left = []

    def walk(value, path):
        if isinstance(value, dict):
            for k, v in value.items():
                walk(v, path + (k,))
        elif isinstance(value, list):
            for i, v in enumerate(value):
                walk(v, path + (i,))
        elif isinstance(value, str) and value in names:
            left.append((path, value))

    walk({k: v for k, v in data.items() if k in ("scenarios", "items")}, ())
    assert not left, left
