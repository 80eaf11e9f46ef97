"""Submission times the files themselves carry: the last commit of a clone, the newest file
inside an archive. Both are set by the student's machine (a commit date or a file time can be
anything), which is why every result names its source; an LMS's own record is better when
there is one.
"""

from __future__ import annotations

import os
import subprocess
import tarfile
import zipfile
from datetime import datetime, timezone
from pathlib import Path

from grader.intake.late import SubmissionTime

GIT_SOURCE = "the last commit's date (git committer date, set by the student's machine)"
ARCHIVE_SOURCE = "the newest file time inside {name} (set by the student's machine)"
NO_TIME = "no submission time (a plain folder: neither an LMS record, a git history nor an archive)"


def last_commit_time(repo: Path) -> SubmissionTime | None:
    """The committer date of HEAD in ``repo`` (a clone), or None when it is not one.

    git reads the student's own ``.git/config``: nothing that runs a program is involved in
    ``git log`` (no hooks, pager, fsmonitor, signature check or external diff; they are switched
    off anyway), the global and system configuration are not read, and only a ``.git`` folder of
    the clone itself is read (not a link or a ``gitdir:`` file pointing elsewhere)."""
    dot_git = repo / ".git"
    if dot_git.is_symlink() or not dot_git.is_dir():
        return None            # not a clone (a .git file or link would point at another repository)
    env = {k: v for k, v in os.environ.items() if not k.startswith("GIT_")}
    env.update(GIT_CONFIG_NOSYSTEM="1", GIT_CONFIG_GLOBAL=os.devnull, GIT_TERMINAL_PROMPT="0",
               GIT_OPTIONAL_LOCKS="0", GIT_NO_REPLACE_OBJECTS="1", GIT_CEILING_DIRECTORIES=str(repo.resolve().parent))
    try:
        proc = subprocess.run(
            ["git", "-c", "core.fsmonitor=false", "-c", "core.hooksPath=" + os.devnull,
             "-c", f"safe.directory={repo.resolve()}", "--no-pager", "-C", str(repo),
             "log", "-1", "--no-show-signature", "--format=%cI", "HEAD"],
            capture_output=True, text=True, timeout=30, env=env, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired):
        return None
    text = proc.stdout.strip()
    if proc.returncode != 0 or not text:
        return None
    try:
        return SubmissionTime(datetime.fromisoformat(text), GIT_SOURCE)
    except ValueError:
        return None


def archive_time(archive: Path, shown: str | None = None) -> SubmissionTime | None:
    """The newest modification time of a file inside a .zip (local time, no zone: read in the
    due date's zone) or a tar archive (UTC); None when unreadable or empty."""
    name = shown or archive.name
    try:
        if archive.name.lower().endswith(".zip"):
            with zipfile.ZipFile(archive) as zf:
                stamps = [datetime(*info.date_time) for info in zf.infolist() if not info.is_dir()]
        else:
            with tarfile.open(archive) as tf:
                stamps = [datetime.fromtimestamp(m.mtime, timezone.utc) for m in tf.getmembers() if m.isfile()]
    except (OSError, zipfile.BadZipFile, tarfile.TarError, EOFError, ValueError):
        return None
    if not stamps:
        return None
    return SubmissionTime(max(stamps), ARCHIVE_SOURCE.format(name=name))


def folder_time(folder: Path) -> SubmissionTime | None:
    """A workspace folder's time: its last commit when it is a clone, else none."""
    return last_commit_time(folder)
