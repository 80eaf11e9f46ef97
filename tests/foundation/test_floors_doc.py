"""docs/ARCHITECTURE.md's floors are the ones `make lint` checks: its floors table against the
import-linter contracts in pyproject.toml.

import-linter holds the code to pyproject's `layers` contract; the document tells a reader what
those floors are. Each was edited by hand and they drifted once (a package moved a floor in one
and not in the other), so this reads both: the table's floor N is the contract's N-th layer
from the bottom, the same packages; the number of back-arrows the text says are left is the
number of `ignore_imports`; and the front-ends' `forbidden` contract forbids every engine floor
(each one below `grader.api` but the ground floor), so a package added to the engine is kept
from the front-ends as soon as it gets its floor.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
GROUND = {"grader.contracts", "grader.errors"}
#: above grader.api, not front-ends that must go through it (pyproject says why)
NOT_FRONT_ENDS = {"grader.testing", "grader.bootstrap"}


def _contracts() -> dict[str, dict[str, Any]]:
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["importlinter"]
    return {c["type"]: c for c in config["contracts"]}


def _layers() -> list[set[str]]:
    """The `layers` contract's floors, bottom first."""
    layers = _contracts()["layers"]["layers"]
    return [{p.strip() for p in layer.split(":")} for layer in reversed(layers)]


def _doc_floors(text: str) -> dict[int, set[str]]:
    """The rows of the "| floor | package | owns |" table: floor number -> grader.<package>."""
    head = text.index("| floor | package | owns |")
    floors: dict[int, set[str]] = {}
    for line in text[head:].splitlines()[2:]:
        if not line.startswith("|"):
            break
        floor, packages = (cell.strip() for cell in line.strip("|").split("|")[:2])
        floors[int(floor)] = {f"grader.{name}" for name in re.findall(r"`([\w.]+)`", packages)}
    return floors


def test_the_floors_table_is_the_layers_contract() -> None:
    doc = _doc_floors((REPO / "docs" / "ARCHITECTURE.md").read_text())
    layers = dict(enumerate(_layers()))
    assert doc == layers, ("docs/ARCHITECTURE.md's floors table and pyproject's layers contract differ:\n"
                           + "\n".join(f"  floor {n}: doc {sorted(doc.get(n, ()))} vs pyproject {sorted(layers.get(n, ()))}"
                                       for n in sorted(set(doc) | set(layers)) if doc.get(n) != layers.get(n)))


def test_the_back_arrows_the_text_counts_are_the_contracts() -> None:
    text = " ".join((REPO / "docs" / "ARCHITECTURE.md").read_text().split())
    said = re.search(r"arrows that still run up a floor, .*?, (\d+) now", text)
    assert said, "ARCHITECTURE.md no longer says how many arrows still run up a floor"
    assert int(said.group(1)) == len(_contracts()["layers"].get("ignore_imports", []))


def test_front_ends_are_forbidden_every_engine_floor() -> None:
    floors = _layers()
    api = next(n for n, floor in enumerate(floors) if "grader.api" in floor)
    engine = set().union(*floors[:api]) - GROUND
    above = set().union(*floors[api + 1:])
    forbidden = _contracts()["forbidden"]
    assert set(forbidden["forbidden_modules"]) == engine
    assert set(forbidden["source_modules"]) == above - NOT_FRONT_ENDS
    assert forbidden.get("allow_indirect_imports") is True      # grader.api itself imports the engine
