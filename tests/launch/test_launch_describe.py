"""Student launch files read by the grader's own launch/launch_ros subset (no ROS 2 ``launch``
on PyPI): what each file would start, and a clear ``file:line`` error for what the subset lacks.

Each file runs in a subprocess (``python -m grader.launch.describe``), as the grader runs it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from grader.launch import node_ros_args

REPO = Path(__file__).resolve().parents[2]
LAUNCH = Path(__file__).parent / "ws" / "src" / "launch_demo" / "launch"
CHAPTER = REPO / "fixtures" / "submissions" / "goal_setter" / "chapter" / "src" / "turtle_goal" / "launch"


def describe(path: Path, *args: str, env: dict[str, str] | None = None) -> dict:
    proc = subprocess.run([sys.executable, "-m", "grader.launch.describe", str(path), *args],
                          capture_output=True, text=True, timeout=60,
                          env={**os.environ, **(env or {})})
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture
def prefix(tmp_path: Path) -> dict[str, str]:
    """An install prefix where ``launch_demo``'s share folder is found (what a build makes)."""
    root = tmp_path / "install" / "launch_demo"
    (root / "share" / "ament_index" / "resource_index" / "packages").mkdir(parents=True)
    (root / "share" / "ament_index" / "resource_index" / "packages" / "launch_demo").write_text("")
    (root / "share" / "launch_demo" / "config").mkdir(parents=True)
    return {"AMENT_PREFIX_PATH": str(root)}


def test_the_chapters_launch_file() -> None:
    """Seed 000's launch file as printed, with the student's package name."""
    entities = describe(CHAPTER / "goal_setter.launch.py")["entities"]
    assert [(e["kind"], e["package"], e["executable"], e["name"]) for e in entities] == [
        ("node", "turtlesim", "turtlesim_node", "turtlesim"),
        ("node", "turtle_goal", "goal_setter_node", "goal_setter"),
        ("node", "turtle_goal", "turtle_controller_node", "turtle_controller")]
    assert all(e["delay"] == 0 and e["at"].startswith("goal_setter.launch.py:") for e in entities)


def test_parameters_remappings_namespace_and_arguments(prefix: dict[str, str]) -> None:
    (node,) = describe(LAUNCH / "params_remap.launch.py", "greeting:=hi there", env=prefix)["entities"]
    yaml_file = str(Path(prefix["AMENT_PREFIX_PATH"]) / "share" / "launch_demo" / "config" / "talker.yaml")
    assert node["name"] == "greeter" and node["namespace"] == "lab"
    assert node["parameters"] == [{"greeting": "hi there"}, yaml_file]
    assert node["remappings"] == [["chatter", "/announcements"]]
    assert node_ros_args(node) == ["--ros-args", "-r", "__node:=greeter", "-r", "__ns:=/lab",
                                   "-p", "greeting:='hi there'", "--params-file", yaml_file,
                                   "-r", "chatter:=/announcements"]
    # the declared default when the rubric passes no argument
    (node,) = describe(LAUNCH / "params_remap.launch.py", env=prefix)["entities"]
    assert node["parameters"][0] == {"greeting": "hello"}


def test_include_passes_arguments_and_timers_delay(prefix: dict[str, str]) -> None:
    included, late = describe(LAUNCH / "top.launch.py", env=prefix)["entities"]
    assert (included["name"], included["parameters"][0], included["delay"]) == ("greeter", {"greeting": "included"}, 0)
    assert included["at"].startswith("params_remap.launch.py:")        # where the node is declared
    assert (late["name"], late["parameters"], late["delay"]) == ("late", [{"greeting": "later", "repeat": 7}], 1.0)


def test_unsupported_action_names_the_api_and_the_line() -> None:
    error = describe(LAUNCH / "unsupported.launch.py")["error"]
    assert error.startswith("unsupported.launch.py:2: launch.actions.GroupAction is not supported")
    assert "launch_ros.actions.Node" in error           # says what to use instead


def test_xml_launch_files_get_one_clear_error() -> None:
    error = describe(LAUNCH / "talker.launch.xml")["error"]
    assert error == ("talker.launch.xml: XML launch files are not supported by the grader's launch "
                     "loader; write it as a Python launch file (*.launch.py)")


