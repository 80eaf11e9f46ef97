"""Synthetic publishers for recorder tests, benchmarks and fixture regeneration.

``python -m grader.bag.loadgen --type turtlesim/msg/Pose --topics /p --rate 62.5 --count 625``

Publishes ``count`` messages per topic on a wall-clock schedule (messages due are sent together,
so high rates stay exact on a busy machine), after waiting until every publisher is matched by
``--wait-subscribers`` subscriptions — so a test knows exactly how many messages a lossless
recorder must hold. Message ``i`` carries ``i`` in its first numeric field(s) so order and loss
are checkable from the bag. Prints ``READY`` when matched and ``DONE <n> in <s> s`` at the end
(``s`` = time spent publishing, so ``n / s`` is the achieved rate).
"""

from __future__ import annotations

import os
import argparse
import math
import random
import sys
import time
from typing import Any

from grader.executors import spin_until


def fill(msg: Any, i: int, pattern: str, rng: random.Random) -> Any:
    """Put the index (or random data) into a message; knows a few types, else the first floats."""
    if pattern == "uniform_pairs" and hasattr(msg, "data"):
        msg.data = [rng.random(), rng.random()]
        return msg
    if pattern == "circle" and hasattr(msg, "angular") and hasattr(msg, "linear"):
        msg.linear.x, msg.angular.z = 2.0, 1.0     # geometry_msgs/Twist: drive a 2 m circle
        return msg
    if pattern == "circle" and hasattr(msg, "theta"):
        # a turtle driving a circle of radius 2 m around (5.5, 5.5) at 1 rad/s, 62.5 Hz
        a = i * 0.016
        msg.x, msg.y = 5.5 + 2 * math.cos(a), 5.5 + 2 * math.sin(a)
        msg.theta = float((a + math.pi / 2 + math.pi) % (2 * math.pi) - math.pi)
        msg.linear_velocity, msg.angular_velocity = 2.0, 1.0
        return msg
    if hasattr(msg, "goal_id"):
        msg.goal_id.uuid = [i & 0xFF, (i >> 8) & 0xFF] + [0] * 14
    for name, typ in msg.get_fields_and_field_types().items():
        if typ in ("float", "double"):
            setattr(msg, name, float(i))
        elif typ in ("int32", "int64", "uint32", "uint64"):
            setattr(msg, name, i)
        elif typ == "string":
            setattr(msg, name, f"message {i}")
        elif "/" in typ and not typ.startswith("sequence"):
            fill(getattr(msg, name), i, pattern, rng)
    return msg


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m grader.bag.loadgen")
    p.add_argument("--type", required=True)
    p.add_argument("--topics", nargs="+", required=True)
    p.add_argument("--rate", type=float, default=10.0, help="messages per second per topic")
    p.add_argument("--count", type=int, default=10, help="messages per topic")
    p.add_argument("--pattern", default="counter", choices=("counter", "uniform_pairs", "circle"))
    p.add_argument("--seed", type=int, default=467)
    p.add_argument("--best-effort", action="store_true")
    p.add_argument("--transient-local", action="store_true")
    p.add_argument("--depth", type=int, default=1000)
    p.add_argument("--wait-subscribers", type=int, default=1,
                   help="wait until each publisher has this many matched subscriptions")
    p.add_argument("--wait-timeout", type=float, default=20.0)
    p.add_argument("--linger", type=float, default=0.5, help="seconds to stay up after the last message")
    p.add_argument("--service-calls", type=int, default=0,
                   help="also serve turtlesim/srv/TeleportAbsolute on /loadgen/teleport with "
                        "introspection (events transient local) and call it this many times, once "
                        "the event topic has --wait-subscribers subscriptions")
    p.add_argument("--node-name", default="loadgen")
    return p


