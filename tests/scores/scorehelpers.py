"""Helpers of the scores tests (imported as ``scorehelpers``: tests/ is not a package)."""

from __future__ import annotations

import hashlib
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
RUBRIC = REPO / "rubrics" / "enee467_lab3.yaml"

def snapshot(out: Path) -> dict[str, str]:
    """Every file under OUT (bags aside) -> content hash: to prove nothing was written."""
    return {str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(out.rglob("*")) if p.is_file() and "scenarios" not in p.parts}


def write_csv(path: Path, text: str, encoding: str = "utf-8") -> Path:
    path.write_bytes(text.encode(encoding))
    return path