@pytest.mark.parametrize("body,error", [
    ("Node(package='p', executable='e', exec_name='x')", "bad.launch.py:6: Node(exec_name=...) is not supported"),
    ("ExecuteProcess(cmd='ls -l', shell=True)", "bad.launch.py:6: ExecuteProcess(shell=True) is not supported"),
    ("Node(package='p', executable=LaunchConfiguration('exe'))", "bad.launch.py:6: launch configuration 'exe' has no value"),
    ("Node(package=FindPackageShare('nowhere'), executable='e')", "bad.launch.py:6: package 'nowhere' is not installed"),
    ("Node(package='p', executable=undefined_name)", "bad.launch.py:6: NameError: name 'undefined_name'"),
    ("DeclareLaunchArgument('speed')", "bad.launch.py:6: launch argument 'speed' has no default; the rubric must pass it"),
    ("DeclareLaunchArgument('mode', default_value='fast', choices=['slow'])", "bad.launch.py:6: launch argument 'mode' is 'fast', not one of ['slow']"),
])
def test_mistakes_in_a_launch_file_are_located(tmp_path: Path, prefix: dict[str, str], body: str, error: str) -> None:
    path = tmp_path / "bad.launch.py"
    path.write_text("from launch import LaunchDescription\n"
                    "from launch.actions import DeclareLaunchArgument, ExecuteProcess\n"
                    "from launch.substitutions import LaunchConfiguration\n"
                    "from launch_ros.actions import Node\n"
                    "from launch_ros.substitutions import FindPackageShare\n"
                    f"def generate_launch_description(): return LaunchDescription([{body}])\n")
    assert describe(path, env=prefix)["error"].startswith(error)


def test_conditions_environment_and_processes(tmp_path: Path) -> None:
    path = tmp_path / "cond.launch.py"
    path.write_text(
        "from launch import LaunchDescription\n"
        "from launch.actions import DeclareLaunchArgument, ExecuteProcess, SetEnvironmentVariable\n"
        "from launch.conditions import IfCondition, UnlessCondition\n"
        "from launch.substitutions import EnvironmentVariable, LaunchConfiguration\n"
        "from launch_ros.actions import Node\n"
        "def generate_launch_description():\n"
        "    use = LaunchConfiguration('use_b')\n"
        "    return LaunchDescription([\n"
        "        DeclareLaunchArgument('use_b', default_value='false'),\n"
        "        SetEnvironmentVariable('TURTLE_MODE', 'fast'),\n"
        "        Node(package='p', executable='a', condition=UnlessCondition(use)),\n"
        "        Node(package='p', executable='b', condition=IfCondition(use)),\n"
        "        ExecuteProcess(cmd=['echo', EnvironmentVariable('TURTLE_MODE')]),\n"
        "    ])\n")
    a, echo = describe(path)["entities"]
    assert a["executable"] == "a" and echo["cmd"] == ["echo", "fast"]
    b, _ = describe(path, "use_b:=true")["entities"]
    assert b["executable"] == "b"


def test_parameter_values_are_typed_as_launch_ros_types_them(tmp_path: Path) -> None:
    """Text and substitutions are read as YAML ('2.0' becomes a double), unless wrapped in
    ParameterValue(value_type=str): a student's declare_parameter('speed', 1.0) gets a double."""
    path = tmp_path / "typed.launch.py"
    path.write_text(
        "from launch import LaunchDescription\n"
        "from launch.substitutions import LaunchConfiguration\n"
        "from launch_ros.actions import Node\n"
        "from launch_ros.parameter_descriptions import ParameterValue\n"
        "def generate_launch_description():\n"
        "    return LaunchDescription([Node(package='p', executable='e', parameters=[{\n"
        "        'speed': LaunchConfiguration('speed', default='2.0'), 'on': 'true', 'n': '3',\n"
        "        'label': ParameterValue(LaunchConfiguration('speed', default='2.0'), value_type=str),\n"
        "        'gains': [1.0, 2.5], 'names': ['a', 'b'], 'pid': {'p': 0.5}}])])\n")
    (node,) = describe(path)["entities"]
    assert node["parameters"] == [{"speed": 2.0, "on": True, "n": 3, "label": "2.0", "gains": [1.0, 2.5],
                                   "names": ["a", "b"], "pid.p": 0.5}]
    assert node_ros_args(node)[1:] == ["-p", "speed:=2.0", "-p", "on:=true", "-p", "n:=3", "-p", "label:='2.0'",
                                       "-p", "gains:=[1.0, 2.5]", "-p", "names:=['a', 'b']", "-p", "pid.p:=0.5"]
