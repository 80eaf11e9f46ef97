"""The cluster examples, exercised as far as this machine allows.

``examples/slurm/grade_array.sbatch``: checked with ``bash -n``; its submit step run against a
stand-in ``sbatch`` (it must submit the array, then a merge job depending on it); its array tasks
and its merge step run for real with the variables Slurm sets, on three small submissions, and
their merged output compared with one unsharded ``grader grade``.
``examples/github-classroom/grader-check.yml``: validated against SchemaStore's GitHub Actions
workflow schema (``tests/scale/data``), and its ``grader`` command lines parsed by grader itself.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from grader.grading.shards import in_shard

REPO = Path(__file__).resolve().parents[2]
SBATCH = REPO / "examples" / "slurm" / "grade_array.sbatch"
WORKFLOW = REPO / "examples" / "github-classroom" / "grader-check.yml"
DATA = Path(__file__).resolve().parent / "data"
FIRST_NODES = REPO / "fixtures" / "submissions" / "first_nodes"


def _executable(path: Path, text: str) -> Path:
    path.write_text(text)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


def _grader_command(tmp: Path) -> Path:
    """A ``grader`` executable running this checkout's grader with this interpreter."""
    return _executable(tmp / "grader", f"#!/bin/sh\nexec {sys.executable} -c "
                       "'import sys; from grader.cli import main; sys.exit(main())' \"$@\"\n")


