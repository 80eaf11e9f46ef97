"""The grader sizes itself by the cgroup it runs in, not by the host (issue 35): inside a group
of 0.5 CPU and 768 MB (Gradescope's default container) it finds the quota and the limit, runs one
scenario at a time, gives a scenario's student processes half its memory, and `grader doctor`
says what it found. A real child cgroup and real processes."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from grader.grading.schedule import default_jobs
from grader.sandbox import allotment
from grader.sandbox.allotment import Allotment
from grader.sandbox.scenario import default_memory_mb
from grader.testing.cgroup import limited_group

REPORT = """
import json
from grader.sandbox import allotment
from grader.grading.schedule import Slots, default_jobs
from grader.sandbox.scenario import SandboxPolicy
given = allotment.current()
print(json.dumps({"cpus": given.cpus, "quota": given.quota_cpus, "memory": given.memory_bytes,
                  "jobs": default_jobs(), "cores": Slots(4).cores, "student_mb": SandboxPolicy.from_env().memory_mb,
                  "line": allotment.describe(given), "throttled": allotment.throttled_s(given)}))
"""


def test_sizes_come_from_the_allotment() -> None:
    small = Allotment(cores=64, cpus=0.5, quota_cpus=0.5, memory_bytes=768 * 2**20)
    assert default_jobs(small) == 1 and small.slots == 1 and default_memory_mb(small) == 384
    two = Allotment(cores=2, cpus=2.0)
    assert default_jobs(two) == 4 and two.slots == 2 and default_memory_mb(two) == 2048
    # on simulated time a scenario takes about a CPU: one per CPU (0.5 CPU: still one)
    assert default_jobs(two, time_scale=4.0) == 2 and default_jobs(small, time_scale=4.0) == 1
    # memory bounds the jobs too: 1.5 GB holds five scenarios of 300 MB, eight CPUs would ask 16
    assert default_jobs(Allotment(cores=8, cpus=8.0, memory_bytes=1536 * 2**20)) == 5
    assert "CPU quota 0.5 of 64 cores (cgroup); memory limit 768 MiB (cgroup)" == allotment.describe(small)


def test_inside_a_small_cgroup_the_grader_sees_the_container_not_the_host() -> None:
    with limited_group(0.5, 768) as group:
        if group is None:
            pytest.skip("no writable cgroup with the cpu and memory controllers (run as root)")
        done = subprocess.run([sys.executable, "-c", REPORT], capture_output=True, text=True, timeout=60,
                              preexec_fn=group.join)
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout)
    assert seen["quota"] == 0.5 and seen["cpus"] == 0.5 and seen["memory"] == 768 * 2**20
    assert seen["jobs"] == 1 and seen["cores"] == 1 and seen["student_mb"] == 384
    assert seen["line"].startswith("CPU quota 0.5 of ") and "memory limit 768 MiB" in seen["line"]
    assert isinstance(seen["throttled"], float)
    # outside it, the same machine as before
    here = allotment.current()
    assert here.quota_cpus != 0.5 or here.memory_bytes != 768 * 2**20
