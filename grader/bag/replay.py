"""``grader replay BAG``: publish a bag back into a live graph with its original timing.

Reads bags of our recorder and of real rosbag2 (Jazzy, MCAP), service-event topics included
(they are republished as the topics they were). Publishers offer the recorded QoS the way
rosbag2 does (the recorded offer when all publishers agreed, otherwise the default) and send
the recorded CDR bytes untouched. Timing follows receive (log) times, scaled by ``--rate``.

Readiness: ``READY`` is printed once publishers exist (and, with ``--wait-subscribers N``, are
matched); ``DONE <n>`` after the last message.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from grader.bag.reader import open_bag
from grader.errors import GraderError


@dataclass
class ReplayPlan:
    """Messages to send, in order: parallel lists of time (ns), publisher index and payload."""

    times: list[int]
    pubs: list[int]
    payloads: list[bytes]
    topics: list[tuple[str, str, str, list[dict]]]   # (bag topic, published name, type, offers)


def parse_remaps(items: list[str] | None) -> dict[str, str]:
    out = {}
    for item in items or []:
        if ":=" not in item:
            raise GraderError(f"--remap {item!r} is not of the form OLD:=NEW (e.g. "
                              "/turtle1/pose:=/replayed/pose).")
        old, new = item.split(":=", 1)
        out[_abs(old)] = _abs(new)
    return out


def _abs(topic: str) -> str:
    return topic if topic.startswith("/") else "/" + topic


def plan(bag_dir: Path | str, topics: list[str] | None = None, start_offset: float = 0.0,
         remaps: dict[str, str] | None = None) -> ReplayPlan:
    """Everything replay needs from the bag (pure: no rclpy), sorted by log time."""
    bag = open_bag(bag_dir)
    names = sorted(bag.topics)
    if topics:
        wanted = [_abs(t) for t in topics]
        missing = [t for t in wanted if t not in bag.topics]
        if missing:
            raise GraderError(f"bag {bag_dir} has no topic {', '.join(missing)} "
                              f"(topics: {', '.join(names) or 'none'}).")
        names = wanted
    remaps = remaps or {}
    lo, _ = bag.time_range()
    start = lo + int(start_offset * 1e9)
    index = {n: i for i, n in enumerate(names)}
    times, pubs, payloads = [], [], []
    for topic, lt, _pt, data in bag.iter_messages(names):
        if lt < start:
            continue
        times.append(lt)
        pubs.append(index[topic])
        payloads.append(bytes(data))
    return ReplayPlan(times, pubs, payloads,
                      [(n, remaps.get(n, n), bag.topics[n].type, bag.topics[n].offered_qos_profiles)
                       for n in names])


class _Stop:
    flag = False


def replay(p: ReplayPlan, *, rate: float = 1.0, loop: bool = False, clock_hz: float = 0.0,
           wait_subscribers: int = 0, wait_timeout: float = 10.0, delay: float = 0.0,
           domain_id: int | None = None, node_name: str = "grader_replay",
           log: Any = print) -> int:
    """Publish the plan; returns the number of messages sent (per pass, times passes)."""
    import rclpy  # noqa: PLC0415 - rclpy: ROS, imported where it is used (this module loads in processes that never use it)
    from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415 - rclpy.signals: ROS, imported where it is used (this module loads in processes that never use it)

    from grader.bag.rosio import dict_to_qos, message_class, replay_offer  # noqa: PLC0415 - bag.replay loads in every scenario child process; bag.rosio only on this path

    if rate <= 0:
        raise GraderError("--rate must be positive (1.0 = recorded speed).")
    if domain_id is None:
        domain_id = int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(node_name, context=ctx, enable_rosout=False,
                             start_parameter_services=False)
    try:
        publishers: list[Any] = []
        for topic, out_name, typ, offers in p.topics:
            try:
                cls = message_class(typ)
            except LookupError as exc:
                log(f"[replay] skipping {topic}: {exc}", file=sys.stderr)
                publishers.append(None)
                continue
            qos = dict_to_qos(replay_offer(offers), depth=100)
            publishers.append(node.create_publisher(cls, out_name, qos))
        clock_pub = None
        if clock_hz > 0:
            from rclpy.qos import QoSProfile  # noqa: PLC0415 - rclpy.qos: ROS, imported where it is used (this module loads in processes that never use it)
            from rosgraph_msgs.msg import Clock  # noqa: PLC0415 - rosgraph_msgs.msg: ROS, imported where it is used (this module loads in processes that never use it)
            clock_pub = node.create_publisher(Clock, "/clock", QoSProfile(depth=1))
        live = [x for x in publishers if x is not None]
        deadline = time.monotonic() + wait_timeout
        while wait_subscribers and time.monotonic() < deadline and not _Stop.flag:
            if all(x.get_subscription_count() >= wait_subscribers for x in live):
                break
            time.sleep(0.01)
        if delay > 0:
            time.sleep(delay)
        print("READY", flush=True)
        sent = 0
        while not _Stop.flag:
            sent += _one_pass(p, publishers, rate, clock_pub, clock_hz)
            if not loop or not p.times:
                break
        print(f"DONE {sent}", flush=True)
        time.sleep(0.2)   # let reliable writers hand over the last samples
        return sent
    finally:
        node.destroy_node()
        rclpy.shutdown(context=ctx)


def _clock_msg(ns: int):
    from rosgraph_msgs.msg import Clock  # noqa: PLC0415 - rosgraph_msgs.msg: ROS, imported where it is used (this module loads in processes that never use it)

    m = Clock()
    m.clock.sec, m.clock.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
    return m


def _one_pass(p: ReplayPlan, publishers: list[Any], rate: float, clock_pub: Any,
              clock_hz: float) -> int:
    if not p.times:
        return 0
    t0 = p.times[0]
    wall0 = time.monotonic()
    clock_period = 1.0 / clock_hz if clock_hz > 0 else None
    next_clock = wall0
    sent = 0
    for lt, idx, data in zip(p.times, p.pubs, p.payloads):
        target = wall0 + (lt - t0) / 1e9 / rate
        while True:
            if _Stop.flag:
                return sent
            now = time.monotonic()
            if clock_period is not None and now >= next_clock:
                clock_pub.publish(_clock_msg(t0 + int((now - wall0) * rate * 1e9)))
                next_clock += clock_period
                continue
            wait = target - now
            if wait <= 0:
                break
            if clock_period is not None:
                wait = min(wait, max(0.0, next_clock - now))
            # sleep most of the way, then yield in short steps: keeps timing within ~0.2 ms
            time.sleep(wait - 0.0005 if wait > 0.002 else wait / 2 if wait > 0.0002 else 0)
        pub = publishers[idx]
        if pub is not None:
            pub.publish(data)
            sent += 1
    return sent


def run(args: Any) -> int:
    p = plan(args.bag, args.topics, args.start_offset, parse_remaps(args.remap))
    print(f"[replay] {args.bag}: {len(p.times)} messages on {len(p.topics)} topics. To look at it instead: open "
          "its .mcap file in Foxglove, or the report's replay of the scenario (report.html#replay=<scenario>); "
          f"with a sourced ROS 2: ros2 bag play {args.bag}", file=sys.stderr)
    if not p.times:
        print("[replay] nothing to publish (no messages after the start offset)", file=sys.stderr)

    def on_signal(signum: int, _frame: Any) -> None:
        _Stop.flag = True

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    _Stop.flag = False
    try:
        replay(p, rate=args.rate, loop=args.loop, clock_hz=args.clock or 0.0,
               wait_subscribers=args.wait_subscribers, wait_timeout=args.wait_timeout,
               delay=args.delay)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0


def add_arguments(p: Any) -> None:
    p.add_argument("bag", type=Path, help="bag directory (ours or rosbag2 Jazzy MCAP)")
    p.add_argument("--rate", "-r", type=float, default=1.0, help="speed factor (default 1.0)")
    p.add_argument("--topics", nargs="+", help="replay only these topics")
    p.add_argument("--remap", "-m", action="append", metavar="OLD:=NEW",
                   help="publish topic OLD as NEW (repeatable)")
    p.add_argument("--loop", "-l", action="store_true", help="start over after the last message")
    p.add_argument("--start-offset", type=float, default=0.0,
                   help="skip the first S seconds of the bag")
    p.add_argument("--clock", type=float, nargs="?", const=40.0, default=0.0, metavar="HZ",
                   help="publish bag time on /clock at HZ (default 40 when given)")
    p.add_argument("--wait-subscribers", type=int, default=0, metavar="N",
                   help="before publishing, wait until every publisher has N subscriptions")
    p.add_argument("--wait-timeout", type=float, default=10.0)
    p.add_argument("--delay", type=float, default=0.0, help="sleep S seconds before publishing")


def main(argv: list[str] | None = None) -> int:
    from grader.rosenv import add_interface_paths  # noqa: PLC0415 - bag.replay loads in every scenario child process; rosenv only on this path

    add_interface_paths()     # a grader process: the students' types from the grader's own build of them
    parser = argparse.ArgumentParser(prog="python -m grader.bag.replay")
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except GraderError as exc:
        print(f"grader: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