def _run_sbatch(env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess:
    base = {k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}
    base["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    return subprocess.run(["bash", str(SBATCH)], env={**base, **env}, cwd=cwd, capture_output=True,
                          text=True, timeout=900)


def test_sbatch_script_is_valid_bash() -> None:
    subprocess.run(["bash", "-n", str(SBATCH)], check=True)


def test_sbatch_submits_the_array_then_a_merge_job_that_waits_for_it(tmp_path: Path) -> None:
    calls = tmp_path / "calls"
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    # a stand-in sbatch: records its arguments, answers with a job id like `sbatch --parsable`
    _executable(bin_dir / "sbatch", f"#!/bin/sh\necho \"$*\" >> {calls}\n"
                "n=$(wc -l < " + str(calls) + ")\necho \"$((4200 + n));cluster\"\n")
    done = _run_sbatch({"PATH": f"{bin_dir}:{os.environ['PATH']}", "SUBMISSIONS": "subs", "RUBRIC": "r.yaml",
                        "OUT": str(tmp_path / "graded"), "SHARDS": "3", "SBATCH_EXTRA": "--partition=short"},
                       tmp_path)
    assert done.returncode == 0, done.stderr
    array, merge = calls.read_text().splitlines()
    assert "--array=1-3" in array and "--partition=short" in array and array.endswith(str(SBATCH))
    assert "--dependency=afterany:4201" in merge and "GRADER_STEP=merge" in merge and "SHARDS=3" in merge
    assert "job array 4201 and the merge as job 4202" in done.stdout
    assert (tmp_path / "graded.shards" / "logs").is_dir()


def test_sbatch_tells_what_is_missing(tmp_path: Path) -> None:
    done = _run_sbatch({"RUBRIC": "r.yaml", "OUT": "o"}, tmp_path)
    assert done.returncode != 0 and "set SUBMISSIONS to the folder of submissions" in done.stderr


def _items(out: Path) -> dict[str, list]:
    return {p.parent.name: json.loads(p.read_text())["items"] for p in sorted(out.glob("*/result.json"))}


@pytest.mark.slow
@pytest.mark.heavy
@pytest.mark.ros
def test_sbatch_array_tasks_and_merge_grade_like_one_run(tmp_path: Path) -> None:
    subs = tmp_path / "subs"
    names = ["chapter", "print_greeting", "reference"]
    for name in names:
        shutil.copytree(FIRST_NODES / name, subs / name)
    assert {n for n in names if in_shard(n, 1, 2)} and {n for n in names if in_shard(n, 2, 2)}
    rubric = DATA / "hello.yaml"
    common = {"SUBMISSIONS": str(subs), "RUBRIC": str(rubric), "OUT": str(tmp_path / "graded"),
              "SHARDS": "2", "GRADER": str(_grader_command(tmp_path)),
              "GRADER_CACHE": str(tmp_path / "cache"), "TMPDIR": str(tmp_path)}
    for k in (1, 2):      # the array's tasks, one after the other, as Slurm would start them
        task = _run_sbatch({**common, "SLURM_ARRAY_TASK_ID": str(k), "SLURM_ARRAY_TASK_COUNT": "2",
                            "SLURM_CPUS_PER_TASK": "1"}, tmp_path)
        assert task.returncode == 0, task.stdout[-2000:] + task.stderr[-2000:]
        graded = set(_items(tmp_path / "graded.shards" / str(k)))
        assert graded == {n for n in names if in_shard(n, k, 2)}
    merge = _run_sbatch({**common, "GRADER_STEP": "merge"}, tmp_path)
    assert merge.returncode == 0, merge.stderr
    assert "merged 3 submissions from 2 outputs" in merge.stdout

    whole = tmp_path / "whole"
    done = subprocess.run([str(common["GRADER"]), "grade", str(subs), "--rubric", str(rubric), "-o", str(whole),
                           "--cache-dir", str(tmp_path / "cache")], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    merged = _items(tmp_path / "graded")
    assert set(merged) == set(names)
    strip = {"evidence", "params"}      # node start times and the like differ between runs
    assert {s: [{k: v for k, v in i.items() if k not in strip} for i in items] for s, items in merged.items()} == \
           {s: [{k: v for k, v in i.items() if k not in strip} for i in items] for s, items in _items(whole).items()}
    assert (tmp_path / "graded" / "grades.csv").read_text().splitlines()[1:] == \
           (whole / "grades.csv").read_text().splitlines()[1:]


class _WorkflowLoader(yaml.SafeLoader):
    """YAML as GitHub reads workflows: ``on``/``off``/``yes``/``no`` are strings (YAML 1.2), only
    ``true``/``false`` are booleans."""


_WorkflowLoader.yaml_implicit_resolvers = {
    k: [(tag, rx) for tag, rx in v if tag != "tag:yaml.org,2002:bool"]
    for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_WorkflowLoader.add_implicit_resolver("tag:yaml.org,2002:bool", __import__("re").compile(r"^(?:true|false)$"),
                                      list("tf"))


def _workflow() -> dict:
    return yaml.load(WORKFLOW.read_text(), Loader=_WorkflowLoader)  # noqa: S506 - a safe loader


def test_classroom_workflow_is_valid_for_github_actions() -> None:
    import jsonschema

    schema = json.loads((DATA / "github-workflow.schema.json").read_text())
    validator = jsonschema.Draft7Validator(schema)
    doc = _workflow()
    assert set(doc["on"]) == {"push", "workflow_dispatch"}
    assert [e.message for e in validator.iter_errors(doc)] == []
    # the schema does catch mistakes: a step that both runs and uses, a misspelt key, no trigger
    for path, value in ((("jobs", "check", "steps", 0, "run"), "echo both"),
                        (("jobs", "check", "run-on"), "ubuntu-24.04"), (("on",), None)):
        broken = json.loads(json.dumps(doc))
        *parents, last = path
        target = broken
        for key in parents:
            target = target[key]
        if value is None:
            del target[last]
        else:
            target[last] = value
        assert list(validator.iter_errors(broken)), path


def test_classroom_workflow_runs_grader_check_and_keeps_the_report() -> None:
    import shlex

    from grader.cli import build_parser
    from grader.labs import rubric_for_lab

    doc = _workflow()
    steps = doc["jobs"]["check"]["steps"]
    env = doc["env"]
    commands = [line.strip() for s in steps for line in str(s.get("run", "")).splitlines()
                if "bin/grader " in line]
    check = next(c for c in commands if " check " in c)
    argv = shlex.split(check.split("|")[0].replace('"$GRADER_LAB"', env["GRADER_LAB"]))[1:]
    args = build_parser().parse_args(argv)
    assert args.func.__name__ == "run_check" and args.out == Path("grader-report")
    assert rubric_for_lab(args.lab).is_file()
    assert any(c.endswith("grader setup") for c in commands)
    upload = next(s for s in steps if str(s.get("uses", "")).startswith("actions/upload-artifact@"))
    assert upload["if"] == "always()" and "grader-report/" in upload["with"]["path"]


def _step_script(name: str) -> str:
    return next(s for s in _workflow()["jobs"]["check"]["steps"] if s.get("name") == name)["run"]


def test_classroom_runner_result_is_what_the_reporter_reads(tmp_path: Path) -> None:
    """The runner document of a result.json: the fields GitHub Classroom's reporter reads, and
    the points it reports (the sum of the tests' scores over max_score)."""
    import base64

    from grader.lms.classroom import points, step_output

    section = {"section": {"exercise": 1}, "public": True}
    doc = {"schema": 1, "submission": "check", "lab": "l", "title": "L", "view": "student", "score": 6.5,
           "auto_score": 6.5, "auto_max": 10, "max_score": 10, "manual_max": 0, "pending_max": 0, "total": 6.5,
           "complete": True, "items": [
        {"id": "ex1.a", "title": "A", "kind": "auto", "status": "pass", "points": 4, "max_points": 4, "feedback": "ok", **section},
        {"id": "ex1.b", "title": "B", "kind": "auto", "status": "partial", "points": 2.5, "max_points": 6,
         "feedback": "half", "hint": "use math.log", **section},
        {"id": "ex1.c", "title": "C", "kind": "advisory", "status": "fail", "points": 0, "max_points": 0, "feedback": "",
         **section}]}
    (tmp_path / "result.json").write_text(json.dumps(doc))
    line, runner = step_output(tmp_path / "result.json")
    assert line.startswith("result=")
    decoded = json.loads(base64.b64decode(line.removeprefix("result=")))
    assert decoded == runner and runner["status"] == "fail" and runner["max_score"] == 10
    assert [(t["name"], t["status"], t["score"]) for t in runner["tests"]] == [("ex1.a: A", "pass", 4), ("ex1.b: B", "fail", 2.5)]
    assert "Hint: use math.log" in runner["tests"][1]["message"]
    assert points(runner) == (6.5, 10)
    _, missing = step_output(tmp_path / "nothing.json")
    assert missing["status"] == "error" and points(missing) == (0, 0)


@pytest.mark.slow
@pytest.mark.heavy
@pytest.mark.ros
@pytest.mark.timeout(1200)
def test_classroom_workflow_steps_report_the_points(tmp_path: Path) -> None:
    """The workflow's own `grader` and Summary steps, run as GitHub runs a `run:` step (bash -eo
    pipefail, GITHUB_OUTPUT and GITHUB_STEP_SUMMARY files), in a student repository holding a Lab 3
    submission with a Box-Muller mistake: the step succeeds with a failing check, its output is
    the runner the reporter reads, and the points it would send to Classroom are grader's. Not run
    here: the checkout, setup-python, cache and install steps (GitHub's own actions; the install is
    what tests/packaging tests) and the reporter action itself (JavaScript fetched from GitHub)."""
    import base64

    from grader.lms.classroom import points

    repo = tmp_path / "student-repo"
    shutil.copytree(REPO / "fixtures" / "submissions" / "enee467_lab3" / "bm_log10" / "src", repo / "src")
    home = tmp_path / "home"
    home.mkdir()
    (home / "grader-venv").symlink_to(Path(sys.prefix))       # what the Install step leaves in ~/grader-venv
    output, summary = tmp_path / "github_output", tmp_path / "step_summary"
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("GITHUB_")}, "HOME": str(home),
           "GITHUB_OUTPUT": str(output), "GITHUB_STEP_SUMMARY": str(summary), **_workflow()["env"],
           "GRADER_CACHE": str(tmp_path / "cache")}
    for name in ("grader check", "Summary"):
        script = tmp_path / f"{name.replace(' ', '_')}.sh"
        script.write_text(_step_script(name))
        done = subprocess.run(["bash", "--noprofile", "--norc", "-eo", "pipefail", str(script)], cwd=repo, env=env,
                              capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"{name}: {done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    outputs = dict(line.split("=", 1) for line in output.read_text().splitlines())
    runner = json.loads(base64.b64decode(outputs["result"]))
    result = json.loads((repo / "grader-report" / "check" / "result.json").read_text())
    assert runner["status"] == "fail"                      # the reporter fails the run
    assert points(runner) == (result["auto_score"], result["auto_max"]) and 0 < result["auto_score"] < result["auto_max"]
    boxmuller = next(t for t in runner["tests"] if t["name"].startswith("ex1.boxmuller"))
    assert boxmuller["status"] == "fail" and "log10" in boxmuller["message"]
    assert "ex1.boxmuller" in summary.read_text()
