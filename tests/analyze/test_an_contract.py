"""Contract names looked for in a recording (synthetic graph snapshots and build facts), and the
log analyzers' diagnoses: each cause gets its own message, a look-alike with another cause its own.

Every case pairs a mismatch (the student's own name for the thing is found by behaviour) with a
look-alike that is *not* one (the thing is simply absent: crashed, never built), which must give
no contract finding.
"""

from __future__ import annotations

import pytest

from analyze_synth import T0, events_frame, rosout_frame, stdout_frame, string_frame, with_meta
from grader.analyze import get
from grader.analyze.contract import check_contract
from grader.contracts.contract import Contract

CONTRACT = Contract.model_validate({
    "packages": {"pkg": "turtle_goal"},
    "executables": {"greeter": {"package": "turtle_goal", "name": "my_first_node"}},
    "launch_files": {"app": {"package": "turtle_goal", "name": "goal_setter.launch.py"}},
    "nodes": {"setter_node": {"name": "/goal_setter", "serves": "/set_goal"},
              "greeter_node": {"name": "/my_first_node"}},
    "topics": {"goal": {"name": "/goal", "type": "geometry_msgs/msg/Point"},
               "news": {"name": "/robot_news", "type": "std_msgs/msg/String"}},
    "services": {"set_goal": "/set_goal"},
    "actions": {"turtle_goal": {"name": "/turtle_goal", "type": "pkg/action/Go"}},
})
PARAM_SERVICES = ["describe_parameters", "get_parameters", "list_parameters", "set_parameters",
                  "get_parameter_types", "set_parameters_atomically", "get_type_description"]


def graph(nodes=(), pubs=None, subs=None, types=None, servers=None, service_types=None, packages=None,
          sim="turtlesim") -> dict:
    servers = dict(servers or {})
    for n in nodes:                       # every node offers rclpy's parameter services
        for s in PARAM_SERVICES:
            servers.setdefault(f"{n}/{s}", [n.rsplit('/', 1)[-1]])
    rows = [(T0, "scenario_start", {"sim_node": sim}),
            (T0 + 1, "graph", {"nodes": ["/grader_driver", "/grader_recorder", *nodes],
                               "publishers": pubs or {}, "subscribers": subs or {}, "services": sorted(servers),
                               "topic_types": types or {}, "servers": servers,
                               "service_types": service_types or {}})]
    if packages is not None:
        rows.insert(1, (T0 + 0.5, "packages", {"packages": packages}))
    return with_meta({"/grader/events": events_frame(rows)})


def found(frames: dict, *roles: str) -> dict[str, tuple]:
    return {m.role: (m.found, m.feedback) for m in check_contract(CONTRACT, set(roles), frames)}


BUILT = {"status": "built", "executables": [], "launch_files": []}


def test_package_called_otherwise_is_one_mismatch_naming_both() -> None:
    facts = {"goal_pkg": {**BUILT, "executables": ["goal_setter_node"], "launch_files": ["app.launch.py"]},
             "turtle_goal_interfaces": BUILT}          # an interface package holds no nodes: not a candidate
    got = found(graph(packages=facts), "pkg")
    assert got == {"pkg": (("goal_pkg",), "Your package is called goal_pkg; this lab asks for turtle_goal.")}
    # look-alike: the package is there (it may have failed to build: the items say so)
    assert found(graph(packages={"turtle_goal": {**BUILT, "status": "failed"}}), "pkg") == {}


def test_executable_called_otherwise_and_one_that_is_missing() -> None:
    other = {"turtle_goal": {**BUILT, "executables": ["hello"]}}
    (names, text), = found(graph(packages=other), "greeter").values()
    assert names == ("hello",) and "is called hello; this lab asks for my_first_node" in text
    assert "ros2 run turtle_goal my_first_node" in text
    # look-alike: no executable of another name (never started, for its own reason): no finding
    assert found(graph(packages={"turtle_goal": BUILT}), "greeter") == {}
    assert found(graph(packages={"turtle_goal": {**BUILT, "executables": ["my_first_node"]}}), "greeter") == {}


def test_launch_file_called_otherwise() -> None:
    facts = {"turtle_goal": {**BUILT, "launch_files": ["app.launch.py"]}}
    (names, text), = found(graph(packages=facts), "app").values()
    assert names == ("app.launch.py",) and "this lab asks for goal_setter.launch.py" in text


def test_node_found_by_what_it_does() -> None:
    frames = graph(nodes=["/turtlesim", "/setter", "/helper"], servers={"/set_goal": ["setter"]})
    (names, text), = found(frames, "setter_node").values()
    assert names == ("/setter",)
    assert text == "Your node that serves /set_goal is called /setter; this lab asks for /goal_setter."
    # look-alike: the goal setter crashed, so nothing serves /set_goal: /helper is not taken for it
    assert found(graph(nodes=["/turtlesim", "/helper"]), "setter_node") == {}
    assert found(graph(nodes=["/goal_setter"], servers={"/set_goal": ["goal_setter"]}), "setter_node") == {}


