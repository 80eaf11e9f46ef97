"""Submissions on disk without an LMS record: a folder of GitHub Classroom clones
(``lab3-alice/``: the assignment's prefix, then the student's GitHub login), a folder of
workspaces or archives (one per student, named for the student), or one submission.

Times: a clone's last commit, an archive's newest file; a plain folder has none.
"""

from __future__ import annotations

from pathlib import Path

from grader.intake.model import Arrival
from grader.intake.times import NO_TIME, archive_time, folder_time
from grader.workspace.source import discover_submissions, is_archive, submission_id


def _submission_id(path: Path) -> str:
    return submission_id(path)


def _time(path: Path):
    return archive_time(path) if is_archive(path) else folder_time(path)


def read_classroom(root: Path, prefix: str) -> tuple[list[Arrival], list[str]]:
    """``root/<prefix><login>/`` clones; what does not start with the prefix is listed, not graded."""
    arrivals: list[Arrival] = []
    notes: list[str] = []
    for entry in sorted((p for p in root.iterdir() if not p.name.startswith(".")), key=lambda p: p.name.casefold()):
        if not entry.name.startswith(prefix) or entry.name == prefix:
            notes.append(f"{entry.name}: does not start with the prefix {prefix!r} (--classroom-prefix); "
                         "not graded")
            continue
        if not entry.is_dir() and not is_archive(entry):
            notes.append(f"{entry.name}: a file, not a clone; not graded")
            continue
        login = entry.name[len(prefix):]
        for suffix in (".zip", ".tar.gz", ".tgz"):
            login = login.removesuffix(suffix)
        arrival = Arrival("classroom", login, entry.name, [entry.name], path=entry,
                          lms={"github_login": login, "repository": entry.name}, time=_time(entry))
        if arrival.time is None:
            arrival.notes.append(f"no submission time: {NO_TIME}")
        arrivals.append(arrival)
    return arrivals, notes


def read_folder(root: Path) -> tuple[list[Arrival], list[str]]:
    """One folder or archive per student (named for the student). A file at the top that is not
    an archive is listed, never taken for a submission."""
    paths = discover_submissions(root)
    if paths == [root]:
        arrival = Arrival("single", _submission_id(root), root.name, [root.name], path=root, time=_time(root))
        return [arrival], []
    arrivals = [Arrival("folder", _submission_id(p), p.name, [p.name], path=p, time=_time(p)) for p in paths]
    notes = [f"{p.name}: a file, not a submission folder or archive; not graded (put each student's files "
             "in a folder named for the student)"
             for p in sorted(root.iterdir()) if p.is_file() and not is_archive(p) and not p.name.startswith(".")]
    return arrivals, notes
