"""Gradescope's "Export Submissions": a folder (or its zip) with ``submission_metadata.yml`` and
one ``submission_<id>/`` folder per submission holding the files the student uploaded::

    submission_409194023:
      :submitters:
      - :name: Jane Doe
        :sid: '12345'
        :email: jdoe@umd.edu
      :created_at: 2025-02-14 23:40:12.861687000 Z
      :score: 0.0
      :history: [...]

The keys are Ruby symbols written by Gradescope (hence the colons); values may carry Ruby type
tags (``!ruby/object:...``), which are read as plain data. ``:created_at:`` is Gradescope's own
submission time. A group submission lists several submitters: each of them gets the grade of
the one submission (it is graded once; the others take its recordings).
"""

from __future__ import annotations

import zipfile
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, cast

import yaml

from grader.errors import GraderError
from grader.intake.late import SubmissionTime
from grader.intake.model import Arrival
from grader.workspace.source import is_archive
from grader.intake.canvas import extract_download

METADATA = "submission_metadata.yml"
TIME_SOURCE = "Gradescope's submission time (created_at in submission_metadata.yml)"


class _Loader(yaml.SafeLoader):
    """Safe YAML that reads Ruby's type tags as the plain mapping, list or text they tag."""


def _untagged(loader: _Loader, _suffix: str, node: yaml.Node) -> Any:
    if isinstance(node, yaml.MappingNode):
        return loader.construct_mapping(node, deep=True)
    if isinstance(node, yaml.SequenceNode):
        return loader.construct_sequence(node, deep=True)
    return loader.construct_scalar(cast(yaml.ScalarNode, node))


_Loader.add_multi_constructor("!", _untagged)
_Loader.add_multi_constructor("tag:yaml.org,2002:", _untagged)


def find_metadata(root: Path) -> Path | None:
    """``submission_metadata.yml`` in ``root`` or in its one subfolder (the export's own)."""
    if (root / METADATA).is_file():
        return root / METADATA
    subs = [p for p in root.iterdir() if p.is_dir() and not p.name.startswith((".", "__MACOSX"))] \
        if root.is_dir() else []
    if len(subs) == 1 and (subs[0] / METADATA).is_file():
        return subs[0] / METADATA
    return None


def zip_is_gradescope(archive: Path) -> bool:
    if not archive.name.lower().endswith(".zip"):
        return False
    try:
        with zipfile.ZipFile(archive) as zf:
            return any(Path(n).name == METADATA and n.count("/") <= 1 for n in zf.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def _key(name: str) -> str:
    return name.lstrip(":")


def _plain(value: Any) -> Any:
    """Ruby-symbol keys (``:name``) as plain ones, at any depth."""
    if isinstance(value, dict):
        return {_key(str(k)): _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _when(value: Any) -> datetime | None:
    if isinstance(value, datetime):
        return value if value.tzinfo else value.replace(tzinfo=timezone.utc)
    if isinstance(value, str) and value.strip():
        try:
            parsed = datetime.fromisoformat(value.strip().replace(" Z", "+00:00").replace("Z", "+00:00"))
        except ValueError:
            return None
        return parsed if parsed.tzinfo else parsed.replace(tzinfo=timezone.utc)
    return None


def read_gradescope(root: Path, work: Path) -> tuple[list[Arrival], list[str]]:
    """The submissions of a Gradescope export (folder or zip); lines about folders without
    metadata and metadata without folders."""
    notes: list[str] = []
    if root.is_file():
        root = extract_download(root, work / "export", notes)
    meta_path = find_metadata(root)
    if meta_path is None:
        raise GraderError(f"{root} has no {METADATA}: export it from Gradescope with "
                          "\"Export Submissions\" and unzip it whole")
    try:
        meta = _plain(yaml.load(meta_path.read_text(encoding="utf-8"), Loader=_Loader))  # noqa: S506
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise GraderError(f"{meta_path} cannot be read: {exc}") from None
    if not isinstance(meta, dict):
        raise GraderError(f"{meta_path} is not a mapping of submission_<id> folders")
    base = meta_path.parent
    arrivals: list[Arrival] = []
    for folder_name, record in sorted(meta.items()):
        record = record if isinstance(record, dict) else {}
        submitters = [s for s in record.get("submitters") or [] if isinstance(s, dict)]
        sub_id = folder_name.removeprefix("submission_")
        folder = base / folder_name
        when = _when(record.get("created_at"))
        time = SubmissionTime(when, TIME_SOURCE) if when else None
        if not submitters:
            notes.append(f"{folder_name}: no submitter in {METADATA}; not graded")
            continue
        path, refused = _what_to_grade(folder)
        group = [str(s.get("name") or s.get("email") or s.get("sid") or "?") for s in submitters]
        for person in submitters:
            email = str(person.get("email") or "")
            sid = str(person.get("sid") or "")
            key = email.split("@")[0].lower() if email else (sid or folder_name)
            arrival = Arrival("gradescope", key, sub_id, [folder_name], path=path, time=time,
                              lms={"submission_id": sub_id, "name": str(person.get("name") or ""),
                                   "email": email, "sid": sid}, refused=refused)
            if len(submitters) > 1:
                arrival.notes.append(f"group submission {sub_id} of {', '.join(group)}: each gets its grade")
            arrivals.append(arrival)
    listed = set(meta)
    for extra in sorted(p.name for p in base.iterdir() if p.is_dir() and p.name not in listed
                        and not p.name.startswith((".", "__MACOSX"))):
        notes.append(f"{extra}: a folder {METADATA} does not list; not graded")
    return arrivals, notes


def _what_to_grade(folder: Path) -> tuple[Path | None, str | None]:
    """The submission folder, or the one archive the student uploaded in it."""
    if not folder.is_dir():
        return None, f"listed in {METADATA} but the export has no folder {folder.name}"
    files = [p for p in folder.rglob("*") if p.is_file() and not p.is_symlink()]
    if not files:
        return None, "the submission is empty (no files)"
    if any(p.name == "package.xml" for p in files):
        return folder, None
    archives = [p for p in folder.iterdir() if is_archive(p)]
    if len(archives) == 1 and len(files) == 1:
        return archives[0], None
    return folder, None