def test_node_without_a_relation_is_the_one_student_node() -> None:
    assert found(graph(nodes=["/hello_node"]), "greeter_node")["greeter_node"][0] == ("/hello_node",)
    assert found(graph(nodes=[]), "greeter_node") == {}          # it crashed: no node at all
    # the simulator is not a student's node
    assert found(graph(nodes=["/turtlesim"]), "greeter_node") == {}


def test_topic_published_under_another_name_vs_never_published() -> None:
    other = graph(nodes=["/talker"], pubs={"/news": ["talker"], "/rosout": ["talker"]},
                  types={"/news": ["std_msgs/msg/String"]})
    (names, text), = found(other, "news").values()
    assert names == ("/news",) and text == "The topic your node publishes is called /news; this lab asks for /robot_news."
    # look-alike: the node advertises /robot_news and never publishes: the name is right
    silent = graph(nodes=["/talker"], pubs={"/robot_news": ["talker"]}, types={"/robot_news": ["std_msgs/msg/String"]})
    assert found(silent, "news") == {}
    # another type is not the same thing under another name
    wrong_type = graph(nodes=["/talker"], pubs={"/news": ["talker"]}, types={"/news": ["std_msgs/msg/Int32"]})
    assert found(wrong_type, "news") == {}


def test_topic_subscribed_under_another_name() -> None:
    frames = graph(nodes=["/goal_setter", "/ctl"], pubs={"/goal": ["goal_setter"]}, subs={"/goals": ["ctl"]},
                   types={"/goal": ["geometry_msgs/msg/Point"], "/goals": ["geometry_msgs/msg/Point"]})
    (names, text), = found(frames, "goal").values()
    assert names == ("/goals",) and "your node subscribes to is called /goals" in text


def test_service_and_action_called_otherwise() -> None:
    frames = graph(nodes=["/goal_setter"], servers={"/setgoal": ["goal_setter"],
                                                     "/go/_action/send_goal": ["goal_setter"]},
                   service_types={"/go/_action/send_goal": ["pkg/action/Go_SendGoal"]})
    got = found(frames, "set_goal", "turtle_goal")
    assert got["set_goal"] == (("/setgoal",), "Your service is called /setgoal; this lab asks for /set_goal.")
    assert got["turtle_goal"][0] == ("/go",)
    # look-alike: nothing but the node's parameter services: the service never appeared
    assert found(graph(nodes=["/goal_setter"]), "set_goal", "turtle_goal") == {}


def test_only_the_roles_asked_for_are_checked() -> None:
    assert found(graph(nodes=["/hello_node"]), "pkg") == {}


# ------------------------------------------------------------------------ log analyzers' diagnoses
def _logs(stdout=(), rosout=(), subscribers=None, published=()) -> dict:
    frames = {"/grader/events": events_frame([(T0, "scenario_start", {"sim_node": "turtlesim"}),
                                              (T0 + 9, "graph", {"nodes": [], "subscribers": subscribers or {}})])}
    if stdout:
        frames["/grader/stdout"] = stdout_frame(stdout)
    if rosout:
        frames["/rosout"] = rosout_frame(rosout)
    if published:
        frames["/robot_news"] = string_frame(published)
    return with_meta(frames)


HELLO = "Hello ROS2 developer"


def test_logged_under_another_node_name_is_logged_and_costs_only_the_name() -> None:
    """Issue 37: real first packages call the node first_node or py_test; the greeting is still
    logged, and its item says under which name (the name's own item charges the name)."""
    frames = _logs(stdout=[(T0 + 1, "node", "stderr", f"[INFO] [{T0 + 1:.3f}] [hello_node]: {HELLO}")],
                   rosout=[(T0 + 1, "hello_node", HELLO)])
    f = get("logged")(frames, {"logger": "/my_first_node", "pattern": "Hello"})
    assert f.status == "pass" and f.fraction == 1.0, f.feedback
    assert f.feedback == f"hello_node logged {HELLO!r} through the ROS logger (this lab asks for the node name my_first_node)."
    assert f.evidence["logged_as"] == "hello_node" and "printed" not in f.feedback
    # a rubric that wants the name itself says so
    f = get("logged")(frames, {"logger": "/my_first_node", "pattern": "Hello", "other_names": False})
    assert f.status == "fail" and "was logged by the node hello_node, not by my_first_node" in f.feedback
    # look-alike: the line only printed in the ROS console format (never reached /rosout) earns nothing
    console = _logs(stdout=[(T0 + 1, "node", "stdout", f"[INFO] [{T0 + 1:.3f}] [hello_node]: {HELLO}")])
    f = get("logged")(console, {"logger": "/my_first_node", "pattern": "Hello"})
    assert f.status == "fail" and "hello_node" in f.feedback
    # the grader's and the simulator's own loggers are never a student's
    grader = _logs(rosout=[(T0 + 1, "grader_driver", HELLO)])
    assert get("logged")(grader, {"logger": "/my_first_node", "pattern": "Hello"}).status == "fail"


