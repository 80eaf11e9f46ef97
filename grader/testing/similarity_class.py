"""A Lab 3 class for the similarity tests and benchmark (grader.similarity), made from the fixtures.

Every member hands in its ``turtle_control`` package only (the rubric's support package is added
by the build), graded with the Lab 3 rubric cut down to the controller scenario
(``controller_rubric``), which places the turtle before each goal, so paths compare:

* ``orig``: ``fixtures/submissions/enee467_lab3/no_wrap`` (theta_e not wrapped: a buggy submission);
* ``copy_a``, ``copy_b``: ``orig`` renamed and reformatted (grader.testing.copies);
* ``rewritten``: ``orig``'s controller rewritten by hand (functions instead of a class, math instead
  of numpy, another setup.py), same constants and behaviour;
* ``known_copy``: the known public solution ``fixtures/similarity/enee467_lab3/known/`` renamed and
  reformatted;
* honest alternatives, all correct: ``honest_b`` and ``honest_c`` (written independently with the
  lab's suggested gains, K_1 = 0.5, K_2 = 1, and timer, 0.03 s: the two converge on one
  trajectory), ``alt_executors`` (K_1 = 0.45, K_2 = 1.5, a stop within 1 cm) and
  ``alt_rate_loop_threads`` (K_1 = 0.4, K_2 = 0.9 in a 30 Hz rate loop), main's Lab 3 ``alt_*``
  fixtures. (``alt_small_gains`` is left out: its 31-40 s per goal would double the test's time.
  The Lab 3 ``reference`` is left out too: ``no_wrap`` is that code with one line changed, so in
  this class it would rightly rank as one more copy.)
"""

from __future__ import annotations

import shutil
from pathlib import Path

import yaml

from grader.testing.copies import disguise_tree

REPO = Path(__file__).resolve().parents[2]
LAB3 = REPO / "fixtures" / "submissions" / "enee467_lab3"
SIM = REPO / "fixtures" / "similarity" / "enee467_lab3"
KNOWN = SIM / "known"
COPIES = {"orig", "copy_a", "copy_b", "rewritten"}      # one code: no_wrap's
HONEST = {"honest_b", "honest_c", "alt_executors", "alt_rate_loop_threads"}
#: the step timeout of the class test's rubric: the correct members settle on every goal within
#: 12 s; no_wrap never reaches the lab's first goal, and its copies need not spend the full 60 s
#: there to show it
TEST_STEP_TIMEOUT = 25


def controller_rubric(dest: Path, scenarios: tuple[str, ...] = ("ex2_controller",),
                      step_timeout: float | None = None) -> Path:
    """The Lab 3 rubric with only ``scenarios`` and their items (paths made absolute);
    ``step_timeout``: every goal step's timeout lowered to it (for a shorter test)."""
    src = REPO / "rubrics" / "enee467_lab3.yaml"
    doc = yaml.safe_load(src.read_text(encoding="utf-8"))
    doc["handout"] = str((src.parent / doc["handout"]).resolve())
    doc["support"] = {k: str((src.parent / v).resolve()) for k, v in doc["support"].items()}
    doc["scenarios"] = {k: v for k, v in doc["scenarios"].items() if k in scenarios}
    if step_timeout is not None:
        for sc in doc["scenarios"].values():
            for step in sc.get("steps") or ():
                if "goal" in step and step.get("timeout", 0) > step_timeout:
                    step["timeout"] = step_timeout
    items = []
    for item in doc["items"]:
        sc = item.get("scenario")
        if sc is None:
            continue
        kept = [s for s in ([sc] if isinstance(sc, str) else sc) if s in scenarios]
        if kept:
            item["scenario"] = kept
            items.append(item)
    doc["items"] = items
    used = {str(i["section"]) for i in items}
    doc["sections"] = [s for s in doc["sections"] if str(s["section"]) in used]
    for s in doc["sections"]:
        s["points"] = sum(i.get("points", 0) for i in items if str(i["section"]) == str(s["section"]))
    doc["total"] = sum(s["points"] for s in doc["sections"])
    doc.pop("late", None)
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return dest


def _package(src_ws: Path, dest: Path) -> None:
    shutil.copytree(src_ws / "src" / "turtle_control", dest / "src" / "turtle_control")


def build_class(root: Path) -> dict[str, Path]:
    """The class's submissions under ``root`` (one workspace each); id -> folder."""
    root = Path(root)
    subs: dict[str, Path] = {}
    _package(LAB3 / "no_wrap", root / "orig")
    for i, name in enumerate(("copy_a", "copy_b"), 1):
        disguise_tree(root / "orig" / "src", root / name / "src", seed=i)
    _package(SIM / "rewritten_no_wrap", root / "rewritten")
    disguise_tree(KNOWN / "public_turtle_lab3" / "src", root / "known_copy" / "src", seed=7)
    for name in ("alt_executors", "alt_rate_loop_threads"):
        _package(LAB3 / name, root / name)
    for name in ("honest_b", "honest_c"):
        _package(SIM / name, root / name)
    for p in sorted(root.iterdir()):
        subs[p.name] = p
    return subs


__all__ = ["COPIES", "HONEST", "KNOWN", "TEST_STEP_TIMEOUT", "build_class", "controller_rubric"]
