"""Grading on many machines: a deterministic share of a batch per machine, then one merge.

``grader grade ... --shard K/N`` grades the submissions whose id hashes to K (of N), so N jobs of
a Slurm array, N Gradescope-free cluster nodes or N CI runners split a class without talking to
each other; ``grader merge OUT_1 ... OUT_N -o OUT`` copies their submission folders into one
output and rebuilds ``grades.csv`` and ``index.html`` (``grader.api.merge``; the command is
``grader.commands.grading``'s). The split is stable (sha-256 of the id):
the same submission always lands in the same shard, whatever else is in the folder.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path
from typing import TYPE_CHECKING

from grader.contracts.result_document import ResultDocument
from grader.contracts.output_folder import SubmissionFolder
from grader.errors import GraderError

if TYPE_CHECKING:
    from grader.rubric.schema import Rubric

NOTE = ".shard.json"


def in_shard(submission: str, k: int, n: int) -> bool:
    """Whether ``submission`` belongs to shard ``k`` of ``n`` (1-based)."""
    return int(hashlib.sha256(submission.encode()).hexdigest(), 16) % n == k - 1


def rubric_digest(rubric: Rubric) -> str:
    return hashlib.sha256(Path(rubric.source).read_bytes()).hexdigest()[:16]


def write_shard_note(out: Path, rubric: Rubric, k: int, n: int) -> None:
    (Path(out) / NOTE).write_text(json.dumps({"lab": rubric.lab, "rubric": rubric_digest(rubric),
                                              "shard": [k, n]}))


def merge_outputs(parts: list[Path], out: Path, rubric: Rubric) -> list[str]:
    """Copy every submission of ``parts`` into ``out``; refuses a part graded with another rubric
    or a submission that two parts both hold (nothing is copied then). Returns the ids merged."""
    digest = rubric_digest(rubric)
    plan: dict[str, Path] = {}
    problems: list[str] = []
    for part in parts:
        part = Path(part)
        if not part.is_dir():
            problems.append(f"{part} is not a folder")
            continue
        note = part / NOTE
        if note.is_file():
            meta = json.loads(note.read_text())
            if meta.get("rubric") != digest:
                problems.append(f"{part} was graded with another rubric (lab {meta.get('lab')}, rubric "
                                f"{meta.get('rubric')}; this one is {rubric.lab} {digest})")
        for sub in sorted(p for p in part.iterdir() if SubmissionFolder(p).result_json.is_file()):
            try:
                lab = ResultDocument.read(SubmissionFolder(sub).result_json).lab
            except (OSError, ValueError) as exc:
                problems.append(str(exc))     # names the file
                continue
            if lab != rubric.lab:
                problems.append(f"{sub}: graded for lab {lab!r}, not {rubric.lab!r}")
            if sub.name in plan:
                problems.append(f"{sub.name} is in both {plan[sub.name].parent} and {part}")
            plan[sub.name] = sub
    if problems:
        raise GraderError("cannot merge:\n  " + "\n  ".join(problems))
    if not plan:
        raise GraderError("cannot merge: none of the folders holds a graded submission (*/result.json)")
    out.mkdir(parents=True, exist_ok=True)
    clash = sorted(sid for sid in plan if (out / sid).exists())
    if clash:
        raise GraderError(f"cannot merge: {out} already holds {', '.join(clash)}")
    for sid, sub in plan.items():
        shutil.copytree(sub, out / sid, symlinks=True)
    return sorted(plan)