def _publish_paced(pubs: list[Any], payloads: list[bytes], rate_hz: float) -> tuple[int, float]:
    """Every payload on every publisher at ``rate_hz`` (catching up after a late wake-up): how
    many rounds were sent and the seconds it took."""
    t0 = time.monotonic()
    sent, count = 0, len(payloads)
    period = 1.0 / rate_hz
    while sent < count:
        due = min(count, int((time.monotonic() - t0) / period) + 1)
        while sent < due:
            for pub in pubs:
                pub.publish(payloads[sent])
            sent += 1
        wait = t0 + sent * period - time.monotonic()
        if wait > 0:
            time.sleep(min(wait, 0.01) if wait < 0.002 else wait - 0.001)
    return sent, time.monotonic() - t0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)


    import rclpy  # noqa: PLC0415 - rclpy: ROS, imported where it is used (this module loads in processes that never use it)
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415 - rclpy.qos: ROS, imported where it is used (this module loads in processes that never use it)

    from grader.bag.rosio import message_class  # noqa: PLC0415 - bag.loadgen loads in every scenario child process; bag.rosio only on this path
    from grader.rosenv import add_interface_paths  # noqa: PLC0415 - bag.loadgen loads in every scenario child process; rosenv only on this path

    add_interface_paths()     # a grader process: the students' types from the grader's own build of them
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=int(os.environ.get("ROS_DOMAIN_ID", "0") or 0))
    node = rclpy.create_node(args.node_name, context=ctx)
    cls = message_class(args.type)
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=args.depth,
                     reliability=ReliabilityPolicy.BEST_EFFORT if args.best_effort else ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL if args.transient_local else DurabilityPolicy.VOLATILE)
    pubs = [node.create_publisher(cls, t, qos) for t in args.topics]
    from rclpy.serialization import serialize_message  # noqa: PLC0415 - rclpy.serialization: ROS, imported where it is used (this module loads in processes that never use it)

    rng = random.Random(args.seed)
    payloads = [serialize_message(fill(cls(), i, args.pattern, rng)) for i in range(args.count)]

    service_state: dict = {}
    if args.service_calls:
        _setup_service(node, service_state)

    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415 - rclpy.executors: ROS, imported where it is used (this module loads in processes that never use it)

    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    if not spin_until(ex, lambda: all(pub.get_subscription_count() >= args.wait_subscribers for pub in pubs),
                      args.wait_timeout):
        print("TIMEOUT waiting for subscribers", flush=True)
        return 3
    print("READY", flush=True)
    sent, elapsed = _publish_paced(pubs, payloads, args.rate)
    if args.service_calls:
        # the graph shows the subscriptions; their DDS match may follow, which the events'
        # transient-local history covers
        if not spin_until(ex, lambda: node.count_subscribers(EVENT_TOPIC) >= args.wait_subscribers,
                          args.wait_timeout):
            print("TIMEOUT waiting for subscribers of the service events", flush=True)
            return 3
        _call_service(node, ex, service_state, args.service_calls)
    end = time.monotonic() + args.linger
    while time.monotonic() < end:
        ex.spin_once(timeout_sec=0.02)
    print(f"DONE {sent * len(pubs)} in {elapsed:.3f} s", flush=True)
    ex.shutdown()
    node.destroy_node()
    rclpy.shutdown(context=ctx)
    return 0


#: where ``_setup_service``'s service publishes its introspection events
EVENT_TOPIC = "/loadgen/teleport/_service_event"


def _setup_service(node: Any, state: dict) -> None:
    """A service and its client, both with CONTENTS introspection. The events are transient
    local (depth 100): the introspection publisher is rcl's own, so its matches cannot be waited
    for, and a recorder whose subscription matches a moment after the graph shows it (CI: 2 of 12
    events in the bag, the first calls' lost) still gets every event."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415 - rclpy.qos: ROS, imported where it is used (this module loads in processes that never use it)
    from rclpy.service_introspection import ServiceIntrospectionState  # noqa: PLC0415 - rclpy.service_introspection: ROS, imported where it is used (this module loads in processes that never use it)
    from turtlesim.srv import TeleportAbsolute  # noqa: PLC0415 - turtlesim.srv: ROS, imported where it is used (this module loads in processes that never use it)

    events = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
    srv = node.create_service(TeleportAbsolute, "/loadgen/teleport", lambda req, resp: resp)
    srv.configure_introspection(node.get_clock(), events, ServiceIntrospectionState.CONTENTS)
    cli = node.create_client(TeleportAbsolute, "/loadgen/teleport")
    cli.configure_introspection(node.get_clock(), events, ServiceIntrospectionState.CONTENTS)
    state.update(srv=srv, cli=cli, cls=TeleportAbsolute)


def _call_service(node: Any, ex: Any, state: dict, n: int) -> None:
    cli, cls = state["cli"], state["cls"]
    cli.wait_for_service(timeout_sec=5.0)
    for i in range(n):
        fut = cli.call_async(cls.Request(x=float(i), y=1.0, theta=0.5))
        ex.spin_until_future_complete(fut, timeout_sec=5.0)


if __name__ == "__main__":
    sys.exit(main())