def test_printed_is_printed() -> None:
    f = get("logged")(_logs(stdout=[(T0 + 1, "node", "stdout", HELLO)]), {"logger": "my_first_node", "pattern": "Hello"})
    assert f.status == "fail" and "was printed, not logged" in f.feedback


def test_heard_by_a_subscriber_of_any_name() -> None:
    news = [(T0 + 1 + k, f"Hello robot {k}") for k in range(5)]
    heard = [(T0 + 1.01 + k, "news_listener", f"I heard: Hello robot {k}") for k in range(5)]
    frames = _logs(rosout=heard, published=news, subscribers={"/robot_news": ["news_listener", "grader_recorder"]})
    f = get("heard_messages")(frames, {"topic": "/robot_news"})
    assert f.status == "pass" and "news_listener logged 5 messages" in f.feedback
    # the rubric may fix the logger: then the same lines are logged under another node's name
    f = get("heard_messages")(frames, {"topic": "/robot_news", "logger": "number_subscriber"})
    assert f.status == "fail" and "logged by the node news_listener, not by number_subscriber" in f.feedback
    # look-alike: the same lines printed
    printed = _logs(stdout=[(t, "subscriber", "stdout", text) for t, _, text in heard], published=news,
                    subscribers={"/robot_news": ["listener"]})
    f = get("heard_messages")(printed, {"topic": "/robot_news"})
    assert f.status == "fail" and "was printed, not logged" in f.feedback


def test_a_subscriber_is_judged_from_the_first_message_it_heard() -> None:
    """Messages published before the subscriber's first line may have gone out before DDS
    matched the two processes: they do not count against it. Missed ones after it do."""
    news = [(T0 + 1 + k / 4, f"Hello robot {k}") for k in range(14)]      # 4 Hz
    subs = {"/robot_news": ["listener"]}
    late = [(T0 + 1.01 + k / 4, "listener", f"I heard: Hello robot {k}") for k in range(4, 14)]
    f = get("heard_messages")(_logs(rosout=late, published=news, subscribers=subs), {"topic": "/robot_news"})
    # (judged from 1 s before its first line, it had missed 3 of 13: 77 %)
    assert f.status == "pass" and f.evidence["published_while_listening"] == 10, f.evidence
    # look-alike: the same first and last lines, two in between missing
    gaps = [h for h in late if h[2] not in ("I heard: Hello robot 7", "I heard: Hello robot 8")]
    f = get("heard_messages")(_logs(rosout=gaps, published=news, subscribers=subs), {"topic": "/robot_news"})
    assert f.status != "pass" and f.evidence["share"] == 0.8, f.evidence


def test_nobody_subscribed_vs_subscribed_and_silent() -> None:
    news = [(T0 + 1 + k, f"Hello robot {k}") for k in range(5)]
    f = get("heard_messages")(_logs(published=news), {"topic": "/robot_news"})
    assert f.status == "fail" and f.feedback.startswith("No node subscribed to /robot_news")
    f = get("heard_messages")(_logs(published=news, subscribers={"/robot_news": ["listener"]}), {"topic": "/robot_news"})
    assert f.status == "fail" and f.feedback.startswith("Your subscriber listener logged nothing")


def test_advertised_and_silent_vs_published_elsewhere() -> None:
    silent = with_meta({"/robot_news": string_frame([])}, publishers={"/robot_news": ["number_publisher"]})
    f = get("text_messages")(silent, {"topic": "/robot_news", "pattern": "x"})
    assert "number_publisher advertised /robot_news but published no message on it" in f.feedback
    elsewhere = with_meta({"/news": string_frame([(T0, "Hello robot 0")])}, types={"/news": "std_msgs/msg/String"},
                          publishers={"/news": ["number_publisher"]})
    f = get("text_messages")(elsewhere, {"topic": "/robot_news", "pattern": "x"})
    assert "No messages were recorded on /robot_news" in f.feedback and "/news" in f.feedback


@pytest.mark.parametrize("code,words", [(1, "crashed with exit code 1"), (0, "returned on its own"),
                                         (None, "could not be started")])
