"""Canvas's "Download Submissions": a zip (or the folder it unpacks to) with one file per
uploaded attachment, named by Canvas as (canvas-lms ``ContentZipper``)::

    <name>[_LATE]_<user id>_<attachment id>_<file name as uploaded>
    doejane_LATE_12345_67890_lab3_ws.zip

``<name>`` is the student's sortable name ("Doe, Jane") lower-cased with everything but
letters, digits and ``_`` removed; ``LATE`` is Canvas's own verdict against the due date it
knows (with each student's extensions); an anonymous assignment has ``anon_<id>`` instead of
name and user id. A text entry or a URL is ``<name>[_LATE]_<user id>_text.html`` /
``_link.html``. A file uploaded twice under the same name becomes ``lab3_ws-1.zip``. The
download holds each student's latest submission only, so all files of one user id are one
submission: one archive is graded as it is, several files are put together in one folder.
"""

from __future__ import annotations

import re
import shutil
import zipfile
from dataclasses import dataclass, replace
from pathlib import Path

from grader.errors import GraderError
from grader.intake.late import SubmissionTime
from grader.intake.model import Arrival
from grader.intake.times import archive_time
from grader.workspace.source import MAX_UNPACKED_BYTES, extract_archive, is_archive

_FILE = re.compile(r"^(?P<name>[^\W_][\w]*?)(?P<late>_LATE)?_(?P<user>\d+)_(?P<att>\d+)_(?P<file>.+)$")
_ANON = re.compile(r"^(?P<late>LATE_)?anon_(?P<user>[A-Za-z0-9]+)_(?P<att>\d+)_(?P<file>.+)$")
_ENTRY = re.compile(r"^(?P<name>[^\W_][\w]*?)(?P<late>_LATE)?_(?P<user>\d+)_(?P<what>text|link)\.html$")
#: the largest LMS download unpacked (a class of a few hundred students' workspaces)
DOWNLOAD_MAX_BYTES = 20 * 2**30
LATE_SOURCE = "Canvas's LATE mark in the file name (the download has no submission times)"


@dataclass(frozen=True)
class CanvasFile:
    path: Path
    name: str                 # Canvas's sanitized sortable name, or anon_<id>
    user: str                 # Canvas user id (or the anonymous id)
    attachment: str           # "" for a text/link entry
    file: str                 # the name the student uploaded it under
    late: bool
    entry: str = ""           # text | link: not a file upload


def parse_name(name: str) -> CanvasFile | None:
    """Canvas's parts of one download file name, or None when it is not one of Canvas's."""
    for pattern, anon in ((_ANON, True), (_FILE, False)):
        m = pattern.match(name)
        if m:
            return CanvasFile(Path(name), f"anon_{m['user']}" if anon else m["name"], m["user"], m["att"],
                              m["file"], bool(m["late"]))
    m = _ENTRY.match(name)
    if m:
        return CanvasFile(Path(name), m["name"], m["user"], "", f"{m['what']}.html", bool(m["late"]), m["what"])
    return None


def looks_like_canvas(names: list[str]) -> bool:
    """Most entries carry Canvas's ``name_userid_attachmentid_file`` pattern."""
    visible = [n for n in names if not n.startswith((".", "__MACOSX"))]
    hits = sum(parse_name(n) is not None for n in visible)
    return bool(visible) and hits * 2 >= len(visible) and hits > 0


def zip_is_canvas(archive: Path) -> bool:
    """A Canvas download zip: top-level members named the Canvas way."""
    if not archive.name.lower().endswith(".zip"):
        return False
    try:
        with zipfile.ZipFile(archive) as zf:
            names = [i.filename for i in zf.infolist()]
    except (OSError, zipfile.BadZipFile):
        return False
    return all("/" not in n.rstrip("/") for n in names) and looks_like_canvas([n.rstrip("/") for n in names])


