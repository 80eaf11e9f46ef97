"""grader/contracts: the values every package shares are defined once (issue 19's acceptance greps,
kept true by a test), and the one ``jsonable`` serves both the evidence and the result files."""

from __future__ import annotations

import datetime as dt
import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from grader.contracts.jsonable import jsonable

GRADER = Path(__file__).resolve().parents[2] / "grader"


def _grep(pattern: str) -> list[str]:
    rx = re.compile(pattern)
    return [f"{p.relative_to(GRADER)}:{n}" for p in sorted(GRADER.rglob("*.py"))
            for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if rx.search(line)]


def test_each_shared_value_is_defined_once() -> None:
    assert _grep(r"11\.0888") == ["contracts/world.py:9"]
    assert [hit.split(":")[0] for hit in _grep(r"^def jsonable\b")] == ["contracts/jsonable.py"]
    assert _grep(r"^STATUSES\s*=") == ["contracts/status.py:6"]
    assert [hit.split(":")[0] for hit in _grep(r"^class Goal\b")] == ["contracts/fields.py"]
    assert _grep(r"\bresult: Any\b") == []


def test_jsonable_makes_strict_json_of_evidence_and_records(tmp_path: Path) -> None:
    value = {
        "np": (np.int64(3), np.float32(0.5), np.bool_(True), np.array([1.0, np.nan])),
        "inf": math.inf, "set": {"b", "a"}, "path": tmp_path / "x.json",
        "when": dt.datetime(2025, 2, 14, 23, 59, tzinfo=dt.timezone.utc),
        "frame": pd.DataFrame({"t": [0.0, 1.0], "v": [1, None]}),
        "series": pd.Series({"x": 1.5}), "na": pd.NA, "nat": pd.NaT, 1: object,
    }
    out = jsonable(value)
    assert out == {
        "np": [3, 0.5, True, [1.0, None]], "inf": None, "set": ["a", "b"], "path": str(tmp_path / "x.json"),
        "when": "2025-02-14T23:59:00+00:00", "frame": [{"t": 0.0, "v": 1.0}, {"t": 1.0, "v": None}],
        "series": {"x": 1.5}, "na": None, "nat": None, "1": str(object),
    }
    json.dumps(out, allow_nan=False)
