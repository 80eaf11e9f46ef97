"""No tracked file is a link that leaves the repository (``.ci/check_links.py``, which ``.ci/run``
runs before ``make test``): a committed link to ``/`` made every wheel build from a clone walk
the whole machine."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CHECK = REPO / ".ci" / "check_links.py"


def _check(repo: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(CHECK), str(repo)], capture_output=True, text=True, timeout=60)


def test_this_repository_has_no_link_leaving_it() -> None:
    done = _check(REPO)
    assert done.returncode == 0, done.stderr


def test_links_leaving_a_repository_are_refused(tmp_path: Path) -> None:
    repo = tmp_path / "repo"
    (repo / "a" / "b").mkdir(parents=True)
    (repo / "a" / "b" / "file.txt").write_text("x")
    (repo / "a" / "inside").symlink_to("b/file.txt")          # stays in: fine
    (repo / "a" / "up_ok").symlink_to("../a/b")               # up and back in: fine
    (repo / "a" / "b" / "rootdir").symlink_to("/")
    (repo / "a" / "escape").symlink_to("../../elsewhere")
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    subprocess.run(["git", "-C", str(repo), "add", "-A"], check=True)
    done = _check(repo)
    assert done.returncode == 1
    flagged = sorted(line.split(" -> ")[0] for line in done.stderr.splitlines())
    assert flagged == ["a/b/rootdir", "a/escape"], done.stderr
