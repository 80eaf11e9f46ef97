"""Every analyzer says what its evidence means: each key it produces on the committed real bags has
a label in words and a unit (or is marked as not for reading), its headline value has a label,
and it states what it expects. The report shows only labelled keys, so a key missing here would
silently vanish from the page; this test names it instead."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Mapping

import pytest

import grader.analyze as A
from grader.analyze.evidence import SHARE, SINCE_START, TIME
from grader.grading.analysis import analyze_item, scenario_frames
from grader.rubric.load import load_rubric

REPO = Path(__file__).resolve().parents[2]
BAGS = REPO / "fixtures" / "bags" / "lab3"
RUBRIC = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml", check_files=False)
UNITS = {"", "m", "s", "Hz", "m/s", "rad", "rad/s", "deg", "1/s", TIME, SHARE, SINCE_START}


def _unlabelled(labels: Mapping[str, Any], ev: Mapping[str, Any], prefix: str = "") -> set[str]:
    missing = set()
    for key, value in ev.items():
        path = prefix + key
        if path not in labels and key not in labels:
            missing.add(path)
            continue
        if labels.get(path, labels.get(key)) is None:
            continue                                   # plot series, ids: not for reading
        if isinstance(value, Mapping):
            missing |= _unlabelled(labels, value, path + ".")
        elif isinstance(value, list):
            for row in value:
                if isinstance(row, Mapping):
                    missing |= {f"{path}[].{k}" for k in _unlabelled(labels, row)}
    return missing


@pytest.fixture(scope="module")
def findings() -> list[tuple[str, str, Any]]:
    out = []
    for sub in sorted(p for p in BAGS.iterdir() if p.is_dir()):
        for sc in sorted(p for p in sub.iterdir() if (p / "bag").is_dir()):
            frames = scenario_frames(sc)
            for item in RUBRIC.items:
                if item.analyzer and sc.name in item.scenario:
                    out.append((f"{sub.name}/{item.id}", item.analyzer, analyze_item(item, frames)))
    return out


def test_every_evidence_key_on_real_bags_is_labelled(findings) -> None:
    missing = {}
    for where, analyzer, finding in findings:
        gaps = _unlabelled(A.evidence_labels(analyzer), finding.evidence)
        if gaps:
            missing[where] = sorted(gaps)
    assert not missing, f"evidence keys without a label (add them to the analyzer's EVIDENCE table): {missing}"


def test_times_are_relative_to_the_scenario_start(findings) -> None:
    for where, _, finding in findings:
        t0 = finding.evidence.get("scenario_start")
        assert isinstance(t0, float) and t0 > 1e9, where


@pytest.mark.parametrize("name", A.builtin_names())
def test_labels_units_and_expectation(name: str) -> None:
    labels = A.evidence_labels(name)
    value = labels.get("value")
    assert value and value[0], f"{name}: label its headline value ('value': (label, unit))"
    assert A.expected_text(name), f"{name}: say what it expects (expect=...)"
    for key, label in labels.items():
        if label is not None:
            text, unit = label
            # words, not an identifier like "n_len_not_2"
            assert text and not re.fullmatch(r"\w+(_\w+)+", text) and unit in UNITS, f"{name}.{key}: {label}"


@pytest.mark.parametrize("item", [i for i in RUBRIC.items if i.analyzer], ids=lambda i: i.id)
def test_expectation_fills_in_from_the_parameters(item) -> None:
    from grader.rubric.score import render_template

    text = render_template(A.expected_text(item.analyzer), {**A.defaults(item.analyzer), **item.params})
    assert "{" not in text and "None" not in text and "['" not in text, text
