"""The grader as students, TAs and Gradescope get it: a wheel built from a fresh clone, installed
outside the repository.

One module fixture does what an instructor and Gradescope do: `grader gradescope` in a real
`git clone` of the tree under test (it builds the wheel with pip; ``gitclone.py``), the zip unpacked into a temporary root laid out like
``/autograder``, and the bundle's ``setup.sh`` run there: it creates a clean python3.11 venv
outside the repository, pip-installs the wheel and runs `grader setup` and `grader doctor`, the
very steps the README gives students. Then:

* that installed grader lists its labs and self-checks a copy of the Lab 3 reference (`grader
  check --lab enee467-lab3`, every public item passes), and so does the same wheel set up with
  `grader setup` against a sourced "system" ROS 2 Jazzy (see ``system_ros``);
* ``run_autograder`` grades three Lab 3 fixtures in their own roots: results.json validates
  against the schema of Gradescope's format, every test's score is the item's points in grader's
  own result.json of that run, the statuses are those of the fixture's expected.yaml, and
  `grader regrade` from the recorded bags gives the same total;

No process here imports the repository: every command runs the installed ``grader`` with
PYTHONPATH removed and a working directory outside the checkout.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import jsonschema
import pytest
import yaml
from gitclone import git_clone

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "fixtures" / "submissions" / "enee467_lab3"
SCHEMA = json.loads((REPO / "grader" / "lms" / "gradescope.schema.json").read_text())

pytestmark = [pytest.mark.slow, pytest.mark.heavy, pytest.mark.ros, pytest.mark.timeout(3600)]


def clean_env(**extra: str) -> dict[str, str]:
    """The environment of a user who never cloned the repository."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "GRADER_VENV", "PYTEST_CURRENT_TEST")}
    env.update(extra)
    return env


def sh(cmd: list[str], *, cwd: Path, env: dict[str, str], timeout: float = 900) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)
    assert proc.returncode == 0, (f"{' '.join(map(str, cmd))} exited {proc.returncode}\n"
                                  f"{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}")
    return proc


@pytest.fixture(scope="module")
def autograder(tmp_path_factory) -> Path:
    """An /autograder-like root after Gradescope's image build: source/ + grader-venv/."""
    if shutil.which("python3.11") is None or not (REPO / ".git").exists():
        pytest.skip("needs python3.11 and a git checkout")
    tmp = tmp_path_factory.mktemp("installed")
    clone = git_clone(tmp / "clone")
    bundle = tmp / "autograder.zip"
    sh([sys.executable, "-m", "grader.cli", "gradescope", "--rubric", "rubrics/enee467_lab3.yaml",
        "-o", bundle], cwd=clone, env=clean_env(PYTHONPATH=str(clone)))
    root = tmp / "autograder"
    with zipfile.ZipFile(bundle) as zf:
        zf.extractall(root / "source")
        for info in zf.infolist():      # zipfile does not restore the mode bits; Gradescope does
            (root / "source" / info.filename).chmod(info.external_attr >> 16 or 0o644)
    # ~5 min on a quiet 2-core machine; the limit leaves room for one shared with other work
    setup = sh(["bash", root / "source" / "setup.sh"], cwd=root / "source",
               env=clean_env(GRADER_AUTOGRADER_ROOT=str(root)), timeout=2400)
    assert "doctor: everything works" in setup.stdout
    assert "support packages built into" in setup.stdout and "turtle_control_interfaces" in setup.stdout
    return root


@dataclass
class SystemRos:
    venv: Path
    env: dict[str, str]                 # the "sourced" environment
    setup_output: list[str]             # stdout of the first and the second `grader setup`


