"""The recorder: a separate process writing every selected topic of a live graph to a rosbag2 bag.

``python -m grader.bag.recorder -o BAG [TOPIC ...] [--regex R] [--all]``

Why not ``ros2 bag record``: the wheels-based install has no rosbag2, and grading needs a few
things it lacks: the send time of every message kept next to the receive time, definitions of
hidden types (service events, action feedback) so bags decode without the student's workspace,
and chunks closed on a timer so a SIGKILL loses at most ~1 s.

Behaviour, as rosbag2 does it: the graph is polled (default every 0.1 s) and topics that appear
later are subscribed too, hidden ones (``_action/...``, ``_service_event``) included (rclpy's
``get_topic_names_and_types`` lists them; rosbag2 calls that ``include_hidden_topics``); the
subscription QoS is adapted to the publishers (reliable only if all are, transient-local only
if all are); every publisher's offered QoS is kept in metadata. A topic seen before any of its
publishers (another node's subscription made it appear) is subscribed as its publishers are
known to offer it: ``/rosout`` transient local (rcl's profile for every node), anything else
volatile; since a subscription is never upgraded, a volatile ``/rosout`` lost every line a node
logged before the recorder matched it (bench_flake at a load of ~20: a chaser's "Spawned
turtle2", logged 0.4 s into its start-up, missing from 1 of 223 chase recordings, turtlesim's
start-up lines with it). Subscriptions are raw (CDR bytes
are written untouched) and drained through our own wait set instead of an executor, which
costs a few microseconds per message instead of tens. While traffic is light the loop wakes at
most every ``--batch`` seconds (default 0.05) and drains what arrived meanwhile: the time stamps
come from the DDS layer, so waking later shifts none of them, and a wake costs far more than a
message (measured next to a simulator's 125 msg/s: 0.024 CPU s/s waking per arrival, 0.014 with
0.05 s batches). A wake that finds a burst (``BURST`` messages or more) goes straight back, so
high rates are drained as fast as before.

``grader.bag.recorder_thread`` runs the same recorder as a thread of the calling process (the
scenario process records its own graph).

Readiness protocol: after the first discovery round the process prints ``READY`` on a line of
its own on stdout (flushed); :func:`wait_ready` polls a stdout log for it. SIGINT and SIGTERM
drain pending messages, finalize the bag (MCAP summary + metadata.yaml) and exit 0, printing
``RECORDED <n> messages``.

Time stamps: log (receive) time = rmw ``received_timestamp`` of the sample (taken by the DDS
layer, so Python scheduling delays do not shift it), falling back to the wall clock when the
RMW gives none; MCAP ``publish_time`` = rmw ``source_timestamp`` (the publisher's send time —
available through rclpy's ``MessageInfo`` in Jazzy). Both stay wall-clock times when the graph
runs on simulated time (``--time-scale``, unlike ``ros2 bag record --use-sim-time``): the DDS
stamps and the ``/rosout`` stamps inside messages can only be wall clock, so the bag keeps one
time base and the recorded ``/clock`` maps all of them to simulated time when it is read
(:mod:`grader.bag.timebase`).

Topics under ``/grader/sim_record/`` are never taken from DDS: the prefix holds the simulator's
own record of its poses (:mod:`grader.sim.record`), which the scenario's recorder writes from the
simulator's file (:mod:`grader.bag.recorder_thread`), so whatever a node publishes under that name
stays out of the bag.

A little over the project's ~400 lines: discovery, subscription, the writer hand-off and
the stop protocol share one loop and its state; split, each part would need the others' fields.

A little over the project's ~450 lines: one process's program (``python -m grader.bag.recorder``),
the recorder and the command line that starts it, which ``recorder_thread`` reuses as they are
(its options and defaults are the CLI's); split, the two would have to agree on every option.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from grader.sim.record import is_record_topic

READY_LINE = "READY"
#: messages drained in one wake above which the recorder does not wait for the next batch
BURST = 200


# --------------------------------------------------------------------------------------------
# API for scenario code (no rclpy import here)

def recorder_argv(out_dir: Path | str, topics: Sequence[str] | None = None, all_topics: bool = True,
                  regex: str | None = None, exclude: str | None = None,
                  extra: Sequence[str] = ()) -> list[str]:
    """argv that starts the recorder with the grader's interpreter (for ``ProcessSpec``).

    ``all_topics`` records everything (hidden topics included) unless ``topics`` or ``regex``
    narrow it; explicit ``topics`` are recorded in addition to what ``regex`` selects.
    """
    argv = [sys.executable, "-m", "grader.bag.recorder", "-o", str(out_dir)]
    argv += list(topics or [])
    if regex:
        argv += ["--regex", regex]
    if exclude:
        argv += ["--exclude", exclude]
    if all_topics and not topics and not regex:
        argv.append("--all")
    return argv + list(extra)


def wait_ready(stdout_path: Path | str, timeout: float = 15.0, proc: Any = None) -> None:
    """Block until the recorder printed ``READY`` into ``stdout_path``.

    ``proc`` (anything with ``alive()`` or ``poll()``) lets a recorder that died early fail fast.
    Raises GraderError with the recorder's last output when it does not become ready.
    """
    from grader.errors import GraderError  # noqa: PLC0415 - bag.recorder loads in every scenario child process; errors only on this path

    path = Path(stdout_path)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.is_file() and READY_LINE in path.read_text(errors="replace").splitlines():
            return
        if proc is not None:
            dead = (not proc.alive()) if hasattr(proc, "alive") else proc.poll() is not None
            if dead:
                break
        time.sleep(0.02)
    tail = path.read_text(errors="replace")[-800:] if path.is_file() else ""
    raise GraderError(f"the recorder did not become ready within {timeout:.0f} s "
                      f"(output: {tail.strip() or 'none'}); see its stderr log.")


# --------------------------------------------------------------------------------------------
# the recorder process

#: topics subscribed transient local while no publisher is known: every ``/rosout`` publisher
#: offers it (rcl), and a volatile subscription would lose what a node logs before it is matched
TRANSIENT_BEFORE_PUBLISHERS = frozenset({"/rosout"})


@dataclass
class _Sub:
    """A recorded topic: its subscription and every publisher offer seen."""

    topic: str
    type: str
    cls: Any
    handle: Any = None               # rclpy Subscription
    reliable: bool = True
    transient: bool = False
    publishers: int = -1             # publisher count seen at the last refresh
    offers: dict[str, dict] = field(default_factory=dict)   # gid -> offered QoS dict
    probed: bool = False             # offers were looked up at the first message (see drain)


class Recorder:
    """One node, raw subscriptions, one wait set, one BagWriter (see the module docstring)."""

    def __init__(self, args: argparse.Namespace, *, domain_id: int | None = None) -> None:
        import rclpy  # noqa: PLC0415 - rclpy: ROS, imported where it is used (this module loads in processes that never use it)
        from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415 - rclpy.signals: ROS, imported where it is used (this module loads in processes that never use it)

        from grader.bag.msgdefs import DefinitionSource  # noqa: PLC0415 - bag.recorder loads in every scenario child process; bag.msgdefs only on this path
        from grader.bag.writer import BagWriter  # noqa: PLC0415 - bag.writer loads mcap (43 ms CPU), only on this path

        self.args = args
        self.rclpy = rclpy
        custom = {"recorder": "grader.bag.recorder"}
        if args.time_scale is not None:
            from grader.bag.timebase import TIME_SCALE_KEY  # noqa: PLC0415 - bag.timebase loads numpy (147 ms CPU), only on this path
            custom[TIME_SCALE_KEY] = repr(float(args.time_scale))
        if args.lockstep:
            from grader.bag.timebase import LOCKSTEP_KEY  # noqa: PLC0415 - bag.timebase loads numpy (147 ms CPU), only on this path
            custom[LOCKSTEP_KEY] = "true"
        self.writer = BagWriter(args.output, chunk_size=args.chunk_size, chunk_age_s=args.chunk_age,
                                custom_data=custom)
        self.defs = DefinitionSource()
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=_domain_id() if domain_id is None else domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(args.node_name, context=self.ctx, enable_rosout=False,
                                      start_parameter_services=False)
        self.subs: dict[str, _Sub] = {}
        self.by_pointer: dict[int, _Sub] = {}
        self.skipped: set[str] = set()
        self.stop = False
        self.topics = set(_abs(t) for t in args.topics)
        self.regex = re.compile(args.regex) if args.regex else None
        self.exclude = re.compile(args.exclude) if args.exclude else None
        self.all = args.all or (not self.topics and not self.regex)
        self._waitset: tuple[Any, list] | None = None

    # -- selection and discovery ---------------------------------------------------------
    def wanted(self, topic: str) -> bool:
        if is_record_topic(topic):     # never from DDS (module docstring)
            return False
        if topic in self.topics:
            return True
        if self.exclude and self.exclude.search(topic):
            return False
        return self.all or bool(self.regex and self.regex.search(topic))

    def discover(self) -> None:
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.skipped or not self.wanted(topic):
                continue
            sub = self.subs.get(topic)
            if sub is None:
                if len(types) > 1:
                    _log(f"topic {topic} has several types {types}; recording {types[0]}")
                try:
                    from grader.bag.rosio import message_class  # noqa: PLC0415 - bag.recorder loads in every scenario child process; bag.rosio only on this path
                    cls = message_class(types[0])
                except LookupError as exc:
                    _log(f"skipping {topic}: {exc}")
                    self.skipped.add(topic)
                    continue
                sub = self.subs[topic] = _Sub(topic, types[0], cls)
            count = self.node.count_publishers(topic)
            if count != sub.publishers:
                self.refresh(sub, count)

    def _record_offers(self, sub: _Sub) -> list:
        """Look up the topic's publishers and keep every new offer; returns their infos."""
        from grader.bag.rosio import qos_to_dict  # noqa: PLC0415 - bag.recorder loads in every scenario child process; bag.rosio only on this path

        infos = self.node.get_publishers_info_by_topic(sub.topic)
        for info in infos:
            gid = ".".join(f"{b:02x}" for b in info.endpoint_gid)
            sub.offers.setdefault(gid, qos_to_dict(info.qos_profile))
        return infos

    def refresh(self, sub: _Sub, count: int) -> None:
        """Publishers changed: record their offers and (re)subscribe with a compatible QoS."""
        from rclpy.qos import DurabilityPolicy, ReliabilityPolicy  # noqa: PLC0415 - rclpy.qos: ROS, imported where it is used (this module loads in processes that never use it)

        infos = self._record_offers(sub)
        sub.publishers = count
        type_hash = ""
        for info in infos:
            type_hash = type_hash or str(info.topic_type_hash)
        if type_hash and not type_hash.startswith("RIHS01_"):
            type_hash = ""
        if self.args.verbose:
            _log(f"{sub.topic}: {count} publisher(s), offers "
                 + ", ".join(f"{d['reliability']}/{d['durability']}" for d in sub.offers.values()))
        reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        transient = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos) \
            if infos else sub.topic in TRANSIENT_BEFORE_PUBLISHERS
        if sub.topic not in self.writer.topics:
            self.add_to_bag(sub, type_hash)
        self.writer.update_qos(sub.topic, list(sub.offers.values()))
        if sub.handle is None:
            self.subscribe(sub, reliable, transient)
        elif infos and ((sub.reliable and not reliable) or (sub.transient and not transient)):
            # a current publisher cannot match the subscription: downgrade (never upgrade, so
            # publishers that leave do not cause churn)
            self.subscribe(sub, sub.reliable and reliable, sub.transient and transient)

    def add_to_bag(self, sub: _Sub, type_hash: str) -> None:
        from grader.bag.msgdefs import DefinitionNotFound  # noqa: PLC0415 - bag.recorder loads in every scenario child process; bag.msgdefs only on this path

        try:
            text = self.defs.full_text(sub.type)
        except DefinitionNotFound as exc:
            _log(f"no message definition for {sub.type} ({exc}); {sub.topic} is recorded "
                 "without one and needs the interface package to be decoded")
            text = ""
        self.writer.add_topic(sub.topic, sub.type, text, type_hash=type_hash
                              or self.defs.type_hash(sub.type))

    def subscribe(self, sub: _Sub, reliable: bool, transient: bool) -> None:
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415 - rclpy.qos: ROS, imported where it is used (this module loads in processes that never use it)

        if sub.handle is not None:
            self.drain(sub)
            self.by_pointer.pop(sub.handle.handle.pointer, None)
            self.node.destroy_subscription(sub.handle)
            _log(f"resubscribing {sub.topic} as {'reliable' if reliable else 'best effort'}"
                 f"/{'transient local' if transient else 'volatile'} for a new publisher")
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=self.args.qos_depth,
                         reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)
        sub.handle = self.node.create_subscription(sub.cls, sub.topic, _noop, qos, raw=True)
        sub.reliable, sub.transient = reliable, transient
        self.by_pointer[sub.handle.handle.pointer] = sub
        self._waitset = None

    # -- the data path -------------------------------------------------------------------
    def drain(self, sub: _Sub, limit: int = 1_000_000) -> int:
        take = sub.handle.handle.take_message
        cls = sub.cls
        write = self.writer.write
        topic = sub.topic
        n = 0
        with sub.handle.handle:
            while n < limit:
                got = take(cls, True)
                if got is None:
                    break
                if not sub.offers and not sub.probed:
                    self._probe_offers(sub)
                data, info = got
                recv = info.get("received_timestamp") or time.time_ns()
                write(topic, recv, data, info.get("source_timestamp") or 0,
                      info.get("publication_sequence_number") or 0)
                n += 1
        return n

    def _probe_offers(self, sub: _Sub) -> None:
        """The first message came from a publisher the last graph poll did not see yet (the
        topic had only subscribers then): look its offer up now, so that the topic's MCAP
        channel, written with this message, carries it instead of an empty list."""
        sub.probed = True
        if self._record_offers(sub):
            self.writer.update_qos(sub.topic, list(sub.offers.values()))

    def _build_waitset(self) -> tuple[Any, list]:
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy  # noqa: PLC0415 - rclpy.impl.implementation_singleton: ROS, imported where it is used (this module loads in processes that never use it)

        subs = [s for s in self.subs.values() if s.handle is not None]
        ws = _rclpy.WaitSet(len(subs), 0, 0, 0, 0, 0, self.ctx.handle)
        return ws, subs

    def spin_once(self, timeout_s: float) -> int:
        """Wait up to ``timeout_s`` for messages and drain the ready topics; how many."""
        if self._waitset is None:
            self._waitset = self._build_waitset()
        ws, subs = self._waitset
        if not subs:
            time.sleep(timeout_s)
            return 0
        ws.clear_entities()
        for s in subs:
            ws.add_subscription(s.handle.handle)
        ws.wait(int(timeout_s * 1e9))
        n = 0
        for ptr in ws.get_ready_entities("subscription"):
            sub = self.by_pointer.get(ptr)
            if sub is not None:
                n += self.drain(sub, limit=10_000)
        return n

    def run(self, on_ready=None) -> int:
        """Record until :attr:`stop` is set; ``on_ready`` (default: print ``READY``) is called
        after the first discovery round."""
        poll = self.args.poll_interval
        batch = max(0.0, self.args.batch)
        self.discover()
        self._wait_matched(min(2.0, self.args.ready_timeout))
        (on_ready or (lambda: print(READY_LINE, flush=True)))()
        next_poll = time.monotonic() + poll
        while not self.stop and self.ctx.ok():
            woke = time.monotonic()
            drained = self.spin_once(min(0.05, poll))
            self.writer.poll()
            now = time.monotonic()
            if now >= next_poll:
                self.discover()
                next_poll = now + poll
            if drained < BURST and not self.stop:
                time.sleep(max(0.0, woke + batch - time.monotonic()))   # let the next batch gather
        return self.finish()

    def _wait_matched(self, timeout: float) -> None:
        """Let DDS match the initial subscriptions with their publishers before READY."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not self.stop:
            if all(s.handle is None or s.handle.get_publisher_count() >= s.publishers
                   for s in self.subs.values()):
                return
            self.spin_once(0.01)

    def finish(self) -> int:
        for sub in self.subs.values():
            if sub.handle is not None:
                try:
                    self.drain(sub)
                except Exception:  # noqa: BLE001 - context may already be shutting down
                    pass
        meta = self.writer.close()
        try:
            self.node.destroy_node()
            self.rclpy.shutdown(context=self.ctx)
        except Exception:  # noqa: BLE001
            pass
        print(f"RECORDED {meta.message_count} messages on {len(meta.topics)} topics "
              f"to {self.writer.path}", flush=True)
        return 0


def _noop(*_: Any) -> None:
    """Subscriptions are drained by :meth:`Recorder.drain`, never by an executor."""


def _abs(topic: str) -> str:
    return topic if topic.startswith("/") else "/" + topic


def _domain_id() -> int:
    try:
        return int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
    except ValueError:
        return 0


def _log(msg: str) -> None:
    print(f"[recorder] {msg}", file=sys.stderr, flush=True)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m grader.bag.recorder",
                                description="Record topics of the live ROS graph to a rosbag2 MCAP bag.")
    add_arguments(p)
    return p


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--output", required=True, type=Path, help="bag directory to create")
    p.add_argument("topics", nargs="*", help="topics to record (exact names)")
    p.add_argument("--regex", "-e", help="also record topics matching this regular expression")
    p.add_argument("--exclude", "-x", help="do not record topics matching this regular expression")
    p.add_argument("--all", "-a", action="store_true",
                   help="record every topic, hidden ones included (default without topics/regex)")
    p.add_argument("--poll-interval", type=float, default=0.1,
                   help="seconds between graph polls for new topics (default 0.1)")
    p.add_argument("--chunk-age", type=float, default=1.0,
                   help="close a chunk after this many seconds (bounds SIGKILL loss; default 1)")
    p.add_argument("--chunk-size", type=int, default=1 << 20, help="chunk size in bytes (default 1 MiB)")
    p.add_argument("--qos-depth", type=int, default=1000,
                   help="subscription queue depth (default 1000; absorbs bursts)")
    p.add_argument("--batch", type=float, default=0.05,
                   help="while traffic is light, wake at most this often (s) and drain what arrived "
                        "(receive times come from DDS, so they are unchanged; default 0.05)")
    p.add_argument("--node-name", default="grader_recorder")
    p.add_argument("--verbose", "-v", action="store_true", help="log publisher changes to stderr")
    p.add_argument("--lockstep", action="store_true",
                   help="the graph runs on the simulator's lockstep clock: noted in the bag's custom_data "
                        "(each time maps to the tick of the last /clock before it)")
    p.add_argument("--time-scale", type=float, default=None, metavar="K",
                   help="the graph runs on simulated time K times faster than the wall clock: "
                        "noted in the bag's custom_data (log times stay wall clock; /clock maps "
                        "them, see grader.bag.timebase)")
    p.add_argument("--ready-timeout", type=float, default=2.0,
                   help="seconds to wait for initial publishers to match before READY")


def run(args: argparse.Namespace) -> int:
    """Record until SIGINT/SIGTERM (arguments as :func:`add_arguments` defines them)."""
    from grader.errors import GraderError  # noqa: PLC0415 - bag.recorder loads in every scenario child process; errors only on this path

    # handlers first: a stop that comes while the recorder is still starting (a batch's Ctrl-C
    # during start-up) must not leave a bag file behind that was never finalized
    stopping: list[Any] = []

    def on_signal(signum: int, _frame: Any) -> None:
        stopping.append(signum)
        if rec is not None:
            rec.stop = True

    rec: Recorder | None = None
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        rec = Recorder(args)
    except GraderError as exc:
        print(f"grader: error: {exc}", file=sys.stderr)
        return 2
    rec.stop = rec.stop or bool(stopping)
    try:
        return rec.run()
    except BaseException:  # noqa: BLE001 - re-raised once the bag is closed
        # whatever happened, leave a readable bag behind
        try:
            rec.writer.close()
        finally:
            raise


def main(argv: list[str] | None = None) -> int:
    from grader.rosenv import add_interface_paths  # noqa: PLC0415 - bag.recorder loads in every scenario child process; rosenv only on this path

    add_interface_paths()     # a grader process: the students' types from the grader's own build of them
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
