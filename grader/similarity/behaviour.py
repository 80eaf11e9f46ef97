"""Behaviour fingerprints: what a submission's code did in each scenario, read from the recording
the grade already made (no new runs), in features that renaming or reformatting cannot change.

Per scenario (``fingerprint_frames``, stored as ``OUT/<id>/scenarios/<sc>/fingerprint.json`` when
the bag is analyzed, so a class is compared without reading its bags again):

* ``path``: each step's trajectory of every pose-like topic (``x`` and ``y`` fields), resampled by
  arc length from where the step's goal was sent; the Lab 3 rubric places the turtle before each
  goal, so two paths of one step start from the same pose and can be compared point by point;
* ``commands``: each step's values of every numeric field the student's nodes publish, on a
  0.1 s grid from their first change after the goal (the controller's response: gains, rate,
  saturation, a wrong sign or a missing wrap all show);
* ``values``: quantiles of every numeric field the student's nodes publish over the scenario;
* ``rate``: the median publish rate of each topic the student's nodes publish;
* ``log``: the templates of the lines the student's nodes log or print (numbers replaced by
  ``#``), so "New goal: (2.00, 7.00)" and "New goal: (0.80, 5.50)" are one template;
* ``names``: the nodes, topics and services the student's nodes create.

From result.json (``result_features``, when the class is compared): the items that did not pass
with their status and headline value (the same failing items with the same wrong values; an item
that measured nothing is left out: a node that never ran is no fingerprint), and the
numbers each item measured (fitted gains, rates, errors: the analyzer's own evidence, without its
thresholds and times).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from grader.analyze._common import end_time, events, rosout_lines, stdout_lines, times
from grader.contracts.result_document import ItemEntry
from grader.contracts.events import Graph, GoalSent, ScenarioStart, StepEnd, StepStart
from grader.analyze.evidence import TIME
from grader.report.result import atomic_write

FINGERPRINT_FILE = "fingerprint.json"
FINGERPRINT_SCHEMA = 2          # 2: generic traceback lines left out
PATH_POINTS = 40            # points of a resampled path
CMD_GRID_S = 0.1            # grid of a command series
CMD_SPAN_S = 6.0            # seconds of a step's command series kept (the response to the goal)
GRADER_NODES = {"grader_driver", "grader_recorder", "grader_clock", "turtlesim"}
IGNORED_TOPICS = ("/grader/", "/rosout", "/parameter_events", "/clock")
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


@dataclass
class Feature:
    key: str            # the same key in every submission of the lab ("ex2_controller|path|/turtle1/pose|goal_lab")
    kind: str           # path | series | scalar | token
    group: str          # path | commands | values | rate | log | names | failure | measured
    label: str          # in words, for the side-by-side page
    value: Any          # [[x, y], ...] | [float, ...] | float | str
    scenario: str = ""

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Feature":
        return cls(**{k: d[k] for k in ("key", "kind", "group", "label", "value", "scenario") if k in d})


#: lines any crashing Python program prints: no fingerprint of anyone's code (the exception's own
#: line, e.g. "ValueError: not enough values to unpack (expected #, got #)", is kept)
GENERIC_LINE = re.compile(r"^(Traceback \(most recent call last\):|File \".*\", line #.*|\^+|~+\^*~*)$")


def template(line: str) -> str:
    """A log line with its numbers replaced by '#' and its spacing collapsed."""
    return re.sub(r"\s+", " ", NUMBER.sub("#", str(line))).strip()[:160]


def _student_nodes(frames: Mapping[str, Any]) -> tuple[set[str], dict[str, set[str]], set[str]]:
    """(student node names, topic -> student publishers, student services) from graph events."""
    start = events(frames, ScenarioStart)
    grader = set(GRADER_NODES) | {e.sim_node for e in start if e.sim_node}
    nodes: set[str] = set()
    pubs: dict[str, set[str]] = {}
    services: set[str] = set()
    for ev in events(frames, Graph):
        mine = {str(n).rsplit("/", 1)[-1] for n in ev.nodes} - grader
        nodes |= {n for n in mine if not n.startswith("_")}
        for topic, who in ev.publishers.items():
            students = {str(n).rsplit("/", 1)[-1] for n in who} - grader
            if students and not topic.startswith(IGNORED_TOPICS):
                pubs.setdefault(topic, set()).update(students)
        for svc, who in (ev.servers or {}).items():
            if {str(n).rsplit("/", 1)[-1] for n in who} & nodes:
                if not any(p in svc for p in ("parameter", "type_description", "_action/")):
                    services.add(svc)
    return nodes, pubs, services


def _windows(frames: Mapping[str, Any]) -> list[tuple[str, float, float]]:
    """(step id, time its goal was sent or it started, end) of each step; the whole run if none."""
    starts = {e.step: e.t for e in events(frames, StepStart) if e.step}
    goals = {e.step: e.t for e in events(frames, GoalSent) if e.step}
    ends = {e.step: e.t for e in events(frames, StepEnd) if e.step}
    end = end_time(frames)
    out = []
    for step, t0 in sorted(starts.items(), key=lambda kv: kv[1]):
        t1 = ends.get(step, end)
        out.append((str(step), float(goals.get(step, t0)), float(t1)))
    return out


def _numeric_columns(df) -> list[str]:
    skip = {"pub_t", "data.len"}
    return [c for c in df.columns if c not in skip and df[c].dtype.kind in "fiu"]


def _path(x: np.ndarray, y: np.ndarray) -> list[list[float]]:
    """PATH_POINTS points evenly spaced along the path (all at the start when it did not move)."""
    seg = np.hypot(np.diff(x), np.diff(y))
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] < 1e-3:
        pts = np.column_stack([np.full(PATH_POINTS, x[0]), np.full(PATH_POINTS, y[0])])
    else:
        grid = np.linspace(0.0, s[-1], PATH_POINTS)
        pts = np.column_stack([np.interp(grid, s, x), np.interp(grid, s, y)])
    return np.round(pts, 4).tolist()


def _pose_topics(frames: Mapping[str, Any]) -> list[str]:
    out = []
    for name, df in frames.items():
        if not isinstance(name, str) or not name.startswith("/") or name.startswith(IGNORED_TOPICS):
            continue
        if hasattr(df, "columns") and "x" in df.columns and "y" in df.columns and len(df) > 2:
            out.append(name)
    return sorted(out)


def fingerprint_frames(frames: Mapping[str, Any], scenario: str) -> list[Feature]:
    """The behaviour features of one scenario's recording (see the module docstring)."""
    feats: list[Feature] = []
    nodes, pubs, services = _student_nodes(frames)
    windows = _windows(frames)
    for topic in _pose_topics(frames):
        df = frames[topic]
        t = times(df)
        x, y = df["x"].to_numpy(float), df["y"].to_numpy(float)
        for step, t0, t1 in windows:
            m = (t >= t0) & (t <= t1) & np.isfinite(x) & np.isfinite(y)
            # a turtle that did not move in the step leaves no fingerprint of its code
            if m.sum() >= 2 and np.hypot(np.ptp(x[m]), np.ptp(y[m])) >= 0.01:
                feats.append(Feature(f"{scenario}|path|{topic}|{step}", "path", "path",
                                     f"path of {topic} in step {step}", _path(x[m], y[m]), scenario))
    for topic in sorted(pubs):
        df = frames.get(topic)
        if df is None or not hasattr(df, "columns") or len(df) < 2:
            continue
        t = times(df)
        dt = np.diff(t)
        dt = dt[dt > 0]
        if len(dt):
            feats.append(Feature(f"{scenario}|rate|{topic}", "scalar", "rate", f"publish rate of {topic} (Hz)",
                                 round(1.0 / float(np.median(dt)), 4), scenario))
        for col in _numeric_columns(df):
            v = df[col].to_numpy(float)
            ok = np.isfinite(v)
            if ok.sum() < 2 or np.nanmax(np.abs(v)) == 0:
                continue
            q = np.quantile(v[ok], [0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 1.0])
            feats.append(Feature(f"{scenario}|values|{topic}.{col}", "series", "values",
                                 f"distribution of {topic} {col}", np.round(q, 5).tolist(), scenario))
            for step, t0, t1 in windows:
                m = (t >= t0) & (t <= t1) & ok
                if m.sum() < 3:
                    continue
                tt, vv = t[m], v[m]
                moved = np.nonzero(np.abs(vv - vv[0]) > 1e-6)[0]
                start = tt[moved[0] - 1] if len(moved) and moved[0] > 0 else tt[0]
                grid = start + np.arange(0.0, min(CMD_SPAN_S, tt[-1] - start) + 1e-9, CMD_GRID_S)
                if len(grid) < 3:
                    continue
                idx = np.clip(np.searchsorted(tt, grid, side="right") - 1, 0, len(tt) - 1)
                feats.append(Feature(f"{scenario}|commands|{topic}.{col}|{step}", "series", "commands",
                                     f"{topic} {col} after the goal of step {step}",
                                     np.round(vv[idx], 4).tolist(), scenario))
    lines: set[str] = set()
    ros = rosout_lines(frames)
    if len(ros):
        loggers = ros["logger"].astype(str).str.rsplit(".", n=1).str[-1]
        lines |= {template(s) for s, who in zip(ros["text"], loggers) if who in nodes}
    out = stdout_lines(frames)
    if len(out):
        lines |= {template(s) for s in out["text"] if str(s).strip()}
    feats += [Feature(f"{scenario}|log|{line}", "token", "log", f"logged: “{line}”", line, scenario)
              for line in sorted(lines) if line and len(line) > 2 and not GENERIC_LINE.match(line)]
    names = [("node", n) for n in sorted(nodes)] + [("topic", t) for t in sorted(pubs)] + \
            [("service", s) for s in sorted(services)]
    feats += [Feature(f"{scenario}|names|{kind}:{name}", "token", "names", f"{kind} {name}", name, scenario)
              for kind, name in names]
    return feats