def read_canvas(root: Path, work: Path) -> tuple[list[Arrival], list[str]]:
    """The submissions of a Canvas download (a zip, or the folder it unpacks to); ``work``: where
    a zip is unpacked and several files of one student are put together. Returns the arrivals
    and lines about entries that are not Canvas submission files."""
    skipped: list[str] = []
    if root.is_file():
        root = extract_download(root, work / "download", skipped)
    entries = sorted(p for p in root.iterdir() if not p.name.startswith((".", "__MACOSX")))
    by_user: dict[str, list[CanvasFile]] = {}
    for entry in entries:
        parsed = parse_name(entry.name)
        if parsed is None:
            skipped.append(f"{entry.name}: not named like a Canvas submission file (name_userid_fileid_file)")
            continue
        by_user.setdefault(parsed.user, []).append(replace(parsed, path=entry))
    arrivals = [_arrival(files, work) for _, files in sorted(by_user.items(), key=lambda kv: kv[1][0].name)]
    return arrivals, skipped


def _arrival(files: list[CanvasFile], work: Path) -> Arrival:
    first = files[0]
    late = any(f.late for f in files)
    lms = {"canvas_user_id": None if first.name.startswith("anon_") else first.user, "name": first.name,
           "attachment_ids": [f.attachment for f in files if f.attachment], "late_mark": late}
    arrival = Arrival("canvas", first.name, first.user, [f.path.name for f in files], lms=lms)
    links = [f for f in files if f.entry]
    uploads = [f for f in files if not f.entry]
    if not uploads:
        if any(f.entry == "link" for f in links):
            arrival.refused = (f"submitted a link ({links[0].path.name}), not files: download or clone what it "
                               "points to and grade that folder")
        else:
            arrival.refused = f"submitted a text entry ({links[0].path.name}), which has no files to grade"
        return arrival
    if links:
        arrival.notes.append(f"also submitted {', '.join(f.path.name for f in links)} (not graded)")
    if len(uploads) == 1 and (is_archive(uploads[0].path) or uploads[0].path.is_dir()):
        arrival.path = uploads[0].path
        inner = archive_time(uploads[0].path, uploads[0].file) if is_archive(uploads[0].path) else None
    else:
        try:
            arrival.path = _together(uploads, work / "students" / f"{first.name}_{first.user}", arrival.notes)
        except GraderError as exc:
            arrival.refused = str(exc)
        inner = None
    # Canvas's LATE mark decides; an archive's newest file time only tells by how much (at least)
    arrival.time = SubmissionTime(inner.at if inner else None,
                                  LATE_SOURCE + (f"; lateness from {inner.source}" if inner else ""),
                                  lms_late=late)
    return arrival


def _together(files: list[CanvasFile], dest: Path, notes: list[str]) -> Path:
    """One folder with the student's files under the names they uploaded (archives unpacked;
    what they skip goes into ``notes``)."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for f in files:
        name = Path(f.file).name or f.path.name
        if is_archive(f.path):
            extract_archive(f.path, dest / _stem(name), notes)
        elif f.path.is_dir():
            shutil.copytree(f.path, dest / name, symlinks=True)
        elif f.path.is_file() and not f.path.is_symlink():
            target = dest / name
            if target.exists():
                raise GraderError(f"{f.path.name}: two files named {name} in one Canvas submission")
            shutil.copyfile(f.path, target)
    return dest


def extract_download(archive: Path, dest: Path, notes: list[str]) -> Path:
    """Unpack an LMS download: a class's archives, so a submission's limits apply to each file
    (MAX_UNPACKED_BYTES) and the whole may be far larger; what is skipped is listed in ``notes``."""
    warnings: list[str] = []
    extract_archive(archive, dest, warnings, max_file=MAX_UNPACKED_BYTES, max_total=DOWNLOAD_MAX_BYTES)
    notes += warnings
    return dest


def _stem(name: str) -> str:
    for suffix in (".tar.gz", ".tgz", ".tar.xz", ".tar.bz2", ".tar", ".zip"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)] or "archive"
    return name
