"""Who handed in what: each arrival matched to a roster row, by the strongest id the LMS gives
(Canvas user id = the gradebook's ``ID``; Gradescope e-mail or SID; a GitHub login = the
roster's ``submission``/``github_username``), then by name when that is unique. Each match says
how it was made; a submission that matches nobody is still graded (under the LMS's name) and
listed, and so is a roster row without a submission.

Then each submission gets its id (the folder under OUT, the ``submission`` cell of grades.csv):
the roster's ``submission`` cell when there is one, else its login (``SIS Login ID``), else the
LMS's own readable name (``doejane``, ``alice``, an e-mail's user part); on a clash, the LMS id
is appended.
"""

from __future__ import annotations

import re
from typing import Callable

from grader.intake.model import Arrival
from grader.scores.roster import Roster, Student

_NOT_ID = re.compile(r"[^A-Za-z0-9._@+-]+")


def canvas_name(name: str) -> str:
    """A roster name as Canvas writes it into download file names: ``Doe, Jane`` -> ``doejane``."""
    return re.sub(r"[^\w]", "", re.sub(r"_(\d+)_", r"\1", name)).lower()


def _fold(text: str) -> str:
    return text.strip().casefold()


def _rows(roster: Roster, field: str, value: str, norm: Callable[[str], str] = _fold) -> list[Student]:
    if not value:
        return []
    want = norm(value)
    return [s for s in roster.students if s.get(field) and norm(s.get(field)) == want]


def _find(arrival: Arrival, roster: Roster) -> tuple[list[Student], str]:
    """Candidate rows and how they were found (the first rule that finds any wins)."""
    lms = arrival.lms
    rules: list[tuple[str, str, str, Callable[[str], str]]] = []
    if arrival.source == "canvas":
        rules += [("id", str(lms.get("canvas_user_id") or ""), "Canvas user id {v} = roster ID", _fold)]
    if arrival.source == "gradescope":
        rules += [("email", str(lms.get("email") or ""), "e-mail {v} = roster Email", _fold),
                  ("sid", str(lms.get("sid") or ""), "SID {v} = roster SID", _fold)]
    if arrival.source == "classroom":
        rules += [("submission", arrival.key, "GitHub login {v} = roster submission", _fold)]
    rules += [("submission", arrival.key, "{v} = roster submission", _fold),
              ("sis_login_id", arrival.key, "{v} = roster SIS Login ID", _fold)]
    if arrival.source == "canvas":
        rules += [("name", arrival.key, "Canvas name {v} = roster Student", canvas_name)]
    elif arrival.source == "gradescope":
        rules += [("name", str(lms.get("name") or ""), "name {v} = roster name", _fold)]
    for field, value, how, norm in rules:
        if field not in roster.columns:
            continue
        found = _rows(roster, field, value, norm)
        if found:
            return found, how.format(v=value)
    return [], ""


def _not_found(arrival: Arrival, roster: Roster) -> str:
    lms = arrival.lms
    tried = []
    if arrival.source == "canvas" and lms.get("canvas_user_id"):
        tried.append(f"ID {lms['canvas_user_id']}")
    if arrival.source == "gradescope":
        tried += [f"e-mail {lms['email']}" if lms.get("email") else "", f"SID {lms['sid']}" if lms.get("sid") else ""]
    tried.append(f"name {arrival.key}" if arrival.source in ("canvas",) else f"submission {arrival.key}")
    return "not on the roster (no row with " + ", ".join(t for t in tried if t) + ")"


def match_roster(arrivals: list[Arrival], roster: Roster | None) -> list[Student]:
    """Set each arrival's ``student`` and ``matched_by``; returns the roster rows nobody matched."""
    if roster is None:
        for a in arrivals:
            a.matched_by = "no roster given"
        return []
    taken: dict[int, Arrival] = {}
    for a in arrivals:
        found, how = _find(a, roster)
        if not found:
            a.matched_by = _not_found(a, roster)
        elif len(found) > 1:
            a.matched_by = (f"{how}, but on {len(found)} rows (lines {', '.join(str(s.line) for s in found)}): "
                            "not matched; make the roster's rows unique")
        elif found[0].line in taken and not _same_submission(taken[found[0].line], a):
            a.matched_by = (f"{how}, but roster line {found[0].line} is already matched to "
                            f"{taken[found[0].line].original[0]}: not matched")
        else:
            a.student, a.matched_by = found[0], how
            taken[found[0].line] = a
    return [s for s in roster.students if s.line not in taken]


def _same_submission(a: Arrival, b: Arrival) -> bool:
    return a.source == b.source and a.lms_id == b.lms_id and a.original == b.original


def safe_id(text: str) -> str:
    return _NOT_ID.sub("_", text).strip("._-")[:100] or "submission"


def assign_ids(arrivals: list[Arrival]) -> None:
    """Each arrival's submission id (see the module docstring), unique in the batch."""
    used: set[str] = set()
    for a in arrivals:
        base = a.key
        if a.student is not None:
            base = a.student.submission or a.student.get("sis_login_id") or base
        sid = safe_id(base)
        if sid in used:
            sid = safe_id(f"{base}-{a.lms_id}")
        n = 2
        while sid in used:
            sid, n = safe_id(f"{base}-{a.lms_id}-{n}"), n + 1
        used.add(sid)
        a.id = sid
