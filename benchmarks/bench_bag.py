"""Bag-layer benchmarks: writer and recorder throughput without loss, bag → DataFrame load time.

``.venv/bin/python benchmarks/bench_bag.py [--quick] [--only write|load|record]``

1. Write: :class:`grader.bag.writer.BagWriter` (the ``mcap`` package's Writer underneath) writes
   300,000 100-byte messages on 3 topics, ``poll()`` every 100 messages with the recorder's 1 s
   chunk age; reported in msg/s (it bounds what the recorder can take).
2. Load: a one-hour 62.5 Hz ``turtlesim/msg/Pose`` bag (225,000 messages) is synthesised with
   ``BagWriter`` (no live run), then timed: ``load_frames`` versus a bare ``rosbags`` read of the
   same bag (AnyReader, every message deserialised — what reading a bag with rosbags means), plus
   raw ``rosbags`` iteration without deserialisation for reference; and our scanning reader
   (``open_bag``: every message located) versus ``mcap``'s ``iter_messages`` (every message
   read, no decoding). Targets: load < 2 s, ratio to the rosbags read < 1.5.
3. Record: the recorder process subscribes, a publisher process sends N small messages
   (Pose payloads) at increasing rates; the highest rate whose bag holds every message is
   reported (target >= 10,000 msg/s), and 62.5 Hz x 50 topics must be lossless.
"""

from __future__ import annotations

import argparse
import json
import shutil
import struct
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

POSE = "turtlesim/msg/Pose"


def synth_pose_bag(path: Path, n: int = 225_000, hz: float = 62.5) -> Path:
    import numpy as np

    from grader.bag.msgdefs import DefinitionSource
    from grader.bag.writer import BagWriter

    src = DefinitionSource()
    t0 = 1_700_000_000_000_000_000
    period = int(1e9 / hz)
    rng = np.random.default_rng(0)
    jitter = rng.integers(-200_000, 200_000, n)
    vals = rng.random((n, 5)).astype("<f4")
    head = b"\x00\x01\x00\x00"
    with BagWriter(path) as w:
        w.add_topic("/turtle1/pose", POSE, src.full_text(POSE), type_hash=src.type_hash(POSE))
        pack = struct.Struct("<5f").pack
        for i in range(n):
            lt = t0 + i * period + int(jitter[i])
            w.write("/turtle1/pose", lt, head + pack(*vals[i]), lt - 150_000, i)
    return path


def bench_write(tmp: Path, n: int) -> dict:
    from grader.bag.msgdefs import DefinitionSource
    from grader.bag.writer import BagWriter

    src = DefinitionSource()
    typ = "std_msgs/msg/String"
    payload = b"\x00\x01\x00\x00" + struct.pack("<I", 91) + b"x" * 91 + b"\x00"   # 100 bytes
    t0 = 1_700_000_000_000_000_000
    start = time.perf_counter()
    w = BagWriter(tmp / "write", chunk_age_s=1.0)
    for k in range(3):
        w.add_topic(f"/w{k}", typ, src.full_text(typ), type_hash=src.type_hash(typ))
    names = [f"/w{k}" for k in range(3)]
    write, poll = w.write, w.poll
    for i in range(n):
        write(names[i % 3], t0 + i * 1000, payload, t0 + i * 1000 - 500, i)
        if i % 100 == 0:
            poll()
    w.close()
    elapsed = time.perf_counter() - start
    return {"messages": n, "payload_bytes": len(payload), "seconds": round(elapsed, 3),
            "msg_per_s": round(n / elapsed), "target_msg_s": 10_000,
            "targets_met": n / elapsed >= 10_000}


