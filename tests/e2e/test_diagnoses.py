"""Every diagnosis is true: each cause gets its own message, and a look-alike with another cause
gets another.

``fixtures/diagnoses/<lab>/<case>/`` holds small workspaces: a ``diagnosis.yaml`` naming the
submission it starts from (``base``), the files it changes (the case's own ``src/`` overlays the
base; ``remove`` deletes), the cause in words, its ``lookalike`` (another case whose symptom is
similar and whose cause differs) and, per item, the status and a regular expression of the
feedback the student must read. Each case is graded for real (build, simulator, bag), on only the
items it names (so only their scenarios run, shortened to the ``steps`` listed), all labs side by
side within one budget of 4 concurrent scenarios.
"""

from __future__ import annotations

import re
import shutil
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import yaml

from grader.rubric import load_rubric

REPO = Path(__file__).resolve().parents[2]
ROOT = REPO / "fixtures" / "diagnoses"
RUBRICS = {"enee467_lab3": "enee467_lab3.yaml", "goal_setter": "goal_setter.yaml",
           "first_nodes": "first_nodes.yaml", "wall_pen": "wall_pen.yaml"}
CASES = sorted((lab.name, case.name) for lab in ROOT.iterdir() if lab.is_dir()
               for case in lab.iterdir() if (case / "diagnosis.yaml").exists())
ITEMS = [(lab, case, item) for lab, case in CASES
         for item in yaml.safe_load((ROOT / lab / case / "diagnosis.yaml").read_text())["expect"]]

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(1800)]


def spec(lab: str, case: str) -> dict:
    return yaml.safe_load((ROOT / lab / case / "diagnosis.yaml").read_text())


def materialize(lab: str, case: str, into: Path) -> Path:
    """The base submission with the case's files laid over it."""
    folder, s = ROOT / lab / case, spec(lab, case)
    ws = into / f"{lab}-{case}"
    shutil.copytree((folder / s["base"]).resolve(), ws, ignore=shutil.ignore_patterns("expected.yaml", "README.md"))
    for rel in s.get("remove", []):
        (ws / rel).unlink()
    if (folder / "src").is_dir():
        shutil.copytree(folder / "src", ws / "src", dirs_exist_ok=True)
    return ws


def only(rubric, s: dict):
    """The rubric reduced to the case's items (and those they require), its scenarios to the
    steps listed: what the case is about, and nothing that costs time besides."""
    wanted = set(s["expect"])
    wanted |= {r for i in rubric.items if i.id in wanted for r in i.requires}
    scenarios = dict(rubric.scenarios)
    for sc, keep in (s.get("steps") or {}).items():
        scenarios[sc] = scenarios[sc].model_copy(update={"steps": tuple(st for st in scenarios[sc].steps
                                                                        if st.id in keep)})
    return rubric.model_copy(update={"items": tuple(i for i in rubric.items if i.id in wanted),
                                     "scenarios": scenarios})


@pytest.fixture(scope="session")
def graded(tmp_path_factory) -> dict[tuple[str, str], dict[str, dict]]:
    from grader.grading.pipeline import grade_submission
    from grader.grading.schedule import Slots
    from grader.report.result import result_to_dict

    root = tmp_path_factory.mktemp("diagnoses")
    slots = Slots(4)

    def grade(lab_case: tuple[str, str]) -> dict[str, dict]:
        lab, case = lab_case
        rubric = only(load_rubric(REPO / "rubrics" / RUBRICS[lab]), spec(lab, case))
        done = grade_submission(materialize(lab, case, root / "ws"), rubric, root / "out", sid=f"{lab}-{case}",
                                slots=slots, cache_dir=root / "cache")
        return {i["id"]: i for i in result_to_dict(done.result, done.id)["items"]}

    with ThreadPoolExecutor(max_workers=len(CASES)) as pool:
        return dict(zip(CASES, pool.map(grade, CASES)))


def test_every_case_says_its_cause_and_its_lookalike_exists() -> None:
    for lab, case in CASES:
        s = spec(lab, case)
        assert lab in RUBRICS and s.get("cause") and s.get("expect"), (lab, case)
        assert (ROOT / lab / case / s["base"] / "src").is_dir(), (lab, case)
        if s.get("lookalike"):
            assert (lab, s["lookalike"]) in CASES, (lab, case)
        items = set(load_rubric(REPO / "rubrics" / RUBRICS[lab]).item_ids)
        assert set(s["expect"]) <= items, (lab, case)


@pytest.mark.parametrize("lab,case,item", ITEMS)
def test_the_student_reads_the_true_cause(graded, lab: str, case: str, item: str) -> None:
    want = spec(lab, case)["expect"][item]
    got = graded[(lab, case)][item]
    assert got["status"] == want["status"] and re.search(want["message"], got["feedback"]), \
        f"{lab}/{case} {item}: expected {want['status']} /{want['message']}/, got {got['status']}: {got['feedback']}"


@pytest.mark.parametrize("lab,case", [c for c in CASES if spec(*c).get("lookalike")])
def test_a_lookalike_gets_its_own_message(graded, lab: str, case: str) -> None:
    other = spec(lab, case)["lookalike"]
    shared = {i for i, want in spec(lab, case)["expect"].items() if want["status"] != "pass"} & set(graded[(lab, other)])
    assert shared, f"{lab}/{case} and its look-alike {other} share no item"
    for item in shared:
        mine, theirs = graded[(lab, case)][item]["feedback"], graded[(lab, other)][item]["feedback"]
        assert mine != theirs and not re.search(spec(lab, case)["expect"][item]["message"], theirs), \
            f"{lab}: {case} and {other} read alike on {item}: {mine!r} / {theirs!r}"