@pytest.fixture(scope="module")
def system_ros(autograder: Path, tmp_path_factory) -> SystemRos:
    """The wheel in a second clean venv, set up against a sourced "system" ROS 2 Jazzy.

    That ROS is the Jazzy wheels installed with ``pip install --prefix`` into a folder laid out
    like ``/opt/ros/jazzy`` (``lib/python3.11/site-packages``, ``lib``, ``share``, ``bin``) and
    sourced through the variables its setup.bash would set: no apt ROS 2 Jazzy exists for this
    machine's Debian. The venv sees system site packages, as the README tells lab machines.
    """
    tmp = tmp_path_factory.mktemp("system-ros")
    installed = autograder / "grader-venv" / "lib" / "python3.11" / "site-packages"
    reqs = installed / "grader" / "_data" / "requirements" / "ros-wheels.txt"   # the wheel's pins
    ros = tmp / "opt-ros-jazzy"
    # numpy too, as a distribution has it beside its ROS (the interface packages' CMake exports
    # name its include folder, which must be inside the "system" a jailed build sees), even when
    # the Python that installs it has one of its own
    numpy = next(installed.glob("numpy-*.dist-info")).name.removesuffix(".dist-info").replace("-", "==")
    sh(["python3.11", "-m", "pip", "install", "-q", "--disable-pip-version-check", "--prefix", ros,
        "--ignore-installed", "-r", reqs, numpy], cwd=tmp, env=clean_env())
    site = ros / "lib" / "python3.11" / "site-packages"
    libs = [ros / "lib", *sorted(site.glob("ros_*.libs"))]      # where its shared libraries are
    sourced = clean_env(ROS_DISTRO="jazzy", ROS_VERSION="2", AMENT_PREFIX_PATH=str(ros),
                        CMAKE_PREFIX_PATH=str(ros), PYTHONPATH=str(site),
                        LD_LIBRARY_PATH=os.pathsep.join(map(str, libs)),
                        PATH=f"{ros / 'bin'}:{os.environ['PATH']}")
    # a distribution's packages export this machine's include paths; pip-installed wheels need
    # the repair `grader setup` does in wheels mode (test preparation, not the code under test)
    sh(["python3.11", "-c", "import sys; from pathlib import Path; from grader.bootstrap import Target, "
        "repair_cmake_exports; repair_cmake_exports(Target(Path(sys.argv[1]), Path(sys.executable), "
        "Path()), {})", ros], cwd=tmp, env=dict(sourced, PYTHONPATH=f"{site}:{installed}"))
    wheel = next((autograder / "source").glob("grader-*.whl"))
    venv = tmp / "venv"
    sh(["python3.11", "-m", "venv", "--system-site-packages", venv], cwd=tmp, env=clean_env())
    sh([venv / "bin" / "python", "-m", "pip", "install", "-q", "--disable-pip-version-check", wheel],
       cwd=tmp, env=clean_env())
    outputs = [sh([venv / "bin" / "grader", "setup"], cwd=tmp, env=sourced).stdout for _ in range(2)]
    return SystemRos(venv, sourced, outputs)


def test_setup_with_a_sourced_system_ros(system_ros: SystemRos, tmp_path: Path) -> None:
    first, second = system_ros.setup_output
    assert "ready (system ROS 2" in first and "ros-wheels.txt" not in first
    assert "building interface package turtlesim" in first          # it has no turtlesim
    site = system_ros.venv / "lib" / "python3.11" / "site-packages"
    assert not list(site.glob("ros_jazzy_rclpy*")) and (site / "turtlesim").is_dir()
    assert "building" not in second and "installing" not in second  # idempotent
    doctor = sh([system_ros.venv / "bin" / "grader", "doctor"], cwd=tmp_path, env=system_ros.env).stdout
    assert "from system install (sourced)" in doctor and "doctor: everything works" in doctor
    assert f"turtlesim       {site}" in doctor


