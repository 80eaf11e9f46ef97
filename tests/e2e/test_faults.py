"""The fault corpus: hostile and broken submissions graded in one batch per lab beside an honest one.

Goal-setter lab: each gets its expected result (fixtures/faults/expected.yaml) in bounded time;
afterwards no process of the batch is alive, and nothing outside the batch's output folder
changed: not the repository (rubrics, fixtures, the grader's sources), not an earlier batch's
results, not HOME or /tmp. Lab 3 (fixtures/faults/enee467_lab3/expected.yaml): cheating
controllers in the lab whose grader teleports the turtle itself, beside the Lab 3 reference.
See fixtures/faults/README.md.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sysconfig
from pathlib import Path

import pytest
import yaml

from grader.cli import main as grader_main

REPO = Path(__file__).resolve().parents[2]
FAULTS = REPO / "fixtures" / "faults"
SPEC = yaml.safe_load((FAULTS / "expected.yaml").read_text())
MARK = "grader-fault-"
LAB3 = FAULTS / "enee467_lab3"
LAB3_SPEC = yaml.safe_load((LAB3 / "expected.yaml").read_text())


def plant_links(folder: Path) -> None:
    """``symlink_folder``'s hostile links (fixtures/faults/make_archives.py)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("fault_archives", FAULTS / "make_archives.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.plant_links(folder)


# the module's batch fixture counts in its first test's limit: the goal-setter corpus took 37 min
# beside two other heavy sessions on a loaded 2-core machine (2026-12-02), over the 30 it had
pytestmark = [pytest.mark.slow, pytest.mark.heavy, pytest.mark.ros, pytest.mark.timeout(3600)]


def tree_state(*roots: Path) -> dict[str, str]:
    out = {}
    for root in roots:
        for f in sorted(root.rglob("*")):
            if f.is_file() and not f.is_symlink() and "__pycache__" not in f.parts:
                out[str(f)] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


def fault_processes() -> list[str]:
    found = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            try:
                cmd = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if MARK in cmd and "pytest" not in cmd:
                found.append(f"{proc.name}: {cmd[:120]}")
    return found


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("faults")
    subs = root / "subs"
    # the corpus's own files (README, expected.yaml, make_archives.py) stay behind; the
    # submissions are copied whole (their setup.py and YAML included)
    shutil.copytree(FAULTS, subs, symlinks=True,
                    ignore=lambda d, names: [n for n in names if Path(d) == FAULTS and Path(d, n).is_file()
                                             and not n.endswith((".zip", ".tar.gz"))])
    plant_links(subs / "symlink_folder")          # its links to /etc/passwd and / (never committed)
    huge = subs / "huge_file"
    shutil.copytree(FAULTS / "honest", huge)
    with open(huge / "src" / "turtle_goal" / "recording.bag", "wb") as f:     # 300 MB, sparse
        f.truncate(300 * 2**20)
    shutil.rmtree(subs / LAB3.name)                          # the Lab 3 corpus is a batch of its own
    earlier = root / "earlier_batch"                         # an earlier batch's results nearby
    (earlier / "alice").mkdir(parents=True)
    (earlier / "alice" / "result.json").write_text('{"auto_score": 3}')
    (earlier / "grades.csv").write_text("submission,auto_total\nalice,3\n")
    watched = [REPO / "rubrics", REPO / "fixtures", REPO / "grader", earlier]
    before = tree_state(*watched)
    home_before = sorted(p.name for p in Path.home().iterdir())
    out = root / "out"
    os.environ["GRADER_TEST_SECRET"] = "caller-secret-7f3a"       # must not reach student code
    rc = grader_main(["grade", str(subs), "--rubric", str(REPO / "rubrics" / "goal_setter.yaml"), "-o", str(out),
                      "--jobs", "3", "--no-reuse", "--cache-dir", str(root / "cache")])
    os.environ.pop("GRADER_TEST_SECRET", None)
    return {"rc": rc, "out": out, "before": before, "after": tree_state(*watched),
            "home_before": home_before, "home_after": sorted(p.name for p in Path.home().iterdir())}


