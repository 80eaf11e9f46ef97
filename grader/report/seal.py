"""Seals on results: nothing but the grader can change a grade, and nothing changes unnoticed.

Every ``result.json`` the grader writes carries a ``seal``: the SHA-256 of each file its grade was
computed from (the scenario bags and canvases: ``inputs``) and an HMAC-SHA256 over the whole
document made with a key only the grader can read (student processes run in a sandbox that does
not see it). So:

* ``grades.csv`` and ``index.html`` are rebuilt only from results whose seal checks out: a
  result.json edited by anyone else is an error naming the file;
* ``grader regrade`` recomputes from the bags only when they are the ones graded (a bag changed
  since, or one that was not finalised cleanly, makes its items errors, never a silent new grade).

The key lives in ``$GRADER_SEAL_KEY`` (a file path; share one file between the machines of a
cluster whose outputs ``grader merge`` combines) or ``<XDG_STATE_HOME or ~/.local/state>/grader/seal.key``,
created on first use, mode 0600.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
from pathlib import Path
from typing import Any, Mapping

from grader.contracts.result_document import ResultDocument, SealEntry
from grader.errors import GraderError

#: what a grade is computed from, inside a submission's output folder
INPUT_GLOBS = ("scenarios/*/bag/*", "scenarios/*/canvas.png")


def key_path() -> Path:
    explicit = os.environ.get("GRADER_SEAL_KEY")
    if explicit:
        return Path(explicit)
    state = Path(os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state")
    return state / "grader" / "seal.key"


def _key() -> bytes:
    path = key_path()
    try:
        return path.read_bytes()
    except FileNotFoundError:
        path.parent.mkdir(parents=True, exist_ok=True)
        key = secrets.token_bytes(32)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            os.write(fd, key)
        finally:
            os.close(fd)
        return key
    except FileExistsError:  # pragma: no cover - created concurrently
        return path.read_bytes()


def input_digests(sub_out: Path) -> dict[str, str]:
    """``{relative path: sha256}`` of every file the grade of ``sub_out`` is computed from."""
    out = {}
    for pattern in INPUT_GLOBS:
        for f in sorted(Path(sub_out).glob(pattern)):
            if f.is_file():
                out[str(f.relative_to(sub_out))] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


def _mac(body: Mapping[str, Any]) -> str:
    text = json.dumps({k: v for k, v in body.items() if k != "seal"}, sort_keys=True, separators=(",", ":"))
    return hmac.new(_key(), text.encode(), hashlib.sha256).hexdigest()


def sealed(doc: ResultDocument, inputs: Mapping[str, str]) -> ResultDocument:
    """``doc`` with its seal; the MAC covers the document's JSON and the input digests."""
    mac = _mac({**doc.without_seal(), "seal_inputs": dict(inputs)})
    return doc.with_seal(SealEntry(inputs=dict(inputs), mac=mac))


def mac_ok(doc: ResultDocument) -> bool:
    if doc.seal is None:
        return False
    return hmac.compare_digest(doc.seal.mac, _mac({**doc.without_seal(), "seal_inputs": doc.seal.inputs}))


def check_doc(doc: ResultDocument, path: Path) -> None:
    """Raise naming ``path`` unless its seal was made by this grader's key for this content."""
    if doc.seal is None:
        raise GraderError(f"{path} has no seal: it was not written by this grader (or by a version "
                          "before seals); regrade it (`grader regrade`) to seal it")
    if not mac_ok(doc):
        raise GraderError(f"{path} was changed after the grader wrote it (its seal does not match), or it was "
                          f"sealed with another key (set GRADER_SEAL_KEY to the grading machine's {key_path().name})")


def changed_inputs(doc: ResultDocument, sub_out: Path) -> list[str]:
    """Inputs that differ from what was graded (missing, added or changed), as relative paths."""
    recorded = dict(doc.seal.inputs) if doc.seal is not None else {}
    now = input_digests(sub_out)
    return sorted(p for p in set(recorded) | set(now) if recorded.get(p) != now.get(p))


def recorded_inputs(result_json: Path) -> dict[str, str] | None:
    """The input digests an existing result.json recorded (None when there is none)."""
    try:
        doc = ResultDocument.read(result_json)
    except (OSError, ValueError):
        return None
    return dict(doc.seal.inputs) if doc.seal is not None else None