def write_fingerprint(scenario_dir: Path, frames: Mapping[str, Any]) -> Path:
    """Fingerprint one scenario's frames into ``scenario_dir/fingerprint.json``."""
    feats = fingerprint_frames(frames, Path(scenario_dir).name)
    path = Path(scenario_dir) / FINGERPRINT_FILE
    doc = {"schema": FINGERPRINT_SCHEMA, "scenario": Path(scenario_dir).name,
           "features": [asdict(f) for f in feats]}
    atomic_write(path, json.dumps(doc, separators=(",", ":")) + "\n")
    return path


def read_fingerprint(scenario_dir: Path) -> list[Feature] | None:
    """The stored features of a scenario, or None (not fingerprinted, or an older schema)."""
    path = Path(scenario_dir) / FINGERPRINT_FILE
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("schema") != FINGERPRINT_SCHEMA:
        return None
    return [Feature.from_dict(f) for f in doc.get("features") or ()]


def _value_text(value: Any) -> str:
    text = json.dumps(value, sort_keys=True, default=str) if not isinstance(value, str) else value
    return NUMBER.sub(lambda m: f"{float(m.group()):.3g}", text)[:200]


def _scalars(evidence: Mapping[str, Any], skip: set[str]) -> Iterable[tuple[str, float]]:
    for key, v in evidence.items():
        if key in skip or isinstance(v, bool):
            continue
        if isinstance(v, (int, float)) and math.isfinite(v):
            yield key, float(v)


