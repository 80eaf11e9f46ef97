"""The colcon build and launch-file loading run student code (setup.py, a launch file) in the
same jail: they write only the build area, reach no network, and leave nothing running."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from grader.launch import describe_launch
from grader.workspace import build_workspace
from sandboxhelpers import processes_with, require_protections, snapshot

ATTACK = '''
import os, socket, subprocess, sys
def attempt(what, fn):
    try:
        fn()
        print("ATTACK-OK " + what, file=sys.stderr)
    except Exception as exc:
        print("ATTACK-DENIED " + what + " " + type(exc).__name__, file=sys.stderr)
attempt("write", lambda: open({target!r}, "a").write("pwned"))
attempt("network", lambda: socket.create_connection(("1.1.1.1", 53), timeout=2))
if os.fork() == 0:   # a daemon (not holding colcon's pipe: colcon would wait for it until its timeout)
    os.setsid()
    subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)", {token!r}], start_new_session=True,
                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os._exit(0)
'''


def _package(src: Path, target: Path, token: str) -> None:
    pkg = src / "sneaky"
    (pkg / "sneaky").mkdir(parents=True)
    (pkg / "launch").mkdir()
    (pkg / "resource").mkdir()
    (pkg / "resource" / "sneaky").write_text("")
    (pkg / "sneaky" / "__init__.py").write_text("")
    (pkg / "sneaky" / "node.py").write_text("def main():\n    print('hi')\n")
    (pkg / "package.xml").write_text(
        '<?xml version="1.0"?><package format="3"><name>sneaky</name><version>0.0.1</version>'
        '<description>d</description><maintainer email="t@example.org">t</maintainer><license>MIT</license>'
        '<export><build_type>ament_python</build_type></export></package>')
    (pkg / "setup.cfg").write_text("[develop]\nscript_dir=$base/lib/sneaky\n[install]\ninstall_scripts=$base/lib/sneaky\n")
    (pkg / "setup.py").write_text(ATTACK.format(target=str(target), token=token) + (
        "from setuptools import setup\n"
        "setup(name='sneaky', version='0.0.1', packages=['sneaky'],\n"
        "      data_files=[('share/ament_index/resource_index/packages', ['resource/sneaky']),\n"
        "                  ('share/sneaky', ['package.xml']), ('share/sneaky/launch', ['launch/go.launch.py'])],\n"
        "      entry_points={'console_scripts': ['node = sneaky.node:main']})\n"))
    (pkg / "launch" / "go.launch.py").write_text(ATTACK.format(target=str(target), token=token) + (
        "from launch import LaunchDescription\nfrom launch_ros.actions import Node\n"
        "def generate_launch_description():\n"
        "    return LaunchDescription([Node(package='sneaky', executable='node', name='n')])\n"))


@pytest.mark.slow
def test_setup_py_and_launch_file_run_jailed(tmp_path, world, token, capfd) -> None:
    require_protections("filesystem", "unprivileged user", "kill all")
    target = world / "batch" / "classmate" / "result.json"
    _package(tmp_path / "ws" / "src", target, token)
    before = snapshot(world)
    build = build_workspace(tmp_path / "ws", cache_dir=tmp_path / "cache")
    assert build.ok, build.packages["sneaky"].log_excerpt
    log = build.build_log.read_text()
    assert "ATTACK-DENIED write PermissionError" in log or "ATTACK-DENIED write FileNotFoundError" in log, log
    assert "ATTACK-DENIED network" in log and "ATTACK-OK" not in log
    # what colcon wrote is the grader's again (no process of the sandbox uid can change it later)
    assert {p.stat().st_uid for p in build.install.rglob("*")} == {os.getuid()}

    entities = describe_launch(build.install / "sneaky" / "share" / "sneaky" / "launch" / "go.launch.py", {},
                               build.env())
    assert [e["executable"] for e in entities] == ["node"]
    assert snapshot(world) == before
    assert processes_with(token) == []