def result(batch: dict, sid: str) -> dict:
    return json.loads((batch["out"] / sid / "result.json").read_text())


def test_the_batch_finishes(batch: dict) -> None:
    assert batch["rc"] == 0


def differences(res: dict, want: dict) -> list[str]:
    """Items of ``res`` whose status is not the expected one (``warn``: fail or partial)."""
    got = {i["id"]: i for i in res["items"]}
    bad = []
    for item, expected in want.items():
        allowed = expected if isinstance(expected, list) else [expected]
        allowed = {("fail" if a == "warn" else a) for a in allowed} | ({"partial"} if "warn" in allowed else set())
        if got[item]["status"] not in allowed:
            bad.append(f"{item}: expected {expected}, got {got[item]['status']}: {got[item]['feedback'][:160]}")
    return bad


@pytest.mark.parametrize("fault", [*SPEC["faults"], "huge_file"])
def test_each_fault_grades_as_expected(batch: dict, fault: str) -> None:
    want = SPEC["faults"].get(fault, SPEC["faults"]["honest"])["expected"]
    bad = differences(result(batch, fault), want)
    assert not bad, f"{fault}:\n" + "\n".join(bad)


def test_nothing_of_the_batch_is_left_running(batch: dict) -> None:
    assert fault_processes() == []


def test_nothing_outside_the_output_changed(batch: dict) -> None:
    changed = sorted(set(batch["before"]) ^ set(batch["after"]) |
                     {k for k in batch["before"] if batch["after"].get(k) != batch["before"][k]})
    assert changed == []
    assert batch["home_after"] == batch["home_before"]
    assert not list(Path("/tmp").glob(f"{MARK}*"))
    assert not list(batch["out"].parent.glob(f"**/{MARK}*"))
    site = Path(sysconfig.get_paths()["purelib"])            # the venv every student process runs in
    assert not list(site.glob(f"{MARK}*"))
    for planted in (site / "sitecustomize.py", site / "grader" / "__init__.py"):
        assert not planted.exists() or MARK not in planted.read_text()


def test_every_result_is_the_graders(batch: dict) -> None:
    """No submission rewrote another's result: every seal checks out."""
    from grader.report.batch import load_results
    assert len(load_results(batch["out"])) == len(SPEC["faults"]) + 1


def test_the_reasons_are_in_the_results(batch: dict) -> None:
    def problems(sid: str) -> str:
        return json.dumps(result(batch, sid).get("errors", [])) + json.dumps(result(batch, sid)["items"])

    assert "symbolic link" in problems("symlink_folder")
    linked = json.dumps(result(batch, "symlink_folder"))
    assert "rootdir -> /" in linked and "leak -> /etc/passwd" in linked       # the planted links were met
    assert "outside the archive" in problems("zip_slip") and "symbolic link" in problems("zip_slip")
    assert "link" in problems("symlink_tar")
    assert "MiB" in problems("huge_file")
    assert "memory" in problems("memory_hog").lower()
    flood_log = sum(f.stat().st_size for f in (batch["out"] / "output_flood").glob("scenarios/*/logs/*.log"))
    assert flood_log < 50 * 2**20
    assert "output" in problems("output_flood").lower()
    snooped = "".join(f.read_text(errors="replace") for f in (batch["out"] / "read_rubric").glob("scenarios/*/logs/*"))
    assert "Goal setter service, turtle controller and launch file" not in snooped      # the rubric's title
    assert "SNOOPED ENV" in snooped and "caller-secret-7f3a" not in snooped     # a minimal environment
    tampered = "".join(f.read_text(errors="replace") for f in (batch["out"] / "autograder_tamper").glob("scenarios/*/logs/*"))
    assert "TAMPER run start" in tampered and "sitecustomize.py: " in tampered and ": done" not in tampered
    assert "SNOOPED" not in tampered
    # the planted module of interface_import ran in its nodes (their jail) and in no grader process
    # (those would also have left its marker in /tmp: test_nothing_outside_the_output_changed)
    scen = batch["out"] / "interface_import" / "scenarios"
    planted = "".join(f.read_text(errors="replace") for f in scen.glob("*/logs/*.log"))
    assert "PLANTED IMPORT uid 65534" in planted or ("PLANTED IMPORT" in planted and os.geteuid() != 0)
    assert "PLANTED IMPORT" not in "".join(f.read_text(errors="replace") for f in scen.glob("*/scenario.log"))
    assert not [f for f in scen.glob("*/logs/*") if "PLANTED IMPORT" in f.read_text(errors="replace")
                and "turtlesim" in f.name]


