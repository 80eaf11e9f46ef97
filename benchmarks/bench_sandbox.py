"""What the sandbox costs, measured side by side with it off (``GRADER_SANDBOX=off``).

1. its parts: the probe, a cgroup made and removed, bubblewrap (+ setpriv + env) around a
   ``python -c pass``, ``unshare`` + ``enter.py`` around one;
2. one scenario (reference simulator, recorder, driver and one student rclpy node publishing at
   20 Hz), runs alternating on/off: the scenario's wall time and how long after its start the
   student's first message reached the bag (DDS discovery across the sandbox). Target: the
   sandbox adds under 1 s per scenario;
3. ``grader grade fixtures/submissions/enee467_lab3 --only reference`` (the CLI, build cached,
   ``--no-reuse``: every scenario recorded again),
   runs alternating on/off. Target: the grading time changes by less than 5 %; the scores are
   identical.

    .venv/bin/python benchmarks/bench_sandbox.py [--scenario-runs 6] [--grade-runs 3] [--skip-grade]

Measured on the shared 2-core development machine (bubblewrap 0.8, cgroup v1 + v2 hybrid):
probe 40-70 ms once per process; bubblewrap + setpriv + env +1 to +12 ms per student process;
unshare + enter.py +17 to +27 ms per scenario; one scenario +0.09 s (median of 6 alternating
runs; first student message 0.43 s after its start with, 0.88 s without); Lab 3 reference
103.3 s with, 103.1 s without (ratio 1.002, 3 alternating runs), identical item results.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

TALKER = '''
import time, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("bench_talker")
pub = node.create_publisher(String, "/student_chatter", 10)
node.create_timer(0.05, lambda: pub.publish(String(data="x")))
try:
    rclpy.spin(node)
except BaseException:
    pass
'''


def _median_ms(fn, n: int) -> float:
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1000


def parts() -> None:
    from grader.sandbox import cgroups, probe
    from grader.sandbox.jail import prepare
    from grader.sandbox.scenario import ENTER, SandboxPolicy, student_jail

    t0 = time.perf_counter()
    probe.cache_clear()
    caps = probe()
    print(f"probe (every tool tried once per process): {(time.perf_counter() - t0) * 1000:.0f} ms")
    if caps.cgroups.bases:
        def cg() -> None:
            g = cgroups.CgroupSet.create(caps.cgroups, f"grader-{os.getpid()}-bench")
            g.child("students").set_limits(memory_bytes=2**30, pids=512, cpus=1.0)
            g.remove()
        print(f"cgroup set made, limited and removed: {_median_ms(cg, 20):.1f} ms")
    plain = [sys.executable, "-S", "-c", "pass"]
    base = _median_ms(lambda: subprocess.run(plain, check=True), 20)
    print(f"python -S -c pass: {base:.1f} ms")
    if caps.bwrap:
        p = prepare(student_jail(caps, SandboxPolicy()), plain, {})
        jailed = _median_ms(lambda: subprocess.run(p.argv, env=p.env, cwd=p.cwd, preexec_fn=p.preexec,
                                                   check=True), 20)
        print(f"  in bubblewrap (+ setpriv + env): {jailed:.1f} ms (+{jailed - base:.1f} ms per student process)")
    if caps.netns:
        ns = ["unshare", "--net", "--pid", "--fork", "--kill-child", "--mount-proc", sys.executable, "-S",
              str(ENTER), "--loopback", "--", *plain]
        netns = _median_ms(lambda: subprocess.run(ns, check=True), 20)
        print(f"  as PID 1 of new network+PID namespaces: {netns:.1f} ms (+{netns - base:.1f} ms per scenario)")


def _scenario(tmp: Path, i: int, sandbox: bool) -> tuple[float, float]:
    from grader.bag.frames import load_frames
    from grader.scenario import run_scenario
    from grader.scenario.model import Scenario
    from grader.scenario.runspec import LaunchedProcess, ScenarioRun

    prefix = tmp / "build" / "install" / "bench"
    (prefix / "lib").mkdir(parents=True, exist_ok=True)
    (prefix / "lib" / "talker.py").write_text(TALKER)
    scenario = Scenario.model_validate({
        "record": ["/student_chatter", "/turtle1/pose"],
        "processes": [{"name": "talker", "package": "bench", "module": "talker:main"}],
        "steps": [{"id": "talk", "until": {"condition": "messages", "topic": "/student_chatter", "count": 20},
                   "timeout": 20}]})
    run = ScenarioRun(id="bench", scenario=scenario, prefixes=(str(prefix),), launched={"talker": (
        LaunchedProcess(name="talker", process="talker", argv=(sys.executable, str(prefix / "lib" / "talker.py"))),)})
    os.environ["GRADER_SANDBOX"] = "auto" if sandbox else "off"
    out = tmp / f"run{i}-{'on' if sandbox else 'off'}"
    t0 = time.monotonic()
    record = run_scenario(run, out)
    wall = time.monotonic() - t0
    if record["errors"]:
        raise SystemExit(f"scenario failed: {record['errors']}")
    frames = load_frames(out / "bag", topics=["/student_chatter", "/grader/events"])
    start = next(json.loads(d)["wall"] for d in frames["/grader/events"]["data"]
                 if json.loads(d)["event"] == "node_started")
    return wall, frames["/student_chatter"].index[0] - start


def scenarios(runs: int) -> None:
    rows: dict[bool, list[tuple[float, float]]] = {True: [], False: []}
    with tempfile.TemporaryDirectory(prefix="bench-sandbox-") as tmp:
        for i in range(runs):
            for sandbox in ((True, False) if i % 2 == 0 else (False, True)):
                rows[sandbox].append(_scenario(Path(tmp), i, sandbox))
                wall, first = rows[sandbox][-1]
                print(f"  scenario run {i + 1} sandbox {'on ' if sandbox else 'off'}: wall {wall:5.2f} s, "
                      f"first student message {first:5.2f} s after its start", flush=True)
    on = statistics.median(w for w, _ in rows[True])
    off = statistics.median(w for w, _ in rows[False])
    first_on = statistics.median(f for _, f in rows[True])
    first_off = statistics.median(f for _, f in rows[False])
    print(f"scenario wall: median {on:.2f} s on, {off:.2f} s off: {on - off:+.2f} s per scenario "
          f"(target < 1 s); first student message: {first_on:.2f} s on, {first_off:.2f} s off")


def grade(runs: int) -> int:
    sub = REPO / "fixtures" / "submissions" / "enee467_lab3"
    rubric = REPO / "rubrics" / "enee467_lab3.yaml"
    walls: dict[bool, list[float]] = {True: [], False: []}
    scores: dict[bool, set] = {True: set(), False: set()}
    with tempfile.TemporaryDirectory(prefix="bench-sandbox-grade-") as tmp:
        cache = Path(tmp) / "cache"

        def once(sandbox: bool, tag: str) -> float:
            env = dict(os.environ, GRADER_SANDBOX="auto" if sandbox else "off", PYTHONPATH=str(REPO))
            out = Path(tmp) / tag
            t0 = time.monotonic()
            subprocess.run([sys.executable, "-m", "grader.cli", "grade", str(sub), "--only", "reference",
                            "--rubric", str(rubric), "-o", str(out), "--cache-dir", str(cache), "--no-reuse"],
                           env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            wall = time.monotonic() - t0
            doc = json.loads((out / "reference" / "result.json").read_text())
            scores[sandbox].add(tuple((i["id"], i["points"], i["status"]) for i in doc["items"]))
            return wall

        once(True, "warmup")           # the colcon build, cached for every run below
        for i in range(runs):
            for sandbox in ((True, False) if i % 2 == 0 else (False, True)):
                walls[sandbox].append(once(sandbox, f"run{i}-{'on' if sandbox else 'off'}"))
                print(f"  grade run {i + 1} sandbox {'on ' if sandbox else 'off'}: {walls[sandbox][-1]:6.1f} s",
                      flush=True)
    on, off = statistics.median(walls[True]), statistics.median(walls[False])
    print(f"Lab 3 reference grading: median {on:.1f} s with the sandbox, {off:.1f} s without: "
          f"ratio {on / off:.3f} ({(on / off - 1) * 100:+.1f} %, target within 5 %)")
    same = len(scores[True] | scores[False]) == 1
    print(f"item results identical with and without the sandbox in every run: {same}")
    return 0 if same else 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario-runs", type=int, default=6)
    ap.add_argument("--grade-runs", type=int, default=3)
    ap.add_argument("--skip-grade", action="store_true")
    args = ap.parse_args()
    parts()
    scenarios(args.scenario_runs)
    return 0 if args.skip_grade else grade(args.grade_runs)


if __name__ == "__main__":
    sys.exit(main())
