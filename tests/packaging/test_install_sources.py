"""Installing grader from the sources a user has: a `git clone`, a `git+file://` URL, pipx.

* the wheel (``pip wheel --no-deps .``) and the sdist (``python -m build --sdist``) build from a
  real clone, and the wheel from ``git+file://``, each well inside its time limit (a committed
  link to ``/`` once made each of them walk the whole machine for over 13 minutes); the sdist and
  the wheel hold no link and carry the labs;
* real pipx (from PyPI, in a venv of its own) installs grader from ``git+file://``, and that
  installed grader runs ``grader setup`` and self-checks a copy of the Lab 3 reference, as the
  README tells students.

Measured (2-core machine, load 9-13 from other work): ``pip wheel --no-deps .`` on a clean
clone 42-54 s wall, 8 s CPU (before the link was removed: still running after 120 s, and 13
minutes in a longer try). The limits below are ~3x that, to tell a hang from a slow machine.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tarfile
import time
import zipfile
from pathlib import Path

import pytest
from gitclone import BRANCH, git_clone

REPO = Path(__file__).resolve().parents[2]
LAB3_REFERENCE = REPO / "fixtures" / "submissions" / "enee467_lab3" / "reference"
BUILD_LIMIT_S = 180

pytestmark = [pytest.mark.slow]


def clean_env(**extra: str) -> dict[str, str]:
    """A user's environment: no venv of the repository, no PYTHONPATH."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "GRADER_VENV", "PYTEST_CURRENT_TEST")}
    env.update(extra)
    return env


def run(cmd: list, *, cwd: Path, env: dict[str, str] | None = None, timeout: float = 900) -> tuple[str, float]:
    """Run ``cmd``; its stdout and wall time. A time-out is a failure that says what hung."""
    t0 = time.monotonic()
    try:
        proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env or clean_env(), capture_output=True,
                              text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{' '.join(map(str, cmd))} still running after {timeout:.0f} s")
    assert proc.returncode == 0, (f"{' '.join(map(str, cmd))} exited {proc.returncode}\n"
                                  f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc.stdout, time.monotonic() - t0


@pytest.fixture(scope="module")
def tools(tmp_path_factory) -> Path:
    """A venv with pipx and build from PyPI (the tools a user runs, not the repository's)."""
    if shutil.which("python3.11") is None or not (REPO / ".git").exists():
        pytest.skip("needs python3.11 and a git checkout")
    venv = tmp_path_factory.mktemp("tools") / "venv"
    run(["python3.11", "-m", "venv", venv], cwd=venv.parent)
    run([venv / "bin" / "python", "-m", "pip", "install", "-q", "--disable-pip-version-check", "pipx", "build"],
        cwd=venv.parent)
    return venv


@pytest.fixture(scope="module")
def clone(tmp_path_factory) -> Path:
    return git_clone(tmp_path_factory.mktemp("src") / "grader")


def _no_links(names_and_kinds: list[tuple[str, bool]]) -> list[str]:
    return [name for name, is_link in names_and_kinds if is_link]


def test_wheel_and_sdist_build_from_a_git_clone(clone: Path, tools: Path, tmp_path: Path) -> None:
    _, wheel_s = run(["python3.11", "-m", "pip", "wheel", "--no-deps", "-q", "--disable-pip-version-check",
                      "-w", tmp_path / "wheel", "."], cwd=clone, timeout=BUILD_LIMIT_S)
    _, sdist_s = run([tools / "bin" / "python", "-m", "build", "--sdist", "-o", tmp_path / "sdist", "."],
                     cwd=clone, timeout=BUILD_LIMIT_S)
    print(f"from a clone: wheel {wheel_s:.1f} s, sdist {sdist_s:.1f} s")
    wheel = next((tmp_path / "wheel").glob("grader-*.whl"))
    with zipfile.ZipFile(wheel) as zf:
        names = zf.namelist()
        assert _no_links([(i.filename, (i.external_attr >> 16) & 0o170000 == 0o120000) for i in zf.infolist()]) == []
    assert "grader/_data/rubrics/enee467_lab3.yaml" in names and "grader/cli.py" in names
    sdist = next((tmp_path / "sdist").glob("grader-*.tar.gz"))
    with tarfile.open(sdist) as tf:
        members = tf.getmembers()
    assert _no_links([(m.name, m.issym() or m.islnk()) for m in members]) == []
    assert any(m.name.endswith("rubrics/enee467_lab3.yaml") for m in members)
    assert not any("symlink_folder" in m.name and m.name.endswith(("rootdir", "leak")) for m in members)


def test_wheel_builds_from_a_git_file_url(clone: Path, tmp_path: Path) -> None:
    _, seconds = run(["python3.11", "-m", "pip", "wheel", "--no-deps", "-q", "--disable-pip-version-check",
                      "-w", tmp_path, f"git+file://{clone}@{BRANCH}"], cwd=tmp_path, timeout=BUILD_LIMIT_S)
    print(f"from git+file://: wheel {seconds:.1f} s")
    assert list(tmp_path.glob("grader-*.whl"))


@pytest.mark.ros
@pytest.mark.heavy
@pytest.mark.timeout(1800)
def test_pipx_install_from_git_then_setup_and_self_check(clone: Path, tools: Path, tmp_path: Path) -> None:
    """`pipx install git+file://...`, `grader setup`, `grader check --lab enee467-lab3`: a student's
    first hour, with real pipx, outside the repository."""
    home = tmp_path / "pipx"
    env = clean_env(PIPX_HOME=str(home), PIPX_BIN_DIR=str(tmp_path / "bin"), PIPX_MAN_DIR=str(tmp_path / "man"))
    run([tools / "bin" / "pipx", "install", "--python", "python3.11", f"git+file://{clone}@{BRANCH}"],
        cwd=tmp_path, env=env, timeout=600)
    grader = tmp_path / "bin" / "grader"
    where, _ = run([home / "venvs" / "grader" / "bin" / "python", "-c", "import grader; print(grader.__file__)"],
                   cwd=tmp_path, env=env)
    assert Path(where.strip()).is_relative_to(home), where          # the installed copy, not a checkout
    first, _ = run([grader, "setup"], cwd=tmp_path, env=env, timeout=1200)
    assert "ready (wheels ROS 2" in first
    again, _ = run([grader, "setup"], cwd=tmp_path, env=env)
    assert "installing" not in again and "building" not in again     # idempotent
    ws = tmp_path / "ws"
    shutil.copytree(LAB3_REFERENCE / "src", ws / "src")
    check, _ = run([grader, "check", "--lab", "enee467-lab3", "--cache-dir", tmp_path / "cache"], cwd=ws, env=env)
    assert "All public checks pass." in check and "50/50 points" in check, check[-3000:]
