"""Where a class's similarity lands (``OUT/similarity/``) and how its summary is read back.

The names both the computation (``grader.grading.similarity``) and its readers (the pair pages, the
class view in ``grader.report``) need; here, the readers do not import the computation (which
writes the class view: a circle through ``grader.grading.outputs``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from grader.contracts.output_folder import SIMILARITY_DIR
OUT_DIR = SIMILARITY_DIR
SUMMARY = "similarity.json"
PAIRS_CSV = "pairs.csv"
#: the id prefix of a known solution (``--known DIR``) among the class's submissions
KNOWN_PREFIX = "known:"


def read_summary(out: Path) -> dict[str, Any] | None:
    """OUT/similarity/similarity.json, or None (never computed, or unreadable)."""
    try:
        doc = json.loads((Path(out) / OUT_DIR / SUMMARY).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and doc.get("schema") == 1 else None
