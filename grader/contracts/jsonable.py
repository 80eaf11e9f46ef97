"""``jsonable``: any value the grader produces as strict JSON (what result.json, the reports and
the LMS exports write), defined once for the analyzers' evidence and the result documents."""

from __future__ import annotations

import math
import os
from typing import Mapping

import numpy as np
import pandas as pd
from grader.contracts.values import JsonValue


def jsonable(obj: object) -> JsonValue:
    """Plain JSON types from numpy/pandas/pathlib/datetime values; NaN and infinities become None.

    Evidence goes straight into result.json and the HTML report, so it must serialise with the
    standard ``json`` module and never contain NaN (which is not valid JSON). Tables become lists
    of records (a DataFrame) or mappings (a Series); sets become lists in a stable order; paths
    their text; dates and times ISO 8601; anything else its ``str``.
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (set, frozenset)):
        return [jsonable(v) for v in sorted(obj, key=str)]
    if isinstance(obj, np.ndarray):
        return [jsonable(v) for v in obj.tolist()]
    if isinstance(obj, pd.DataFrame):
        return [jsonable(r) for r in obj.to_dict(orient="records")]
    if isinstance(obj, pd.Series):
        return jsonable(obj.to_dict())
    if obj is pd.NA or obj is pd.NaT:
        return None
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if hasattr(obj, "tolist"):           # other numpy scalars
        return jsonable(obj.tolist())
    if hasattr(obj, "item"):
        return jsonable(obj.item())
    if hasattr(obj, "isoformat"):
        return obj.isoformat()
    return str(obj)