def test_a_missing_node_says_what_became_of_its_process(code, words) -> None:
    rows = [(T0, "scenario_start", {"sim_node": "turtlesim"}),
            (T0 + 2, "graph", {"nodes": ["/grader_driver"]})]
    if code is None:
        rows.append((T0 + 0.5, "node_unavailable", {"process": "node", "error": "package 'p' has no executable 'x'"}))
    else:
        rows += [(T0 + 0.5, "node_started", {"process": "node", "node_name": None}),
                 (T0 + 1, "process_exit", {"process": "node", "returncode": code, "stopped_by_grader": False})]
    f = get("nodes_running")(with_meta({"/grader/events": events_frame(rows)}), {"nodes": ["/my_first_node"]})
    assert f.status == "fail" and words in f.feedback and "did it crash" not in f.feedback


@pytest.mark.parametrize("running,status", [(["node"], "pass"), ([], "fail"), (None, "pass")])
def test_a_node_counts_only_while_its_process_ran(running, status) -> None:
    """The graph lags behind a dead process: a greeter that raised in its constructor was in the
    snapshot its crash ended the step with once in CI, and got the name's point; a snapshot with
    no process that could have made the node alive does not count it (a bag without ``running``
    keeps the old reading; the reference simulator's node counts whoever runs)."""
    graph = {"nodes": ["/grader_driver", "/my_first_node", "/turtlesim"]}
    if running is not None:
        graph["running"] = running
    rows = [(T0, "scenario_start", {"sim_node": "turtlesim"}),
            (T0 + 0.5, "node_started", {"process": "node", "node_name": None}),
            (T0 + 1, "process_exit", {"process": "node", "returncode": 1, "stopped_by_grader": False}),
            (T0 + 1.1, "graph", graph)]
    f = get("nodes_running")(with_meta({"/grader/events": events_frame(rows)}),
                             {"nodes": ["/my_first_node", "/turtlesim"]})
    assert f.status == ("partial" if status == "fail" else status), f.feedback
    if status == "fail":
        assert f.value == "1/2 nodes" and f.evidence["stale"] == ["/my_first_node"]
        assert "/my_first_node was never seen running in the ROS graph (node crashed with exit code 1)" \
            in f.feedback
    else:
        assert f.value == "2/2 nodes"


def test_logged_to_the_console_only_is_not_printed() -> None:
    """A bare rclpy.logging.get_logger('my_first_node') prints in the ROS format, not to /rosout."""
    line = f"[INFO] [{T0 + 1:.3f}] [my_first_node]: {HELLO}"
    f = get("logged")(_logs(stdout=[(T0 + 1, "node", "stderr", line)]), {"logger": "my_first_node", "pattern": "Hello"})
    assert f.status == "fail" and "reached the console under the name my_first_node but not /rosout" in f.feedback


def test_boxmuller_values_on_the_console_are_not_print() -> None:
    pairs = [(T0 + 1 + 0.01 * k, {"data": [0.5, 0.25]}) for k in range(20)]
    frames = {"/random_numbers": __import__("analyze_synth").frame([t for t, _ in pairs],
                                                                   **{"data[0]": 0.5, "data[1]": 0.25, "data.len": 2}),
              "/rosout": rosout_frame([(T0, "other", "start")])}
    console = [(T0 + 1.005 + 0.01 * k, "subscriber", "stderr", f"[INFO] [{T0 + 1 + 0.01 * k:.3f}] [sub]: {0.1 * k:.4f}")
               for k in range(20)]
    plain = [(t, p, "stdout", line.rsplit(": ", 1)[1]) for t, p, _, line in console]
    f = get("boxmuller_logging")(with_meta({**frames, "/grader/stdout": stdout_frame(console)}), {"topic": "/random_numbers"})
    assert f.status == "fail" and "not its node's" in f.feedback
    f = get("boxmuller_logging")(with_meta({**frames, "/grader/stdout": stdout_frame(plain)}), {"topic": "/random_numbers"})
    assert f.status == "fail" and "with print()" in f.feedback


def test_a_recording_that_misses_a_package_is_reused_only_with_the_same_packages(tmp_path) -> None:
    """Its `packages` event names the student's other packages (the contract's candidates): a
    recording made for a student whose package was called foo must not speak for one whose is bar."""
    from types import SimpleNamespace

    from grader.grading.reuse import scenario_key
    from grader.scenario.model import Scenario

    scenario = Scenario.model_validate({"sim": False, "processes": [{"name": "n", "package": "pkg", "executable": "x"}],
                                        "steps": [{"id": "w", "wait": 1}]})

    def build(name: str, exes=("x",)):
        src = tmp_path / name / "src" / name
        src.mkdir(parents=True, exist_ok=True)
        (src / "package.xml").write_text(f"<package><name>{name}</name></package>")
        return SimpleNamespace(root=tmp_path / name, packages={name: SimpleNamespace(status="built", executables=dict.fromkeys(exes))})

    assert scenario_key("s", scenario, build("foo")) != scenario_key("s", scenario, build("bar"))
    assert scenario_key("s", scenario, build("pkg")) == scenario_key("s", scenario, build("pkg", ("x", "y")))
