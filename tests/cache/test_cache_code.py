"""The cache keys' code and environment parts: derived from the code, the same wherever the
package is installed, and changed by what changes an entry (a driver constant, a compiler)."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from grader.cache import code, environment
from grader.cache.code import (BUILD_ROOTS, EXTRA_DATA, NOT_MAKING, PACKAGE, RECORDING_ROOTS, closure, code_files,
                               files_digest, module_file)


def _ast_imports(name: str) -> set[str]:
    """The grader modules ``name`` imports, by the book (``ast``), lazy imports included."""
    file = module_file(name)
    tree = ast.parse(file.read_bytes())
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            found |= {node.module} | {f"{node.module}.{a.name}" for a in node.names}
    return {n for n in found if n.split(".")[0] == "grader" and module_file(n) is not None}


@pytest.mark.parametrize("roots", [RECORDING_ROOTS, BUILD_ROOTS], ids=["recording", "build"])
def test_the_closure_holds_every_import_ast_finds(roots) -> None:
    """The regular expressions that read imports (fast) miss none of them (ast, slow)."""
    modules, _files = closure(roots)
    missing = {f"{m} imports {i}" for m in modules for i in _ast_imports(m)
               if i not in modules and not i.startswith(tuple(s + "." for s in NOT_MAKING)) and i not in NOT_MAKING}
    assert not missing, sorted(missing)


def test_the_recording_set_holds_what_makes_a_recording() -> None:
    rel = {f.relative_to(PACKAGE).as_posix() for f in code_files(RECORDING_ROOTS, EXTRA_DATA)}
    # imported: child, driver, steps, recorder, simulator, runner, sandbox, launch loader, reuse
    for must in ("scenario/run.py", "scenario/driver.py", "scenario/steps.py", "bag/recorder_thread.py",
                 "bag/writer.py", "sim/node.py", "sim/physics.py", "runner.py", "sandbox/jail.py",
                 "launch/entities.py", "grading/timescale.py", "workspace/executables.py",
                 # the simulator's record of its poses, the driver's client ids, the CPU-wait probe
                 # and the retry of a starved recording
                 "sim/record.py", "scenario/client_gid.py", "scenario/cpuwait.py", "grading/starvation.py"):
        assert must in rel, must
    # started as processes: `-m grader.sim`, the launch loader, the module: entry runner
    assert {"sim/__main__.py", "launch/describe.py", "workspace/launch.py"} <= rel
    # named by path: the sandbox's PID 1, the Fast DDS profiles, the launch stand-ins; interfaces
    assert {"sandbox/enter.py", "dds/fastdds_profile.xml", "dds/fastdds_profile_sandbox.xml",
            "launch/api/launch_ros/actions.py", "interfaces/turtlesim/msg/Pose.msg"} <= rel
    # not the analysis side: a new analyzer or report does not record every scenario again
    assert not any(r.startswith(("report/", "rubric/", "scores/", "lms/")) for r in rel), rel
    assert "grading/pipeline.py" not in rel and not any(r.startswith("analyze/") for r in rel), rel
    build = {f.relative_to(PACKAGE).as_posix() for f in code_files(BUILD_ROOTS)}
    assert build < rel and "workspace/diagnose.py" in build and "scenario/driver.py" not in build


def _copy(dest: Path) -> Path:
    shutil.copytree(PACKAGE, dest / "grader", ignore=shutil.ignore_patterns("__pycache__", "_data"))
    return dest / "grader"


def _digests_in(site: Path) -> list[str]:
    out = subprocess.run([sys.executable, "-c", "from grader.cache import code; import grader; "
                          "print(grader.__file__); print(code.recording_code()); print(code.build_code())"],
                         env={**os.environ, "PYTHONPATH": str(site)}, cwd=site, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out[0] == str(site / "grader" / "__init__.py")        # the copy, not the checkout
    return out[1:]


def test_digest_follows_the_files_not_where_they_are(tmp_path: Path) -> None:
    """A copy of the package elsewhere has the same digests; one driver constant changed
    changes the recording digest (not the build's); so does a new interface definition."""
    copy = _copy(tmp_path / "a")
    assert _digests_in(tmp_path / "a") == [code.recording_code(), code.build_code()]
    driver = copy / "scenario" / "driver.py"
    text = driver.read_text()
    assert "poll: float = 0.02," in text
    driver.write_text(text.replace("poll: float = 0.02,", "poll: float = 0.025,"))
    changed = _digests_in(tmp_path / "a")
    assert changed[0] != code.recording_code() and changed[1] == code.build_code()
    driver.write_text(text)
    # an analyzer's change regrades from the same bags: it makes no recording
    analyze = copy / "analyze" / "__init__.py"
    analyze.write_text(analyze.read_text() + "\nTHRESHOLD = 1\n")
    assert _digests_in(tmp_path / "a") == [code.recording_code(), code.build_code()]
    (copy / "interfaces" / "turtlesim" / "msg" / "Extra.msg").write_text("float32 x\n")
    assert _digests_in(tmp_path / "a")[0] != code.recording_code()


@pytest.mark.slow
def test_an_installed_wheel_has_the_checkouts_digests(tmp_path: Path) -> None:
    """The wheel carries every file of both sets, at the same place: same digests."""
    from grader.lms.gradescope_bundle import build_wheel

    (tmp_path / "dist").mkdir()
    wheel = build_wheel(tmp_path / "dist")          # as `grader gradescope` builds it (pip, isolated)
    site = tmp_path / "site"
    with zipfile.ZipFile(wheel) as zf:
        zf.extractall(site)              # what pip installs into site-packages
    package = site / "grader"
    for roots, extra, here in ((RECORDING_ROOTS, EXTRA_DATA, code.recording_code()), (BUILD_ROOTS, (), code.build_code())):
        files = code_files(roots, extra, package=package)
        assert [f.relative_to(package) for f in files] == [f.relative_to(PACKAGE) for f in code_files(roots, extra)]
        assert files_digest(files, package) == here


def test_the_environment_part_changes_with_the_toolchain(tmp_path: Path, monkeypatch) -> None:
    """A build's key follows the compiler, CMake and ROS; a recording's follows ROS 2 and Python."""
    before_build, before_run = environment.build_tools.__wrapped__(), environment.runtime.__wrapped__()
    assert before_build["cmake"].startswith("cmake version") and before_run["rclpy"] != "?"
    fake = tmp_path / "cc"
    fake.write_text("#!/bin/sh\necho 'cc (Fake) 99.1'\n")
    fake.chmod(0o755)
    monkeypatch.setenv("CC", str(fake))
    after = environment.build_tools.__wrapped__()
    assert after["cc"] == "cc (Fake) 99.1" and after["digest"] != before_build["digest"]
    monkeypatch.setenv("ROS_DISTRO", "rolling")
    assert environment.runtime.__wrapped__()["digest"] != before_run["digest"]
    # a ROS package upgraded: its package.xml version is part of it
    prefix = tmp_path / "overlay"
    (prefix / "share" / "rclpy").mkdir(parents=True)
    (prefix / "share" / "rclpy" / "package.xml").write_text("<package><version>99.0.0</version></package>")
    monkeypatch.delenv("ROS_DISTRO")
    monkeypatch.setenv("AMENT_PREFIX_PATH", f"{prefix}{os.pathsep}{os.environ.get('AMENT_PREFIX_PATH', '')}")
    upgraded = environment.runtime.__wrapped__()
    assert upgraded["rclpy"] == "99.0.0" and upgraded["digest"] != before_run["digest"]


def test_a_recordings_key_follows_how_it_is_run(tmp_path: Path) -> None:
    """Run k of a repeated scenario, the time scale and the rates its watchdog expects are each
    a recording of their own; the same settings give the same key."""
    from types import SimpleNamespace

    from grader.grading.reuse import recording_settings, scenario_key
    from grader.scenario.model import Scenario

    scenario = Scenario.model_validate({"sim": False, "processes": [{"name": "n", "package": "pkg", "executable": "x"}],
                                        "steps": [{"id": "w", "wait": 1}]})
    src = tmp_path / "src" / "pkg"
    src.mkdir(parents=True)
    (src / "package.xml").write_text("<package><name>pkg</name></package>")
    build = SimpleNamespace(root=tmp_path, packages={"pkg": SimpleNamespace(status="built", executables={"x": None})})
    keys = [scenario_key("s", scenario, build, settings=recording_settings(*how))
            for how in ((), (1.0, (), 2), (1.0, (), 3), (4.0, ()), (4.0, (("/a", 10.0),)))]
    assert len(set(keys)) == len(keys), keys
    assert scenario_key("s", scenario, build, settings=recording_settings()) == keys[0]
    assert recording_settings(1.0, (), 1) == recording_settings()        # run 1 is the scenario's own