def _self_check(grader: Path, ws: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    shutil.copytree(FIXTURES / "reference" / "src", ws / "src")
    return subprocess.run([grader, "check", "--lab", "enee467-lab3", "--cache-dir", ws.parent / f"{ws.name}-cache"],
                          cwd=ws, env=env, capture_output=True, text=True, timeout=900)


def test_installed_wheel_self_checks_the_lab3_reference(autograder: Path, system_ros: SystemRos,
                                                         tmp_path: Path) -> None:
    """`grader check --lab enee467-lab3` on a copy of the reference passes with the installed
    wheel: with the ROS 2 wheels (the Gradescope venv) and with the sourced system ROS, side by
    side (two live gradings at once, as `make demo` runs them)."""
    venv = autograder / "grader-venv"
    where = sh([venv / "bin" / "python", "-c", "import grader, turtlesim.msg; print(grader.__file__)"],
               cwd=tmp_path, env=clean_env()).stdout.strip()
    assert Path(where).is_relative_to(venv), where            # the wheel, not the checkout
    labs = sh([venv_grader(autograder), "labs", "--json"], cwd=tmp_path, env=clean_env()).stdout
    lab3 = next(lab for lab in json.loads(labs) if lab["id"] == "enee467-lab3")
    assert Path(lab3["rubric"]).is_relative_to(venv) and lab3["auto_points"] == 50
    runs = {"wheels": (venv_grader(autograder), clean_env()),
            "system": (system_ros.venv / "bin" / "grader", system_ros.env)}
    with ThreadPoolExecutor(max_workers=2) as pool:
        futures = {mode: pool.submit(_self_check, grader, tmp_path / f"ws-{mode}", env)
                   for mode, (grader, env) in runs.items()}
    for mode, fut in futures.items():
        check = fut.result()
        assert check.returncode == 0, f"{mode}: " + check.stdout[-4000:] + check.stderr[-3000:]
        assert "All public checks pass." in check.stdout and "50/50 points" in check.stdout, mode
        report = tmp_path / f"ws-{mode}" / ".grader-check" / "check"
        # the self-check's report replays each of the five scenarios, from data beside it (issue 39)
        html = (report / "report.html").read_text()
        ran = sorted(p.parent.parent.name for p in report.glob("scenarios/*/bag/metadata.yaml"))
        assert len(ran) >= 5 and all((report / "scenarios" / sc / "replay.js").is_file()
                                     and f'data-scenario="{sc}"' in html for sc in ran), (mode, ran)


def venv_grader(root: Path) -> Path:
    return root / "grader-venv" / "bin" / "grader"


def _allowed(want) -> set[str]:
    """expected.yaml's statuses ("warn": an advisory item that did not pass)."""
    wants = want if isinstance(want, list) else [want]
    return {("fail" if w == "warn" else w) for w in wants} | ({"partial"} if "warn" in wants else set())


def _submit(fixture: str, how: str, submission: Path) -> None:
    """Put a fixture where Gradescope puts a student's upload, in one of the shapes students use."""
    src = FIXTURES / fixture / "src"
    submission.mkdir(parents=True)
    if how == "zip":                                  # an uploaded archive of the workspace
        with zipfile.ZipFile(submission / "lab3_ws.zip", "w") as zf:
            for f in sorted(src.rglob("*")):
                if f.is_file():
                    zf.write(f, Path("lab3_ws/src") / f.relative_to(src))
    elif how == "packages":                           # the package folders themselves
        shutil.copytree(src, submission, dirs_exist_ok=True)
    else:                                             # a workspace (e.g. a GitHub repository)
        shutil.copytree(src, submission / "src")


def _run_autograder(autograder: Path, tmp: Path, fixture: str, how: str) -> Path:
    root = tmp / fixture
    root.mkdir()
    (root / "source").symlink_to(autograder / "source")
    (root / "grader-venv").symlink_to(autograder / "grader-venv")
    (root / "grader-cache").symlink_to(autograder / "grader-cache")     # made by setup.sh, in the image
    _submit(fixture, how, root / "submission")
    proc = subprocess.run([root / "source" / "run_autograder"], cwd=root, capture_output=True, text=True,
                          env=clean_env(GRADER_AUTOGRADER_ROOT=str(root)), timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return root


CASES = [("reference", "zip"), ("bm_log10", "packages"), ("broken_build", "workspace")]


def _compiled(cache: Path, package: str) -> list[str]:
    """Build areas of ``cache`` that compiled ``package`` (not taken from the package cache)."""
    out = []
    for f in sorted(cache.glob("*/result.json")):
        build = json.loads(f.read_text())["packages"].get(package)
        if build and build["status"] == "built" and not build.get("reused_from"):
            out.append(f.parent.name)
    return out


def test_gradescope_bundle_grades_like_grader_grade(autograder: Path, tmp_path: Path) -> None:
    image_builds = _compiled(autograder / "grader-cache", "turtle_control_interfaces")
    assert len(image_builds) == 1, image_builds         # setup.sh compiled the support package once
    with ThreadPoolExecutor(max_workers=len(CASES)) as pool:       # `grader grade --jobs 3` load
        roots = list(pool.map(lambda case: _run_autograder(autograder, tmp_path, *case), CASES))
    rubric = autograder / "source" / "rubric" / "rubrics" / "enee467_lab3.yaml"
    problems = []
    for (fixture, _how), root in zip(CASES, roots):
        doc = json.loads((root / "results" / "results.json").read_text())
        jsonschema.validate(doc, SCHEMA)
        graded = json.loads((root / "grader-out" / "submission" / "result.json").read_text())
        items = {i["id"]: i for i in graded["items"]}
        tests = {t["extra_data"]["item"]: t for t in doc["tests"]}
        assert set(tests) == {i for i, item in items.items() if item["kind"] != "manual"}
        assert doc["score"] == graded["auto_score"] == sum(t["score"] for t in doc["tests"])
        for item_id, test in tests.items():
            assert test["score"] == (items[item_id]["points"] or 0), item_id
            assert test["max_score"] == items[item_id]["max_points"], item_id
        expected = yaml.safe_load((FIXTURES / fixture / "expected.yaml").read_text())["expected"]
        problems += [f"{fixture} {i}: expected {want}, got {tests[i]['extra_data']['status']}: "
                     f"{tests[i]['output'][:200]}"
                     for i, want in expected.items() if tests[i]["extra_data"]["status"] not in _allowed(want)]
        regrade = sh([venv_grader(root), "regrade", root / "grader-out" / "submission", "--rubric", rubric],
                     cwd=root, env=clean_env()).stdout
        assert f"submission: {doc['score']:g}/50" in regrade
    assert not problems, "\n".join(problems)
    scores = {fixture: json.loads((root / "results" / "results.json").read_text())["score"]
              for (fixture, _how), root in zip(CASES, roots)}
    assert scores == {"reference": 50, "bm_log10": 42, "broken_build": 30}
    broken = json.loads((roots[2] / "results" / "results.json").read_text())
    assert "did not build" in broken["output"] and "turtle_control" in broken["output"]
    # no submission compiled the lab's interface package again: each took the image's build
    assert _compiled(autograder / "grader-cache", "turtle_control_interfaces") == image_builds




SMALL_CONTAINER = (0.5, 768)        # Gradescope's default autograder: 0.5 vCPU, 768 MB


def test_gradescope_bundle_grades_in_gradescopes_default_container(autograder: Path, tmp_path: Path) -> None:
    """Inside a cgroup of Gradescope's default resources (0.5 CPU, 768 MB, set up as root), the
    bundle's ``run_autograder`` grades the Lab 3 reference and a buggy controller, one after the
    other as Gradescope's containers would: the reference in under 5 minutes (201 s measured), the
    controller with the wrong sign, which never settles and holds each of its four goals for the
    whole 60 s, within Gradescope's default 10-minute timeout (320 s measured: at 1x, the default
    in so small a container), every item at its expected.yaml (a starved timing item is recorded
    again, never failed), nothing killed for memory, and ``grader doctor`` inside the group
    reports the quota and the limit it found.
    (The reference lost 2 points there, measured 23 Hz for its 30 Hz timer, before the grader
    sized itself by the cgroup: issue 35.)"""
    import time

    from grader.testing.cgroup import limited_group

    cpus, memory_mb = SMALL_CONTAINER
    problems = []
    for fixture, how, limit_s in (("reference", "zip", 300), ("wrong_sign", "workspace", 600)):
        with limited_group(cpus, memory_mb, name=f"grader-gs-{fixture}-{os.getpid()}") as group:
            if group is None:
                pytest.skip("no writable cgroup with the cpu and memory controllers (run as root)")
            doctor = subprocess.run([venv_grader(autograder), "doctor"], capture_output=True, text=True,
                                    env=clean_env(), preexec_fn=group.join, timeout=300)
            assert f"CPU quota {cpus:g} of" in doctor.stdout and f"memory limit {memory_mb} MiB" in doctor.stdout, \
                doctor.stdout
            root = tmp_path / fixture
            root.mkdir()
            for name in ("source", "grader-venv", "grader-cache"):
                (root / name).symlink_to(autograder / name)
            _submit(fixture, how, root / "submission")
            t0 = time.monotonic()
            proc = subprocess.run([root / "source" / "run_autograder"], cwd=root, capture_output=True, text=True,
                                  env=clean_env(GRADER_AUTOGRADER_ROOT=str(root)), preexec_fn=group.join,
                                  timeout=600)
            took = time.monotonic() - t0
            assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
            oom = group.dirs["memory"] / "memory.oom_control"
            if oom.exists():                          # cgroup v1: "oom_kill N" (kernel 4.13+)
                kills = dict(line.split() for line in oom.read_text().splitlines()).get("oom_kill", "0")
                assert kills == "0", f"{fixture}: {kills} processes killed for memory"
        assert took < limit_s, f"{fixture} took {took:.0f} s in {cpus:g} CPU / {memory_mb} MB"
        doc = json.loads((root / "results" / "results.json").read_text())
        jsonschema.validate(doc, SCHEMA)
        expected = yaml.safe_load((FIXTURES / fixture / "expected.yaml").read_text())["expected"]
        tests = {t["extra_data"]["item"]: t for t in doc["tests"]}
        problems += [f"{fixture} {i}: expected {want}, got {tests[i]['extra_data']['status']}: "
                     f"{tests[i]['output'][:200]}"
                     for i, want in expected.items() if tests[i]["extra_data"]["status"] not in _allowed(want)]
    assert not problems, "\n".join(problems)


def test_installed_grader_grades_the_chase_lab_with_its_own_analyzer_file(autograder: Path,
                                                                          tmp_path: Path) -> None:
    """The fifth lab, written only through the analyzer plug-in point (issue 19), graded by the
    grader pip-installed from the wheel into a new venv (the Gradescope image's): the wheel
    carries ``chase.yaml`` with ``chase_checks.py`` beside it, the installed ``grader`` package
    defines none of the lab's analyzers, and an instructor's copy of those two files, outside any
    checkout, grades the chase reference with every point (one scenario, ``--jobs 1``)."""
    venv = autograder / "grader-venv"
    staged = venv / "lib" / "python3.11" / "site-packages" / "grader" / "_data" / "rubrics"
    assert (staged / "chase.yaml").is_file() and (staged / "chase_checks.py").is_file()
    course = tmp_path / "course"                      # where an instructor keeps a lab of their own
    course.mkdir()
    for name in ("chase.yaml", "chase_checks.py"):
        shutil.copy(staged / name, course / name)
    origins = sh([venv / "bin" / "python", "-c",
                  "import sys; from grader import analyze; from grader.rubric import load_rubric; "
                  "before = [n for n in analyze.names() if n.startswith('chase_')]; "
                  "load_rubric(sys.argv[1]); "
                  "print(before, sorted({analyze.origin(n) for n in analyze.names() if n.startswith('chase_')}))",
                  course / "chase.yaml"], cwd=tmp_path, env=clean_env()).stdout.strip()
    assert origins == f"[] ['{(course / 'chase_checks.py').resolve()}']", origins
    subs = tmp_path / "submissions"
    shutil.copytree(REPO / "fixtures" / "submissions" / "chase" / "reference" / "src", subs / "reference" / "src")
    out = tmp_path / "out"
    sh([venv_grader(autograder), "grade", subs, "--rubric", course / "chase.yaml", "-o", out, "--jobs", "1",
        "--cache-dir", tmp_path / "cache"], cwd=tmp_path, env=clean_env(), timeout=900)
    result = json.loads((out / "reference" / "result.json").read_text())
    items = {i["id"]: i for i in result["items"]}
    expected = yaml.safe_load((REPO / "fixtures" / "submissions" / "chase" / "reference" / "expected.yaml")
                              .read_text())["expected"]
    assert {i: items[i]["status"] for i in expected} == expected, \
        {i: items[i]["feedback"][:200] for i in expected if items[i]["status"] != expected[i]}
    assert (result["auto_score"], result["auto_max"]) == (20, 20)
    assert {items[i]["analyzer"] for i in ("spawn.turtle2", "chase.catches", "chase.short_way", "chase.follows")} \
        == {"chase_spawned", "chase_catches", "chase_short_way", "chase_follows"}

# --- the sandbox on Gradescope: hostile submissions in a simulated /autograder, run as root ---

FAULTS = REPO / "fixtures" / "faults"
HOSTILE = ("autograder_tamper", "read_rubric", "write_outside", "interface_import")
TAMPER = "grader-fault-tamper"
PLANTED = "grader-fault-interface-import"     # the marker interface_import's planted module writes


@pytest.fixture(scope="module")
def goal_setter_image(autograder: Path, tmp_path_factory) -> tuple[Path, str]:
    """A second image, for the goal-setter rubric of the fault corpus: its bundle made by the
    installed grader (``--wheel``), its ``setup.sh`` run as Gradescope runs it (as root) on the
    first image's venv (already set up: the script's steps find everything in place)."""
    tmp = tmp_path_factory.mktemp("gs-image")
    wheel = next((autograder / "source").glob("grader-*.whl"))
    bundle = tmp / "goal_setter.zip"
    sh([venv_grader(autograder), "gradescope", "--rubric", REPO / "rubrics" / "goal_setter.yaml",
        "--wheel", wheel, "-o", bundle], cwd=tmp, env=clean_env())
    root = tmp / "autograder"
    with zipfile.ZipFile(bundle) as zf:
        zf.extractall(root / "source")
        for info in zf.infolist():
            (root / "source" / info.filename).chmod(info.external_attr >> 16 or 0o644)
    (root / "grader-venv").symlink_to(autograder / "grader-venv")
    setup = sh(["bash", root / "source" / "setup.sh"], cwd=root / "source",
               env=clean_env(GRADER_AUTOGRADER_ROOT=str(root)), timeout=1200)
    return root, setup.stdout


def _files(top: Path, *, content: bool = True) -> dict[str, object]:
    """Every file under ``top`` (links not followed): its hash, or its size and mtime."""
    out: dict[str, object] = {}
    for dirpath, dirs, names in os.walk(top):
        dirs[:] = [d for d in dirs if d != "__pycache__"]      # bytecode the grader's own runs may add
        for name in names:
            f = Path(dirpath, name)
            st = f.lstat()
            out[str(f.relative_to(top))] = (hashlib.sha256(f.read_bytes()).hexdigest()
                                            if content and f.is_file() and not f.is_symlink()
                                            else (st.st_size, st.st_mtime_ns))
    return out


def _gradescope_case(image: Path, tmp: Path, fault: str) -> Path:
    """A fresh container of the image: ``source``, the venv and the build cache as the image
    has them, the fault's workspace as the upload."""
    root = tmp / fault
    root.mkdir()
    for part in ("source", "grader-venv", "grader-cache"):
        (root / part).symlink_to(image / part)
    shutil.copytree(FAULTS / fault / "src", root / "submission" / "src")
    if fault == "autograder_tamper":     # it hard-codes /autograder; this root is elsewhere: tell it
        pkg = root / "submission" / "src" / "turtle_goal" / "turtle_goal"
        (pkg / "autograder_root.py").write_text(f"ROOT = '{root}'\n")
    proc = subprocess.run([root / "source" / "run_autograder"], cwd=root, capture_output=True, text=True,
                          env=clean_env(GRADER_AUTOGRADER_ROOT=str(root)), timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return root


def test_gradescope_grades_hostile_submissions_in_the_jail(goal_setter_image: tuple[Path, str],
                                                          autograder: Path, tmp_path: Path) -> None:
    """As root, like Gradescope: submissions that read the rubric in ``source/``, rewrite
    ``results.json``, grader's result and the build cache, and plant code in the grader's venv
    (at build and at run time) get the honest submission's grade and change nothing; the honest
    submission's results.json is the one a local ``grader grade`` gives."""
    image, setup_log = goal_setter_image
    assert os.geteuid() == 0, "Gradescope runs the autograder as root; so must this test"
    for protection in ("filesystem", "unprivileged user", "network", "processes"):  # doctor, at image build
        assert re.search(rf"^\s*on\s+{protection}\s", setup_log, re.M), setup_log[-3000:]
    site = Path(sysconfig_purelib(autograder / "grader-venv"))
    before = {"source": _files(image / "source"), "cache": _files(image / "grader-cache"),
              "venv": _files(autograder / "grader-venv", content=False),
              "grader": _files(site / "grader")}
    with ThreadPoolExecutor(max_workers=2) as pool:
        roots = dict(zip(("honest", *HOSTILE),
                         pool.map(lambda f: _gradescope_case(image, tmp_path, f), ("honest", *HOSTILE))))
    after = {"source": _files(image / "source"), "cache": _files(image / "grader-cache"),
             "venv": _files(autograder / "grader-venv", content=False),
             "grader": _files(site / "grader")}
    assert before["source"] == after["source"] and before["grader"] == after["grader"]
    assert before["venv"] == after["venv"], sorted(set(after["venv"].items()) ^ set(before["venv"].items()))[:10]
    assert {k for k in after["cache"] if TAMPER in k} == set()

    honest = json.loads((roots["honest"] / "results" / "results.json").read_text())
    rubric = next((image / "source" / "rubric").rglob("goal_setter.yaml"))     # where the bundle staged it
    rubric_text = rubric.read_text()
    title = "Goal setter service, turtle controller and launch file"
    assert title in rubric_text
    for fault, root in roots.items():
        doc = json.loads((root / "results" / "results.json").read_text())
        jsonschema.validate(doc, SCHEMA)
        assert doc["score"] == 20 and TAMPER not in json.dumps(doc), fault
        assert [(t["name"], t["score"], t["status"]) for t in doc["tests"]] == \
               [(t["name"], t["score"], t["status"]) for t in honest["tests"]], fault
        graded = (root / "grader-out" / "submission" / "result.json").read_text()
        assert TAMPER not in graded and json.loads(graded)["auto_score"] == 20, fault
        sandbox = json.loads(graded)["sandbox"]
        assert {"filesystem", "unprivileged user"} <= set(sandbox["active"]), sandbox
        logs = "".join(f.read_text(errors="replace")
                       for f in (root / "grader-out" / "submission").rglob("*.log"))
        assert not re.search(r"SNOOPED /", logs) and title not in logs, fault      # nothing of source/ or the rubrics
    tamper_logs = "".join(f.read_text(errors="replace")
                          for f in (roots["autograder_tamper"] / "grader-out" / "submission").rglob("*.log"))
    root = roots["autograder_tamper"]
    # it aimed at this root's files, from inside the jail as an unprivileged user, and was refused
    assert "TAMPER run start: uid 65534" in tamper_logs, tamper_logs[-3000:]
    for target in (root / "results" / "results.json", site / "sitecustomize.py", site / f"{TAMPER}.pth",
                   site / "grader" / "__init__.py"):
        assert re.search(rf"TAMPER run \w+ {re.escape(str(target))}: \w+Error", tamper_logs), target
    assert not re.search(r"TAMPER run .*: done", tamper_logs)
    # its build planted sitecustomize.py and a .pth file in its own install tree, which grader's
    # processes (root, outside the jail) must never run
    assert re.search(r"TAMPER build write \S+/install/turtle_goal/\S+/sitecustomize.py: done", tamper_logs)
    assert not list(Path("/tmp").glob(f"{TAMPER}*"))
    # interface_import's planted module ran in its nodes, jailed, and in no grader process: the
    # scenario process imported SetGoal from the grader's own build of SetGoal.srv
    planted = "".join(f.read_text(errors="replace")
                      for f in (roots["interface_import"] / "grader-out" / "submission").rglob("*.log"))
    assert "PLANTED IMPORT uid 65534" in planted, planted[-3000:]
    assert not re.search(r"PLANTED IMPORT uid 0\b", planted) and not list(Path("/tmp").glob(f"{PLANTED}*"))

    # the honest submission graded by `grader grade` outside Gradescope: the same results
    subs = tmp_path / "local-subs"
    shutil.copytree(FAULTS / "honest", subs / "honest")
    sh([venv_grader(autograder), "grade", subs, "--rubric", rubric,
        "-o", tmp_path / "local", "--cache-dir", tmp_path / "local-cache", "--jobs", "2"], cwd=tmp_path, env=clean_env())
    local = json.loads((tmp_path / "local" / "honest" / "result.json").read_text())
    # results.json as Gradescope would get it from the local grade, field by field. What may
    # differ between two live runs of the same code: execution_time (wall time) and each test's
    # ``output`` (its feedback quotes measured values, e.g. the distance at which the turtle
    # stopped); everything that is a grade (score, status, visibility) may not.
    local_tests = [{"name": f"{i['id']}: {i['title']}", "score": float(i["points"] or 0),
                    "max_score": float(i["max_points"]), "status": "passed" if i["status"] == "pass" else "failed",
                    "item": i["id"], "kind": i["kind"], "item_status": i["status"]}
                   for i in local["items"] if i["kind"] != "manual"]
    gradescope_tests = [{"name": t["name"], "score": t["score"], "max_score": t["max_score"], "status": t["status"],
                         "item": t["extra_data"]["item"], "kind": t["extra_data"]["kind"],
                         "item_status": t["extra_data"]["status"]} for t in honest["tests"]]
    assert gradescope_tests == local_tests
    assert honest["score"] == local["auto_score"] and honest["extra_data"]["auto_max"] == local["auto_max"]
    assert honest["output"].splitlines()[0] == f"{title}: {local['auto_score']:g}/{local['auto_max']:g} points from the autograder."


def sysconfig_purelib(venv: Path) -> str:
    return subprocess.run([venv / "bin" / "python", "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