def result_features(items: Iterable[ItemEntry], item_scenarios: Mapping[str, list[str]],
                    labels: Mapping[str, Mapping[str, Any]] | None = None) -> list[Feature]:
    """Features of a result.json's ``items``: failing items with their values, and every item's
    measured numbers (``labels``: item id -> its analyzer's evidence table; unlabelled keys,
    thresholds and times are left out)."""
    feats = []
    for item in items:
        iid, status = item.id, item.status
        if item.kind not in ("auto", "advisory", "integrity") or status not in ("pass", "partial", "fail"):
            continue
        scenario = ",".join(item_scenarios.get(iid, []))
        if status != "pass" and item.value is not None:     # no value: nothing was measured
            value = item.value
            feats.append(Feature(f"item|{iid}|outcome", "token", "failure", f"{iid}: {status}, {_value_text(value)}",
                                 f"{status}:{_value_text(value)}", scenario))
        table = (labels or {}).get(iid) or {}
        params = set(item.params)
        skip = params | {"scenario_start"} | {k for k, lab in table.items() if lab is None or lab[1] == TIME}
        for key, v in _scalars(item.evidence, skip):
            if table and key not in table:
                continue
            words = table.get(key)
            label = f"{iid}: {words[0]}" + (f" ({words[1]})" if words and words[1] else "") if words else f"{iid}: {key}"
            feats.append(Feature(f"item|{iid}|{key}", "scalar", "measured", label, v, scenario))
    return feats


__all__ = ["FINGERPRINT_FILE", "Feature", "fingerprint_frames", "read_fingerprint", "result_features",
           "template", "write_fingerprint"]
