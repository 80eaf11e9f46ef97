"""``read_intake``: whatever ``grader grade`` is pointed at, as a list of submissions with ids,
students and times, plus the one table that says what matched how and what did not.

What it reads, recognised by its shape (``kind`` forces one):

* a Canvas "Download Submissions" zip or its folder (files named ``name[_LATE]_uid_fid_file``);
* a Gradescope "Export Submissions" folder or zip (``submission_metadata.yml``);
* a folder of GitHub Classroom clones (``--classroom-prefix lab3-``);
* a folder with one workspace or archive per student, or one submission (as before).

Submissions that are only loose ``.py`` files are wrapped into the rubric's package
(``loose_files``) or refused with the reason (grader.intake.loose). Files the download needs
unpacked go to ``work`` (``OUT/.intake``).
"""

from __future__ import annotations

import csv
import io
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from grader.errors import GraderError
from grader.intake.model import SOURCES, Arrival
from grader.scores.roster import Roster, Student

KINDS = ("auto", "canvas", "gradescope", "classroom", "folder")
WORK_DIR = ".intake"


@dataclass
class IntakeBatch:
    kind: str
    root: Path
    arrivals: list[Arrival]
    roster: Roster | None = None
    no_submission: list[Student] = field(default_factory=list)   # roster rows nobody handed in for
    skipped: list[str] = field(default_factory=list)             # entries that are not submissions

    @property
    def gradable(self) -> list[Arrival]:
        return [a for a in self.arrivals if a.gradable]

    @property
    def refused(self) -> list[Arrival]:
        return [a for a in self.arrivals if not a.gradable]

    def rows(self) -> list[list[str]]:
        """The table's rows: submission, from, student, matched by, submitted, notes."""
        out = []
        for a in self.arrivals:
            who = "—" if a.student is None else (a.student.get("name") or a.student.get("email")
                                                 or a.student.get("sis_login_id") or a.student.submission)
            if a.student is not None:
                who += f" (line {a.student.line})"
            when = _when(a)
            what = f"REFUSED: {a.refused}" if a.refused else "; ".join(a.notes)
            out.append([a.id if a.gradable else "—", ", ".join(a.original), who, a.matched_by, when, what])
        return out

    def table(self) -> str:
        """The printed table (see docs/lms.md, "Submissions from an LMS")."""
        n = len(self.arrivals)
        roster = (f"roster {self.roster.name}: {len(self.roster.students)} student(s)" if self.roster
                  else "no roster (--roster): ids from the LMS names")
        head = (f"{SOURCES.get(self.kind, self.kind)} {self.root.name}: {n} submission(s), "
                f"{len(self.gradable)} to grade; {roster}")
        header = ["submission", "from", "student", "matched by", "submitted", "notes"]
        rows = self.rows()
        widths = [min(36, max(len(r[j]) for r in [header, *rows])) for j in range(5)]
        lines = [head, "  " + "  ".join(h.ljust(w) for h, w in zip(header, widths)) + "  notes"]
        for r in rows:
            cells = [c if len(c) <= w else c[: w - 1] + "…" for c, w in zip(r, widths)]
            lines.append(("  " + "  ".join(c.ljust(w) for c, w in zip(cells, widths)) + "  " + r[5]).rstrip())
        lines += [f"  roster {_who(s)}: no submission" for s in self.no_submission]
        lines += [f"  skipped {line}" for line in self.skipped]
        return "\n".join(lines)

    def csv_text(self) -> str:
        """The same table in full, for ``OUT/intake.csv``."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["submission", "from", "student", "matched_by", "submitted", "notes"])
        writer.writerows(self.rows())
        writer.writerows([["", "", _who(s), "no submission", "", ""] for s in self.no_submission])
        writer.writerows([["", line, "", "skipped", "", ""] for line in self.skipped])
        return buf.getvalue()


def _who(s: Student) -> str:
    return f"line {s.line}: " + (s.get("name") or s.get("email") or s.get("sis_login_id") or s.get("id") or "?")


def _when(a: Arrival) -> str:
    t = a.time
    if t is None:
        return "—"
    mark = "" if t.lms_late is None else ("LATE (Canvas)" if t.lms_late else "on time (Canvas)")
    at = t.at.strftime("%Y-%m-%d %H:%M") + ("" if t.at.tzinfo is None else t.at.strftime(" %z")) if t.at else ""
    return " ".join(x for x in (mark, at) if x) or "—"


def detect(root: Path, classroom_prefix: str | None) -> str:
    """Which kind of input ``root`` is (see the module docstring)."""
    from grader.intake.canvas import looks_like_canvas, zip_is_canvas  # noqa: PLC0415 - at the head it would close a circle: intake.batch -> intake -> intake.batch
    from grader.intake.gradescope import find_metadata, zip_is_gradescope  # noqa: PLC0415 - at the head it would close a circle: intake.batch -> intake -> intake.batch

    if classroom_prefix:
        return "classroom"
    if root.is_file():
        if zip_is_gradescope(root):
            return "gradescope"
        return "canvas" if zip_is_canvas(root) else "folder"
    if find_metadata(root) is not None:
        return "gradescope"
    if (root / "src").is_dir() or (root / "package.xml").exists():
        return "folder"
    return "canvas" if looks_like_canvas([p.name for p in root.iterdir()]) else "folder"


def read_intake(root: Path, rubric, *, work: Path, roster: Roster | None = None,
                classroom_prefix: str | None = None, kind: str = "auto") -> IntakeBatch:
    """Every submission in ``root`` with its id, roster row, time and what to grade."""
    from grader.intake.canvas import read_canvas  # noqa: PLC0415 - at the head it would close a circle: intake.batch -> intake -> intake.batch
    from grader.intake.folders import read_classroom, read_folder  # noqa: PLC0415 - at the head it would close a circle: intake.batch -> intake -> intake.batch
    from grader.intake.gradescope import read_gradescope  # noqa: PLC0415 - at the head it would close a circle: intake.batch -> intake -> intake.batch
    from grader.intake.loose import check_loose  # noqa: PLC0415 - at the head it would close a circle: intake.batch -> intake -> intake.batch
    from grader.intake.match import assign_ids, match_roster  # noqa: PLC0415 - at the head it would close a circle: intake.batch -> intake -> intake.batch

    root = Path(root)
    if not root.exists():
        raise GraderError(f"{root} does not exist.")
    if kind not in KINDS:
        raise GraderError(f"unknown intake {kind!r}; one of {', '.join(KINDS)}")
    if kind == "classroom" and not classroom_prefix:
        raise GraderError("GitHub Classroom clones need --classroom-prefix (e.g. lab3- for lab3-alice)")
    kind = detect(root, classroom_prefix) if kind == "auto" else kind
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    if kind == "canvas":
        arrivals, skipped = read_canvas(root, work / "canvas")
    elif kind == "gradescope":
        arrivals, skipped = read_gradescope(root, work / "gradescope")
    elif kind == "classroom":
        arrivals, skipped = read_classroom(root, classroom_prefix or "")
    else:
        arrivals, skipped = read_folder(root)
        kind = arrivals[0].source if len(arrivals) == 1 and arrivals[0].source == "single" else "folder"
    if not arrivals:
        raise GraderError(f"{root} holds no submissions ({SOURCES[kind]}): "
                          + ("; ".join(skipped[:3]) if skipped else "it is empty"))
    no_submission = match_roster(arrivals, roster)
    assign_ids(arrivals)
    for arrival in arrivals:
        check_loose(arrival, rubric, work)
    return IntakeBatch(kind, root, arrivals, roster, no_submission, skipped)
