"""Builders of LMS downloads, made by the tests from the fixture workspaces (nothing large is
committed): a Canvas "Download Submissions" zip of zips, a Gradescope "Export Submissions"
folder, a folder of GitHub Classroom clones with commits at chosen times.
Imported as ``intakehelpers`` (tests/ is not a package)."""

from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from datetime import datetime
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
FIRST = REPO / "fixtures" / "submissions" / "first_nodes"
LAB3 = REPO / "fixtures" / "submissions" / "enee467_lab3"
FIRST_RUBRIC = REPO / "rubrics" / "first_nodes.yaml"
LAB3_RUBRIC = REPO / "rubrics" / "enee467_lab3.yaml"
MODULES = FIRST / "reference" / "src" / "my_first_package" / "my_first_package"


def zip_tree(folder: Path, dest: Path, when: datetime) -> Path:
    """``folder``'s files in a zip, every member stamped ``when`` (a zip keeps local times)."""
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(p for p in folder.rglob("*") if p.is_file()):
            info = zipfile.ZipInfo(path.relative_to(folder.parent).as_posix(), when.timetuple()[:6])
            zf.writestr(info, path.read_bytes())
    return dest


def canvas_zip(dest: Path, files: dict[str, bytes]) -> Path:
    """A Canvas download: one member per file, named the Canvas way."""
    with zipfile.ZipFile(dest, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return dest


def git(repo: Path, *args: str, when: str | None = None) -> str:
    env = {**os.environ, "GIT_AUTHOR_NAME": "Student", "GIT_AUTHOR_EMAIL": "s@example.edu",
           "GIT_COMMITTER_NAME": "Student", "GIT_COMMITTER_EMAIL": "s@example.edu",
           "GIT_CONFIG_NOSYSTEM": "1", "GIT_CONFIG_GLOBAL": os.devnull}
    if when:
        env.update(GIT_AUTHOR_DATE=when, GIT_COMMITTER_DATE=when)
    return subprocess.run(["git", *args], cwd=repo, env=env, check=True, capture_output=True, text=True).stdout


def clone(source: Path, dest: Path, commits: list[str]) -> Path:
    """A repository holding ``source``'s files, committed at each of ``commits`` (ISO times)."""
    shutil.copytree(source, dest)
    git(dest, "init", "-q", "-b", "main")
    for i, when in enumerate(commits):
        (dest / "NOTES.md").write_text(f"commit {i}\n")
        git(dest, "add", "-A")
        git(dest, "commit", "-q", "-m", f"work {i}", when=when)
    return dest


def gradescope_export(root: Path, metadata: str, folders: dict[str, Path | dict[str, bytes]]) -> Path:
    """An export folder: ``submission_metadata.yml`` and ``submission_<id>/`` folders (a copy
    of a workspace, or the files given)."""
    root.mkdir(parents=True)
    (root / "submission_metadata.yml").write_text(metadata)
    for name, content in folders.items():
        if isinstance(content, Path):
            shutil.copytree(content, root / name)
        else:
            (root / name).mkdir()
            for file, data in content.items():
                (root / name / file).write_bytes(data)
    return root
