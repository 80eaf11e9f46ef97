"""The course roster: which student handed in which submission.

Any CSV works (a Canvas gradebook export, the registrar's list, a sheet of GitHub user names);
``--map FIELD=COLUMN`` says which column holds what. Without a mapping, columns named like
Canvas's export (``Student``, ``ID``, ``SIS User ID``, ``SIS Login ID``, ``Section``) and
``submission``, ``Email``, ``SID`` are used when present, so a Canvas gradebook export with one
added ``submission`` column needs no ``--map`` at all. Canvas's "Points Possible" and "Manual
Posting" rows are skipped.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from typing import Iterable, Mapping

from grader.scores.csvfile import read_table
from grader.scores.errors import ScoresError

#: field -> what it is
FIELDS = {
    "submission": "the submission id (folder name under OUT), e.g. a GitHub user name",
    "name": "the student's name (Canvas: Student)",
    "id": "the Canvas user id (Canvas: ID)",
    "sis_user_id": "the SIS user id (Canvas: SIS User ID)",
    "sis_login_id": "the login (Canvas: SIS Login ID)",
    "section": "the section (Canvas: Section)",
    "email": "the e-mail (Gradescope matches on it)",
    "sid": "the student id number (Gradescope: SID)",
    "late_days": "late days the student has left (a late policy's late_days budget)",
}
DEFAULT_COLUMNS = {
    "submission": ("submission", "github_username"), "name": ("Student", "Name", "Full Name"), "id": ("ID",),
    "sis_user_id": ("SIS User ID",), "sis_login_id": ("SIS Login ID",),
    "section": ("Section", "Sections"), "email": ("Email", "E-mail"), "sid": ("SID",),
    "late_days": ("late_days", "Late days left"),
}
_NOT_A_STUDENT = re.compile(r"^\s*(Muted|Manual Posting.*)?\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class Student:
    """One roster row: the mapped fields (field -> cell, empty when blank or unmapped)."""

    line: int
    fields: Mapping[str, str]

    def get(self, name: str) -> str:
        return self.fields.get(name, "")

    @property
    def submission(self) -> str:
        return self.get("submission")

    def describe(self) -> str:
        who = self.get("name") or self.get("email") or self.get("sis_login_id") or self.get("id") or "?"
        sub = f" ({self.submission})" if self.submission else " (no submission id)"
        return f"line {self.line}: {who}{sub}"


@dataclass(frozen=True)
class Roster:
    name: str
    columns: Mapping[str, str]        # field -> roster column used
    students: tuple[Student, ...]

    def by_submission(self) -> dict[str, Student]:
        return {s.submission: s for s in self.students if s.submission}


def parse_mapping(specs: Iterable[str]) -> dict[str, str]:
    """``["submission=github,name=Student", "section=Lab"]`` -> {field: column}."""
    mapping: dict[str, str] = {}
    problems = []
    for spec in specs:
        for part in (p for p in spec.split(",") if p.strip()):
            field, sep, column = part.partition("=")
            field, column = field.strip().lower(), column.strip()
            if not sep or not column:
                problems.append(f'"{part.strip()}" is not FIELD=COLUMN (e.g. submission=github_username)')
            elif field not in FIELDS:
                problems.append(f'unknown field "{field}"; the fields are {", ".join(FIELDS)}')
            elif field in mapping:
                problems.append(f'field "{field}" is mapped twice')
            else:
                mapping[field] = column
    if problems:
        raise ScoresError("--map", problems)
    return mapping


def _find(header: list[str], column: str) -> int | None:
    exact = [j for j, h in enumerate(header) if h == column]
    loose = [j for j, h in enumerate(header) if h.casefold() == column.casefold()]
    return (exact or loose or [None])[0]  # type: ignore[list-item]  # (None: no such column)


def read_roster(path: str | os.PathLike[str], mapping: Mapping[str, str] | None = None, *,
                require_submission: bool = True) -> Roster:
    """Read the roster with ``mapping`` (field -> column; defaults as in the module docstring).
    Raises ScoresError for a missing column or a submission id on two rows. Without
    ``require_submission`` (``grader grade --roster``: submissions are matched by the LMS's ids,
    names or e-mails), a roster needs no submission column."""
    mapping = dict(mapping or {})
    key = mapping.get("submission", "submission")
    keys = [key] if "submission" in mapping else list(DEFAULT_COLUMNS["submission"])
    identity = [c for f in ("name", "id", "email", "sid", "sis_login_id") for c in DEFAULT_COLUMNS[f]]
    table = read_table(path, has_key=lambda header: any(_find(header, k) is not None for k in keys)
                       or (not require_submission and any(_find(header, c) is not None for c in identity)))
    shown = ", ".join(f'"{h}"' for h in table.header if h)
    problems: list[str] = []
    index: dict[str, int] = {}
    for field in FIELDS:
        if field in mapping:
            j = _find(table.header, mapping[field])
            if j is None:
                problems.append(f'--map {field}={mapping[field]}: the roster has no column '
                                f'"{mapping[field]}" (its columns: {shown})')
                continue
            index[field] = j
        else:
            j = next((j for c in DEFAULT_COLUMNS[field] if (j := _find(table.header, c)) is not None), None)
            if j is not None:
                index[field] = j
    if "submission" not in index and "submission" not in mapping and require_submission:
        problems.append(f"no column with the submission ids: name it with --map submission=COLUMN "
                        f"(the roster's columns: {shown})")
    if problems:
        raise ScoresError(table.name, problems, changed_nothing=False)
    students: list[Student] = []
    first: dict[str, int] = {}
    for line, cells in table.rows:
        if cells and "Points Possible" in cells[0]:
            continue                                   # Canvas export: the row of maximum points
        if all(_NOT_A_STUDENT.match(c) for c in cells):
            continue
        fields = {f: (cells[j] if j < len(cells) else "") for f, j in index.items()}
        student = Student(line, fields)
        if student.submission in first:
            problems.append(f'line {line}: submission id "{student.submission}" is also on line '
                            f"{first[student.submission]}")
            continue
        if student.submission:
            first[student.submission] = line
        students.append(student)
    if problems:
        raise ScoresError(table.name, problems, changed_nothing=False)
    return Roster(table.name, {f: table.header[j] for f, j in index.items()}, tuple(students))
