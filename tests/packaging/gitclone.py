"""A real ``git clone`` of the tree under test, for the packaging tests.

The commit cloned is ``git stash create``'s snapshot of the working tree (tracked files with
their uncommitted edits, links as git stores them; untracked files left out, as a clone has
them), or HEAD when nothing is edited. Copying files instead would hide what a clone brings
along: a committed link to ``/`` made every wheel build from a clone walk the whole machine.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BRANCH = "under-test"


def _git(*args: str, cwd: Path = REPO) -> str:
    return subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True,
                          check=True).stdout.strip()


def snapshot() -> str:
    """The commit of the working tree as it is (HEAD when clean)."""
    return _git("stash", "create") or _git("rev-parse", "HEAD")


def git_clone(dest: Path) -> Path:
    """Clone this repository into ``dest`` with git and check out the tree under test on branch
    ``under-test`` (so ``git+file://DEST@under-test`` names it too)."""
    commit = snapshot()
    subprocess.run(["git", "clone", "-q", "--no-checkout", str(REPO), str(dest)], check=True)
    # the snapshot is no branch of REPO: fetch it by id from the local repository
    _git("-c", "uploadpack.allowAnySHA1InWant=true", "fetch", "-q", str(REPO), commit, cwd=dest)
    _git("checkout", "-q", "-b", BRANCH, commit, cwd=dest)
    return dest
