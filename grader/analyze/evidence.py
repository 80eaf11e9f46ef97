"""What an analyzer's evidence means, in words: a label and a unit for each key a reader may see.

Why here and not in the report: the analyzer that produces a number is the only place that knows
what it measures. Each analyzer module keeps a table ``{key: (label, unit) | None}`` next to its
code and passes it to ``@register(..., evidence=TABLE, expect="...")``; the report shows only keys
with a label (so no internal key name is ever shown to a reader) and keeps everything, raw, in
result.json.

Table entries
-------------
* ``"key": ("label in words", unit)``: ``unit`` is a plain unit ("m", "s", "Hz", "m/s", "rad/s",
  "deg", "rad") or one of the special units below; ``""`` for counts, names and yes/no values
  (say what is counted in the label: "messages recorded").
* ``"key": None``: data that is not for reading (series drawn by the report's figures, ids).
* Keys apply at any depth: a top-level key, a key of a nested mapping (``"ks.u1_p"`` for a
  nested key when the bare name would be ambiguous) or a column of a list of records
  (``goals[].final_error`` is looked up as ``"final_error"``).
* ``"value"`` labels the finding's headline ``value``.
* Thresholds (the analyzer's parameters) are labelled in the same table, so the report can show
  "goal tolerance: 0.1 m" for ``tol_reached``.

``expect`` is one phrase saying what was expected, formatted with the item's effective
parameters and the evidence (``"{expected_hz:g} Hz ± {rel_tol:.0%}"``); the report writes
"<value label>: <value> — expected <expect>." as the first sentence of a failing item.
"""

from __future__ import annotations

from typing import Mapping, Optional, Tuple

#: epoch seconds of the bag (receive time): shown as seconds since the scenario started
TIME = "time"
#: a share 0..1: shown as a percentage
SHARE = "share"
#: seconds already counted from the scenario start (series in evidence)
SINCE_START = "s since start"

Label = Optional[Tuple[str, str]]
Labels = Mapping[str, Label]

#: keys any analyzer (or the pipeline) may add
COMMON: dict[str, Label] = {
    "scenario_start": None,                       # epoch s; the report's origin of times
    "topic": ("topic", ""),
    "measured_topic": ("measured on the student's topic", ""),
    "process": ("process (node started by the grader)", ""),
    "unavailable_nodes": ("nodes that could not run", ""),
    "crashed_nodes": ("nodes that crashed", ""),
    "analyzer": None,
    "traceback": None,
    "note": ("note", ""),
    "t": ("time", TIME),
    "n": ("values", ""),
    "meta": None,
    # the moment of the run that decided the item (the report's replay opens there)
    "at_s": ("the moment that decided it", SINCE_START),
    "at": ("what happened then", ""),
}


def merged(labels: Labels | None) -> dict[str, Label]:
    """The common table overlaid with an analyzer's own."""
    return {**COMMON, **dict(labels or {})}


__all__ = ["COMMON", "Label", "Labels", "SHARE", "SINCE_START", "TIME", "merged"]