# --------------------------------------------------------------------------- Lab 3: the grader teleports too
@pytest.fixture(scope="module")
def lab3_batch(tmp_path_factory) -> dict:
    """The Lab 3 faults and the Lab 3 reference (``honest``), graded in one batch."""
    root = tmp_path_factory.mktemp("faults-lab3")
    subs = root / "subs"
    shutil.copytree(LAB3, subs, ignore=lambda d, names: [n for n in names if Path(d) == LAB3 and Path(d, n).is_file()])
    shutil.copytree(REPO / "fixtures" / "submissions" / "enee467_lab3" / "reference", subs / "honest",
                    ignore=shutil.ignore_patterns("expected.yaml", "README.md"))
    out = root / "out"
    rc = grader_main(["grade", str(subs), "--rubric", str(REPO / "rubrics" / "enee467_lab3.yaml"), "-o", str(out),
                      "--jobs", "3", "--no-reuse", "--cache-dir", str(root / "cache")])
    return {"rc": rc, "out": out, "root": root}


@pytest.mark.ci
def test_the_lab3_batch_finishes_and_leaves_nothing_running(lab3_batch: dict) -> None:
    assert lab3_batch["rc"] == 0
    mark = str(lab3_batch["root"])
    left = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            try:
                cmd = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if mark in cmd and "pytest" not in cmd:
                left.append(f"{proc.name}: {cmd[:120]}")
    assert left == []


@pytest.mark.ci
@pytest.mark.parametrize("fault", [*LAB3_SPEC["faults"]])
def test_each_lab3_fault_grades_as_expected(lab3_batch: dict, fault: str) -> None:
    bad = differences(result(lab3_batch, fault), LAB3_SPEC["faults"][fault]["expected"])
    assert not bad, f"{fault}:\n" + "\n".join(bad)


@pytest.mark.ci
def test_the_lab3_teleport_earns_nothing_and_the_honest_one_everything(lab3_batch: dict) -> None:
    """The acceptance line of issue 17: the teleport fault earns 0 of ex2.goals_reached and is
    flagged; the reference beside it keeps every point."""
    items = {i["id"]: i for i in result(lab3_batch, "teleport")["items"]}
    goals = items["ex2.goals_reached"]
    assert goals["points"] == 0 and "student code" in goals["feedback"], goals["feedback"]
    assert items["integrity.no_teleport"]["status"] == "fail"
    honest = result(lab3_batch, "honest")
    assert honest["auto_score"] == honest["auto_max"] == 50, \
        [(i["id"], i["points"], i["max_points"]) for i in honest["items"] if i["points"] != i["max_points"]]


@pytest.mark.ci
def test_the_lab3_reasons_are_true(lab3_batch: dict) -> None:
    def item(sid: str, iid: str) -> dict:
        return next(i for i in result(lab3_batch, sid)["items"] if i["id"] == iid)

    assert "/reset called by student code" in item("reset", "ex2.goals_reached")["feedback"]
    assert "/reset" in item("reset", "integrity.no_teleport")["feedback"]
    fake = item("fake_pose", "ex2.goals_reached")["feedback"]
    assert "the simulator never published were ignored" in fake, fake
    assert "never published" in item("fake_pose", "integrity.pose_publisher")["feedback"]
