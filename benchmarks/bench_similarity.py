"""Similarity of a class of 200 (grader.similarity): source and behaviour of every pair, timed, on
this machine's cores. The goal (issue 20): under a minute for source and behaviour together.

Grading 200 submissions for real takes hours, so the class is made the way ``grader grade``
leaves it, from the committed Lab 3 reference recording and generated code:

* each honest student gets a controller written from random choices (class or closures, math or
  numpy, how theta_e is wrapped, the distance, gains, timer period, stop rule, saturation, log
  lines, helper functions), plus a goal publisher and an action-server loop written the same way,
  so three files of their own besides the handout (the rubric's boilerplate);
* its behaviour in the controller scenario comes from simulating that controller (a unicycle at
  turtlesim's 62.5 Hz tick, from the rubric's placed starts), turned into the features
  ``grader.similarity.behaviour`` writes (paths, command series, value quantiles, rate, log
  templates, names); the other four scenarios are the reference's real fingerprints, each
  student's own deviation (3 %) added; result.json is the reference's, its measured numbers
  deviated the same way (5 %); a copy has its original's deviations plus a re-run's noise (0.2 %);
* ``--copies`` groups (default 12: pairs and triples) copy one student: the source renamed and
  reformatted (grader.testing.copies) or rewritten (a fresh generation with the same constants),
  the behaviour re-simulated with the re-run noise of one code.

Printed: the time of each phase (wall and CPU), the pair count and the time per pair, the pages
(the ``--max-pages`` most similar listed pairs), and how the copies ranked.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_similarity.py [--n 200] [--copies 12] [--jobs 2]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import shutil
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from grader.rubric.load import load_rubric  # noqa: E402
from grader.similarity import behaviour  # noqa: E402
from grader.grading.similarity import OUT_DIR, Settings, compute, write  # noqa: E402
from grader.testing.batch import LAB3_BAGS, recorded_batch  # noqa: E402
from grader.testing.copies import disguise_tree  # noqa: E402

GOAL_S = 60.0
SC = "ex2_controller"
#: (step, placed start x, y, theta, goal x, y): the Lab 3 rubric's ex2_controller
STEPS = [("goal_lab", 5.544445, 5.544445, 0.0, 2.0, 7.0), ("goal_wrap", 2.0, 7.0, 2.1, 0.8, 5.5),
         ("goal_behind", 0.8, 5.5, -3.0349, 3.3, 8.6), ("goal_right", 3.3, 8.6, 0.8921, 4.7, 4.9)]
LAB_GAINS = (0.5, 1.0)


# ---------------------------------------------------------------------------------- the code
def choices(rng: random.Random) -> dict:
    lab = rng.random() < 0.45          # many keep the lab's suggested gains and timer
    return {
        "k1": 0.5 if lab else rng.choice([0.3, 0.35, 0.4, 0.45, 0.6, 0.8, 1.0]),
        "k2": 1.0 if lab else rng.choice([0.8, 1.2, 1.5, 2.0, 3.0, 4.0]),
        "period": 0.03 if lab else rng.choice([0.02, 0.05, 0.1, 1 / 30, 0.04]),
        "wrap": rng.choice(["while", "atan2", "mod", "numpy"]),
        "dist": rng.choice(["hypot", "sqrt", "norm", "pow"]),
        "style": rng.choice(["class", "closure", "class_params"]),
        "stop": rng.choice([None, 0.01, 0.05, 0.1]),
        "vmax": rng.choice([None, None, 2.0, 3.0, 1.5]),
        "log": rng.choice(["New goal: (%.2f, %.2f)", "goal -> %.1f %.1f", "Heading to x=%.3f y=%.3f",
                           "received goal %f,%f", "Target set: %.2f / %.2f", "going to (%g, %g)"]),
        "extra": rng.sample(["counter", "debug", "clamp_fn", "status_log", "reset_fn", "pose_copy",
                             "guard_nan", "docstrings"], k=rng.randint(1, 5)),
        "seed": rng.randrange(1 << 30),
    }


def _wrap_code(kind: str) -> str:
    return {"while": "    while a > math.pi:\n        a -= 2.0 * math.pi\n    while a < -math.pi:\n"
                     "        a += 2.0 * math.pi\n    return a\n",
            "atan2": "    return math.atan2(math.sin(a), math.cos(a))\n",
            "mod": "    return (a + math.pi) % (2 * math.pi) - math.pi\n",
            "numpy": "    return float(np.arctan2(np.sin(a), np.cos(a)))\n"}[kind]


def _dist_code(kind: str) -> str:
    return {"hypot": "math.hypot(dx, dy)", "sqrt": "math.sqrt(dx * dx + dy * dy)",
            "norm": "float(np.linalg.norm([dx, dy]))", "pow": "(dx ** 2 + dy ** 2) ** 0.5"}[kind]


def controller_source(c: dict) -> str:
    """A go-to-goal controller written from the choices ``c`` (a student's own file)."""
    r = random.Random(c["seed"])
    imports = ["import math", "import numpy as np", "import rclpy", "from rclpy.node import Node",
               "from geometry_msgs.msg import Twist", "from turtlesim.msg import Pose",
               "from std_msgs.msg import Float32MultiArray"]
    r.shuffle(imports)
    out = ["\n".join(imports), ""]
    if "docstrings" in c["extra"]:
        out.append('"""Lab 3 exercise 2: drive the turtle to the goal with a P controller."""\n')
    out.append(f"K_LIN = {c['k1']}\nK_ANG = {c['k2']}\nPERIOD = {c['period']!r}\n")
    out.append("def wrap(a):\n" + _wrap_code(c["wrap"]))
    if "clamp_fn" in c["extra"] or c["vmax"]:
        out.append(f"def clamp(v, m={c['vmax'] or 5.0}):\n    return max(-m, min(m, v))\n")
    stop = (f"        if d < {c['stop']}:\n            self.pub.publish(Twist())\n            return\n"
            if c["stop"] else "")
    sat = "        v = clamp(v)\n" if c["vmax"] else ""
    nan = ("        if math.isnan(self.x) or math.isnan(self.y):\n            return\n"
           if "guard_nan" in c["extra"] else "")
    count = "        self.ticks += 1\n" if "counter" in c["extra"] else ""
    debug = ("        self.get_logger().debug('d=%.3f e=%.3f' % (d, e))\n" if "debug" in c["extra"] else "")
    body = (f"{nan}        dx = self.gx - self.x\n        dy = self.gy - self.y\n"
            f"        d = {_dist_code(c['dist'])}\n        e = wrap(math.atan2(dy, dx) - self.th)\n{stop}"
            f"        v = K_LIN * d\n{sat}        w = K_ANG * e\n{count}{debug}"
            "        cmd = Twist()\n        cmd.linear.x = v\n        cmd.angular.z = w\n        self.pub.publish(cmd)\n")
    if c["style"] == "closure":
        body = body.replace("self.pub", "pub").replace("self.get_logger()", "node.get_logger()")
        body = body.replace("self.ticks", "state['ticks']").replace("self.", "state_")
        out.append(
            "def make(node):\n    state_x = state_y = state_th = 0.0\n    state_gx = state_gy = None\n"
            "    state = {'ticks': 0}\n    pub = node.create_publisher(Twist, '/turtle1/cmd_vel', 10)\n\n"
            "    def on_pose(p):\n        nonlocal state_x, state_y, state_th\n"
            "        state_x, state_y, state_th = p.x, p.y, p.theta\n\n"
            "    def on_goal(g):\n        nonlocal state_gx, state_gy\n        state_gx, state_gy = g.data[0], g.data[1]\n"
            f"        node.get_logger().info('{c['log']}' % (state_gx, state_gy))\n\n"
            "    def tick():\n        if state_gx is None:\n            return\n"
            + body.replace("        ", "        ", 1)
            + "\n    node.create_subscription(Pose, '/turtle1/pose', on_pose, 10)\n"
            "    node.create_subscription(Float32MultiArray, '/turtle1/goal', on_goal, 10)\n"
            "    node.create_timer(PERIOD, tick)\n\n"
            "def main(args=None):\n    rclpy.init(args=args)\n    node = rclpy.create_node('turtle_control_node')\n"
            "    make(node)\n    rclpy.spin(node)\n")
    else:
        params = ("        self.declare_parameter('k_lin', K_LIN)\n        self.declare_parameter('k_ang', K_ANG)\n"
                  if c["style"] == "class_params" else "")
        reset = ("    def reset(self):\n        self.gx = self.gy = None\n        self.pub.publish(Twist())\n\n"
                 if "reset_fn" in c["extra"] else "")
        status = ("        self.get_logger().info('controller ready, period %.3f s' % PERIOD)\n"
                  if "status_log" in c["extra"] else "")
        copy = ("        self.last = msg\n" if "pose_copy" in c["extra"] else "")
        out.append(
            "class Controller(Node):\n    def __init__(self):\n        super().__init__('turtle_control_node')\n"
            f"{params}        self.x = self.y = self.th = 0.0\n        self.gx = self.gy = None\n        self.ticks = 0\n"
            "        self.pub = self.create_publisher(Twist, '/turtle1/cmd_vel', 10)\n"
            "        self.create_subscription(Pose, '/turtle1/pose', self.on_pose, 10)\n"
            "        self.create_subscription(Float32MultiArray, '/turtle1/goal', self.on_goal, 10)\n"
            f"        self.create_timer(PERIOD, self.tick)\n{status}\n"
            f"    def on_pose(self, msg):\n{copy}        self.x, self.y, self.th = msg.x, msg.y, msg.theta\n\n"
            "    def on_goal(self, msg):\n        self.gx, self.gy = float(msg.data[0]), float(msg.data[1])\n"
            f"        self.get_logger().info('{c['log']}' % (self.gx, self.gy))\n\n{reset}"
            "    def tick(self):\n        if self.gx is None:\n            return\n" + body + "\n"
            "def main(args=None):\n    rclpy.init(args=args)\n    node = Controller()\n    rclpy.spin(node)\n")
    return "\n".join(out)


def other_source(c: dict, role: int) -> str:
    """A goal publisher (role 0) or an action-server loop (role 1) written from choices."""
    r = random.Random(c["seed"] + role)
    lines = ["import rclpy", "from rclpy.node import Node", "import math"]
    r.shuffle(lines)
    names = ["line", "text", "raw", "entry", "s"]
    v = r.choice(names)
    parse = r.choice([f"x, y = [float(t) for t in {v}.split(',')]",
                      f"parts = {v}.strip().split(',')\n        x = float(parts[0])\n        y = float(parts[1])",
                      f"x, y = map(float, {v}.replace(' ', '').split(','))"])
    check = r.choice(["", "        if not (0 <= x <= 11 and 0 <= y <= 11):\n            return None\n",
                      "        if x < 0 or y < 0 or x > 11.08 or y > 11.08:\n            raise ValueError('out')\n"])
    body = [f"def parse({v}):", "    try:", f"        {parse}", "    except ValueError:",
            "        return None" if r.random() < 0.5 else "        print('bad input')\n        return None",
            check.rstrip("\n") or "    pass", "    return x, y", ""]
    if role == 1:
        body += ["def step(x, y, gx, gy, th, k1, k2):", "    dx, dy = gx - x, gy - y",
                 r.choice(["    d = math.hypot(dx, dy)", "    d = math.sqrt(dx ** 2 + dy ** 2)"]),
                 r.choice(["    e = math.atan2(math.sin(math.atan2(dy, dx) - th), math.cos(math.atan2(dy, dx) - th))",
                           "    e = (math.atan2(dy, dx) - th + math.pi) % (2 * math.pi) - math.pi"]),
                 f"    return k1 * d, k2 * e, d < {r.choice([0.05, 0.1, 0.2])}", ""]
    loop = r.choice(["while rclpy.ok():", "for _ in iter(int, 1):"])
    body += ["def main(args=None):", "    rclpy.init(args=args)", f"    node = Node('{r.choice(['goal_pub', 'goals', 'gp'])}')",
             f"    {loop}", f"        {v} = input('{r.choice(['x,y: ', 'Goal: ', 'goal x,y > '])}')",
             f"        got = parse({v})", "        if got is None:", "            continue",
             f"        node.get_logger().info('{r.choice(['sent %s', 'goal %s', 'publishing %s'])}' % (got,))", ""]
    return "\n".join(lines) + "\n\n" + "\n".join(body)


def write_workspace(c: dict, dest: Path) -> None:
    pkg = dest / "src" / "turtle_control"
    (pkg / "turtle_control").mkdir(parents=True, exist_ok=True)
    (pkg / "turtle_control" / "turtle_control.py").write_text(controller_source(c))
    (pkg / "turtle_control" / "goal_publisher.py").write_text(other_source(c, 0))
    server = dest / "src" / "turtle_controller_server" / "turtle_controller_server"
    server.mkdir(parents=True, exist_ok=True)
    (server / "loop.py").write_text(other_source(c, 1))
    shutil.copy(REPO / "fixtures" / "similarity" / "enee467_lab3" / "honest_b" / "src" / "turtle_control" / "setup.py",
                pkg / "setup.py")


# ------------------------------------------------------------------------------ the behaviour
def simulate(c: dict, noise: np.random.Generator) -> list[behaviour.Feature]:
    """The controller scenario's features of controller ``c``, simulated (one re-run's noise)."""
    feats: list[behaviour.Feature] = []
    dt, ctrl = 0.016, max(c["period"], 0.016)
    all_v, all_w = [], []
    for step, x, y, th, gx, gy in STEPS:
        t, next_ctrl, v, w, settled = 0.0, noise.uniform(0, ctrl), 0.0, 0.0, 0.0
        xs, ys, cmd_t, vs, ws = [x], [y], [], [], []
        while t < GOAL_S:
            if t >= next_ctrl:
                dx, dy = gx - x, gy - y
                d = math.hypot(dx, dy)
                e = math.atan2(math.sin(math.atan2(dy, dx) - th), math.cos(math.atan2(dy, dx) - th))
                v, w = c["k1"] * d, c["k2"] * e
                if c["stop"] and d < c["stop"]:
                    v = w = 0.0
                if c["vmax"]:
                    v = max(-c["vmax"], min(c["vmax"], v))
                cmd_t.append(t), vs.append(v), ws.append(w)
                next_ctrl += ctrl
            th = th + w * dt
            x, y = min(11.09, max(0.0, x + v * math.cos(th) * dt)), min(11.09, max(0.0, y + v * math.sin(th) * dt))
            xs.append(x), ys.append(y)
            t += dt
            settled = settled + dt if math.hypot(gx - x, gy - y) < 0.1 else 0.0
            if settled >= 1.0:
                break
        feats.append(behaviour.Feature(f"{SC}|path|/turtle1/pose|{step}", "path", "path",
                                       f"path of /turtle1/pose in step {step}",
                                       behaviour._path(np.array(xs), np.array(ys)), SC))
        grid = np.arange(0.0, min(behaviour.CMD_SPAN_S, cmd_t[-1]) + 1e-9, behaviour.CMD_GRID_S)
        idx = np.clip(np.searchsorted(cmd_t, grid, side="right") - 1, 0, len(cmd_t) - 1)
        for col, series in (("linear.x", vs), ("angular.z", ws)):
            feats.append(behaviour.Feature(f"{SC}|commands|/turtle1/cmd_vel.{col}|{step}", "series", "commands",
                                           f"/turtle1/cmd_vel {col} after the goal of step {step}",
                                           np.round(np.asarray(series)[idx], 4).tolist(), SC))
        all_v += vs
        all_w += ws
    for col, series in (("linear.x", all_v), ("angular.z", all_w)):
        q = np.quantile(series, [0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 1.0])
        feats.append(behaviour.Feature(f"{SC}|values|/turtle1/cmd_vel.{col}", "series", "values",
                                       f"distribution of /turtle1/cmd_vel {col}", np.round(q, 5).tolist(), SC))
    feats.append(behaviour.Feature(f"{SC}|rate|/turtle1/cmd_vel", "scalar", "rate", "publish rate of /turtle1/cmd_vel (Hz)",
                                   round(1.0 / ctrl * (1 + noise.normal(0, 0.002)), 4), SC))
    line = behaviour.template(c["log"].replace("%", "1").replace("1.2f", "1").replace("1.1f", "1"))
    for token, group in ((line, "log"), ("node:turtle_control_node", "names"), ("topic:/turtle1/cmd_vel", "names")):
        feats.append(behaviour.Feature(f"{SC}|{group}|{token}", "token", group, token, token, SC))
    return feats


def jitter(feats: list[dict], noise: np.random.Generator, scale: float) -> list[dict]:
    out = []
    for f in feats:
        f = dict(f)
        if f["kind"] in ("path", "series"):
            f["value"] = np.round(np.asarray(f["value"], float) * (1 + noise.normal(0, scale)), 4).tolist()
        elif f["kind"] == "scalar":
            f["value"] = round(float(f["value"]) * (1 + noise.normal(0, scale)), 5)
        out.append(f)
    return out


# --------------------------------------------------------------------------------- the class
def make_class(out: Path, n: int, n_copies: int, seed: int = 7) -> tuple[dict[str, str], dict[str, dict]]:
    """OUT as ``grader grade`` leaves it for ``n`` submissions; copy id -> original id, and each
    submission's choices."""
    rubric = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
    ref_out = out.parent / "reference-regrade"
    recorded_batch(LAB3_BAGS, ref_out, rubric, only=["reference"])
    ref = ref_out / "reference"
    others = {p.parent.name: json.loads(p.read_text())["features"]
              for p in ref.glob("scenarios/*/fingerprint.json") if p.parent.name != SC}
    result = json.loads((ref / "result.json").read_text())
    rng, noise = random.Random(seed), np.random.default_rng(seed)
    originals = n - sum(size - 1 for size in _copy_sizes(n_copies))
    made: dict[str, dict] = {}
    copies: dict[str, str] = {}
    ids = [f"s{i:03d}" for i in range(n)]
    for sid in ids[:originals]:
        made[sid] = choices(rng)
    at = originals
    for g, size in enumerate(_copy_sizes(n_copies)):
        src = ids[g]
        for k in range(size - 1):
            copies[ids[at]] = src
            made[ids[at]] = made[src]
            at += 1
    for i, sid in enumerate(ids):
        c = made[sid]
        sub = out / sid
        (sub / "scenarios" / SC).mkdir(parents=True)
        ws = out.parent / "ws" / sid
        if sid in copies and i % 2 == 0:          # renamed and reformatted
            disguise_tree(out.parent / "ws" / copies[sid] / "src", ws / "src", seed=i)
        elif sid in copies:                       # rewritten: other code, same constants
            write_workspace({**choices(random.Random(i)), **{k: c[k] for k in ("k1", "k2", "period", "stop", "vmax", "log")}}, ws)
        else:
            write_workspace(c, ws)
        from grader.similarity.files import snapshot
        snapshot(ws / "src", sub)
        feats = [asdict(f) for f in simulate(c, noise)]
        _store(sub / "scenarios" / SC, feats)
        own = np.random.default_rng(c["seed"])      # this code's own way (a copy has it too) ...
        for sc, fl in others.items():
            (sub / "scenarios" / sc).mkdir(parents=True, exist_ok=True)
            _store(sub / "scenarios" / sc, jitter(jitter(fl, own, 0.03), noise, 0.002))   # ... and a re-run's noise
        doc = json.loads(json.dumps(result))
        for item in doc["items"]:
            for key, v in list((item.get("evidence") or {}).items()):
                if isinstance(v, float) and not isinstance(v, bool):
                    item["evidence"][key] = round(v * (1 + own.normal(0, 0.05) + noise.normal(0, 0.002)), 5)
        (sub / "result.json").write_text(json.dumps(doc))
    return copies, made


def _copy_sizes(n_copies: int) -> list[int]:
    return [3 if g % 4 == 3 else 2 for g in range(n_copies)]


def _store(folder: Path, feats: list[dict]) -> None:
    (folder / behaviour.FINGERPRINT_FILE).write_text(json.dumps(
        {"schema": behaviour.FINGERPRINT_SCHEMA, "scenario": folder.name, "features": feats}))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--copies", type=int, default=12)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    rubric = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
    with tempfile.TemporaryDirectory(prefix="bench-similarity-") as tmp:
        out = Path(tmp) / "out"
        t0 = time.perf_counter()
        copies, made = make_class(out, args.n, args.copies)
        print(f"class of {args.n} made in {time.perf_counter() - t0:.1f} s ({len(copies)} copies of "
              f"{len(set(copies.values()))} submissions); load average {os.getloadavg()[0]:.1f}")
        from grader.grading.analysis import scenario_frames
        spent = 0.0
        for sc_dir in sorted((Path(tmp) / "reference-regrade" / "reference" / "scenarios").iterdir()):
            frames = scenario_frames(sc_dir)
            c0 = time.process_time()
            behaviour.fingerprint_frames(frames, sc_dir.name)
            spent += time.process_time() - c0
        print(f"at grade time: fingerprinting the reference's {len(list(sc_dir.parent.iterdir()))} real recordings "
              f"(frames in memory) took {spent:.2f} s CPU")
        settings = Settings()
        c0, w0 = time.process_time(), time.perf_counter()
        summary = compute(out, rubric, settings, jobs=args.jobs)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        t = summary["timings"]
        pairs = summary["pairs_compared"]
        n_feats = sum(len(v) for v in summary["_features"].values()) / args.n
        n_fp = sum(s.size for s in summary["_sets"].values()) / args.n
        print(f"\n{args.n} submissions, {pairs} pairs; per submission {n_feats:.0f} behaviour features, "
              f"{n_fp:.0f} source fingerprints (after boilerplate and {t and summary['settings']['common_fingerprints_dropped']} "
              f"class-common ones)")
        print(f"  behaviour: features read {t['behaviour_features_s']:.2f} s, pairs {t['behaviour_pairs_s']:.2f} s")
        print(f"  source:    fingerprints {t['source_fingerprints_s']:.2f} s, pairs {t['source_pairs_s']:.2f} s")
        print(f"  total {wall:.1f} s wall, {cpu:.1f} s CPU: {1e3 * wall / pairs:.2f} ms per pair "
              f"({'under' if wall < 60 else 'OVER'} the minute)")
        w1 = time.perf_counter()
        write(out, summary)
        listed = [p for p in summary["pairs"] if p["listed"]]
        pages = sum(1 for p in summary["pairs"] if p["page"])
        print(f"  pages: {pages} side-by-side pages of {len(listed)} listed pairs in "
              f"{time.perf_counter() - w1:.1f} s ({len(list((out / OUT_DIR).glob('pair-*.html')))} written)")
        truth = {frozenset((c, o)) for c, o in copies.items()}
        for c1, o1 in copies.items():
            for c2, o2 in copies.items():
                if c1 < c2 and o1 == o2:
                    truth.add(frozenset((c1, c2)))
        rank = {frozenset((p["a"], p["b"])): i for i, p in enumerate(summary["pairs"])}
        found = [p for p in listed if frozenset((p["a"], p["b"])) in truth]
        worst = max(rank.get(k, len(rank)) for k in truth)
        others = [p for p in listed if frozenset((p["a"], p["b"])) not in truth]
        by_src = sum(1 for p in others if p["source"] >= settings.threshold)
        print(f"\ncopied pairs: {len(truth)}; listed {len(found)}, ranked within the first {worst + 1}; "
              f"other pairs listed: {len(others)} ({by_src} by source, {len(others) - by_src} by behaviour "
              f"only; the generator's honest code shares whole blocks)")
        pairs_of = {frozenset((p["a"], p["b"])): p for p in summary["pairs"]}
        for k in sorted(truth, key=lambda k: rank.get(k, len(rank))):
            p = pairs_of.get(k)
            a, b = sorted(k)
            how = "renamed" if int(max(a, b)[1:]) % 2 == 0 else "rewritten"
            lab = (made[a]["k1"], made[a]["k2"], made[a]["period"]) == (*LAB_GAINS, 0.03)
            print(f"  {a} {b} ({how}{', lab gains' if lab else ''}): rank {rank.get(k, len(rank)) + 1}, "
                  f"source {p['source'] if p else 0:.2f}, behaviour {p['behaviour'] if p else 0:.2f}")
        by_beh = sorted(summary["pairs"], key=lambda p: -p["behaviour"])
        top = {frozenset((p["a"], p["b"])) for p in by_beh[:len(truth)]}
        print(f"by behaviour alone, {len(top & truth)} of the {len(truth)} copied pairs are the top {len(truth)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