def bench_scan(bag: Path, n: int) -> dict:
    """Our scanning reader (every message located) versus ``mcap``'s iter_messages."""
    from mcap.reader import make_reader

    from grader.bag.reader import open_bag

    def ours() -> int:
        b = open_bag(bag)     # every message located: offsets, lengths, times as arrays
        return sum(len(t.log_times()) for t in b.topics.values())

    def mcap_iter() -> int:
        with open(next(bag.glob("*.mcap")), "rb") as f:
            return sum(1 for _ in make_reader(f).iter_messages())

    t_ours = min(_timed(ours) for _ in range(3))
    t_mcap = min(_timed(mcap_iter) for _ in range(2))
    assert ours() == mcap_iter() == n
    return {"open_bag_s": round(t_ours, 3), "mcap_iter_messages_s": round(t_mcap, 3),
            "mcap_over_ours": round(t_mcap / t_ours, 1)}


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def bench_load(tmp: Path, n: int) -> dict:
    from rosbags.highlevel import AnyReader

    from grader.bag.frames import load_frames

    bag = synth_pose_bag(tmp / "hour", n)
    size = sum(f.stat().st_size for f in bag.iterdir())

    def best(fn, reps=3):
        times = []
        for _ in range(reps):
            t = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t)
        return min(times), out

    t_ours, frames = best(lambda: load_frames(bag))

    def rosbags_read():
        with AnyReader([bag]) as r:
            return [r.deserialize(raw, c.msgtype) for c, _, raw in r.messages()]

    def rosbags_raw():
        with AnyReader([bag]) as r:
            return sum(1 for _ in r.messages())

    t_rb, msgs = best(rosbags_read, reps=2)
    t_raw, count = best(rosbags_raw, reps=2)
    df = frames["/turtle1/pose"]
    assert len(df) == n == len(msgs) == count, (len(df), n, len(msgs), count)
    assert abs(float(df["x"].iloc[-1]) - float(msgs[-1].x)) < 1e-6
    return {"messages": n, "bag_mib": round(size / 2**20, 2), "load_frames_s": round(t_ours, 3),
            "rosbags_read_s": round(t_rb, 3), "ratio_to_rosbags_read": round(t_ours / t_rb, 3),
            "rosbags_raw_iter_s": round(t_raw, 3), "ratio_to_raw_iter": round(t_ours / t_raw, 3),
            **(scan := bench_scan(bag, n)),
            "mcap_iter_over_load_frames": round(scan["mcap_iter_messages_s"] / t_ours, 1),
            "targets_met": t_ours < 2.0 and t_ours / t_rb < 1.5}


def _record_once(tmp: Path, rate: float, count: int, topics: int, tag: str) -> dict:
    from grader.bag.frames import load_bag_meta
    from grader.bag.recorder import recorder_argv, wait_ready
    from grader.runner import ProcessSpec, RosGraph, python_argv

    names = [f"/bench/t{i}" for i in range(topics)]
    work = tmp / tag
    with RosGraph(workdir=work) as g:
        rec = g.start(ProcessSpec(name="rec", argv=recorder_argv(work / "bag", regex="^/bench/")))
        wait_ready(rec.stdout_path, 30, rec)
        pub = g.start(ProcessSpec(name="pub", argv=python_argv(
            "grader.bag.loadgen", "--type", POSE, "--topics", *names, "--rate", str(rate),
            "--count", str(count), "--wait-subscribers", "1", "--linger", "1.0")))
        pub.wait(count / rate + 60)
        done = [l for l in pub.output().splitlines() if l.startswith("DONE")]
        time.sleep(0.5)
        rec.stop()
    meta = load_bag_meta(work / "bag")
    got = sum(meta.counts.get(n, 0) for n in names)
    elapsed = float(done[0].split()[3]) if done else float("nan")
    return {"rate_per_topic": rate, "topics": topics, "sent": count * topics, "recorded": got,
            "achieved_msg_s": round(count * topics / elapsed, 1) if done else None,
            "lossless": got == count * topics}


def bench_record(tmp: Path, quick: bool) -> dict:
    out: dict = {"ladder": []}
    best = 0.0
    rates = [2000, 5000, 8000] if quick else [2000, 5000, 8000, 12000, 16000, 24000, 32000]
    for rate in rates:
        r = _record_once(tmp, rate, int(rate * (2 if quick else 3)), 1, f"rate{rate}")
        out["ladder"].append(r)
        print(json.dumps(r), flush=True)
        if not r["lossless"]:
            break
        best = r["achieved_msg_s"] or rate
    out["max_lossless_msg_s"] = best
    many = _record_once(tmp, 62.5, 312 if quick else 625, 50, "fifty")
    print(json.dumps(many), flush=True)
    out["fifty_topics_62_5hz"] = many
    out["targets_met"] = best >= 10_000 and many["lossless"]
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--quick", action="store_true", help="smaller sizes (CI smoke run)")
    p.add_argument("--only", choices=("write", "load", "record"))
    args = p.parse_args(argv)
    results = {}
    tmp = Path(tempfile.mkdtemp(prefix="bench-bag-"))
    try:
        if args.only in (None, "write"):
            results["write"] = bench_write(tmp, 30_000 if args.quick else 300_000)
            print(json.dumps(results["write"]), flush=True)
        if args.only in (None, "load"):
            results["load"] = bench_load(tmp, 22_500 if args.quick else 225_000)
            print(json.dumps(results["load"]), flush=True)
        if args.only in (None, "record"):
            results["record"] = bench_record(tmp, args.quick)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
