"""The Slurm example on a real Slurm: ``examples/slurm/grade_array.sbatch`` submitted on a
single-node cluster started for the test (``slurmcluster.py``: Debian's ``slurmctld`` + ``slurmd``,
torn down after), grading first-nodes fixtures as a job array of two shards, then the merge job
that Slurm starts when the array has ended; the merged output is compared, item for item, with
one local ``grader grade`` of the same submissions.

Four first-nodes fixtures (the reference at full marks, a subscriber that never spins, swapped
Twist fields, a slow timer), three and one in the shards: the lab with the shortest scenarios,
because what is tested is the array, the shards and the merge, not a lab (four Lab 3 fixtures took
674 s of CI's 90 minutes; every Lab 3 fixture is graded by ``tests/e2e/test_lab_fixtures.py``).
``make test-slurm`` runs only this file.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest
import slurmcluster

from grader.grading.shards import in_shard

REPO = Path(__file__).resolve().parents[2]
SBATCH = REPO / "examples" / "slurm" / "grade_array.sbatch"
LAB = REPO / "fixtures" / "submissions" / "first_nodes"
RUBRIC = REPO / "rubrics" / "first_nodes.yaml"
FIXTURES = ["reference", "no_spin", "swapped_twist", "slow_timer"]

pytestmark = [pytest.mark.slow, pytest.mark.heavy, pytest.mark.ros, pytest.mark.timeout(2400)]


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    if slurmcluster.missing():
        pytest.skip(f"Slurm is not installed ({', '.join(slurmcluster.missing())} missing): `make bootstrap` "
                    "as root installs Debian's slurmctld, slurmd and slurm-client")
    c = slurmcluster.start(tmp_path_factory.mktemp("slurm"))
    try:
        yield c
    finally:
        c.stop()


def _grader_command(tmp: Path) -> Path:
    """``grader`` as a command on the compute node: this checkout's grader, this interpreter."""
    path = tmp / "bin" / "grader"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"#!/bin/sh\nexec {sys.executable} -c 'import sys; from grader.cli import main; "
                    "sys.exit(main())' \"$@\"\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


def _items(out: Path) -> dict[str, list[tuple]]:
    """Per submission, each item's id, status and points (what a grade is made of; evidence and
    wording of measured values differ between two live runs)."""
    return {p.parent.name: [(i["id"], i["status"], i["points"], i["max_points"]) for i in json.loads(p.read_text())["items"]]
            for p in sorted(out.glob("*/result.json"))}


def _grades(out: Path) -> list[dict]:
    with open(out / "grades.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return sorted(({k: v for k, v in r.items() if not k.endswith("_s")} for r in rows), key=lambda r: r["submission"])


def test_slurm_array_then_merge_grades_like_one_local_batch(cluster, tmp_path: Path) -> None:
    subs = tmp_path / "subs"
    for name in FIXTURES:
        shutil.copytree(LAB / name, subs / name)
    shards = {k: sorted(n for n in FIXTURES if in_shard(n, k, 2)) for k in (1, 2)}
    assert shards[1] and shards[2], shards
    out = tmp_path / "graded"
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}, **cluster.env,
           "SUBMISSIONS": str(subs), "RUBRIC": str(RUBRIC), "OUT": str(out), "SHARDS": "2",
           "GRADER": str(_grader_command(tmp_path)), "GRADER_CACHE": str(tmp_path / "node-cache"),
           "TMPDIR": str(tmp_path), "GRADER_LOCK_DIR": f"/tmp/grader-domains-{os.getuid()}",
           # one CPU per task: both shards run side by side on a 2-core node
           "SBATCH_EXTRA": "--cpus-per-task=1 --mem=2G --partition=test",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    submit = subprocess.run(["bash", str(SBATCH)], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert submit.returncode == 0, submit.stderr + cluster.logs()
    assert "submitted shards as job array" in submit.stdout
    cluster.wait_idle(timeout=1800)
    logs = out.with_name("graded.shards") / "logs"
    task_logs = {p.name: p.read_text(errors="replace") for p in sorted(logs.glob("*.out"))}
    assert set(task_logs) == {"shard-1.out", "shard-2.out", "merge.out"}, task_logs
    assert "merged 4 submissions from 2 outputs" in task_logs["merge.out"], task_logs
    for k in (1, 2):       # each task graded its shard, under Slurm's own variables
        assert sorted(_items(out.with_name("graded.shards") / str(k))) == shards[k], task_logs[f"shard-{k}.out"]

    local = tmp_path / "local"
    done = subprocess.run([str(env["GRADER"]), "grade", str(subs), "--rubric", str(RUBRIC), "-o", str(local),
                           "--jobs", "2", "--cache-dir", str(tmp_path / "local-cache")],
                          env={k: v for k, v in env.items() if k != "SLURM_CONF"}, capture_output=True, text=True,
                          timeout=1800)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    merged, whole = _items(out), _items(local)
    assert sorted(merged) == sorted(FIXTURES)
    differ = {s: [(a, b) for a, b in zip(merged[s], whole[s]) if a != b] for s in merged if merged[s] != whole[s]}
    assert not differ, differ
    assert _grades(out) == _grades(local)
    assert json.loads((out / "reference" / "result.json").read_text())["auto_score"] == 20
