"""rclpy-side helpers shared by the recorder and replay: message classes and QoS conversion.

Kept apart from the pure modules so that analysis code never imports rclpy by accident.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any

from grader.bag.metadata import INFINITE, default_qos
from grader.bag.msgdefs import normalize_type, split_type


def message_class(type_name: str) -> Any:
    """The generated Python class of a topic type, including hidden ones.

    ``pkg/srv/Spawn_Event`` and ``pkg/action/X_FeedbackMessage`` have no module of their own;
    rosidl puts them next to their service/action class, so we import that and look beside it.
    """
    pkg, kind, name = split_type(normalize_type(type_name))
    try:
        module = importlib.import_module(f"{pkg}.{kind}")
    except ImportError as exc:
        raise LookupError(f"cannot import {pkg}.{kind} for {type_name} ({exc}); is the interface "
                          "package built and on PYTHONPATH?") from None
    cls = getattr(module, name, None)
    if cls is not None:
        return cls
    parts = name.split("_")
    for i in range(len(parts) - 1, 0, -1):
        base = getattr(module, "_".join(parts[:i]), None)
        if base is not None:
            cls = getattr(sys.modules[base.__module__], name, None)
            if cls is not None:
                return cls
    raise LookupError(f"{pkg}.{kind} has no type {name} (from {type_name})")


def _duration_dict(d: Any) -> dict[str, int]:
    ns = getattr(d, "nanoseconds", None)
    if ns is None:
        return dict(INFINITE)
    if ns >= 2**63 - 1 or ns < 0:
        return dict(INFINITE)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def qos_to_dict(qos: Any) -> dict[str, Any]:
    """An rclpy QoSProfile (as offered by a publisher) in rosbag2 Jazzy's metadata spelling."""
    def name(policy: Any) -> str:
        return policy.name.lower() if hasattr(policy, "name") else str(policy).lower()

    return {
        "history": name(qos.history), "depth": int(qos.depth),
        "reliability": name(qos.reliability), "durability": name(qos.durability),
        "deadline": _duration_dict(qos.deadline), "lifespan": _duration_dict(qos.lifespan),
        "liveliness": name(qos.liveliness),
        "liveliness_lease_duration": _duration_dict(qos.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions),
    }


def _duration(d: dict[str, int]):
    from rclpy.duration import Duration, Infinite  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install

    if d.get("sec", 0) >= INFINITE["sec"] or d.get("sec", 0) >= 0x7FFFFFFF:
        return Infinite
    return Duration(seconds=int(d.get("sec", 0)), nanoseconds=int(d.get("nsec", 0)))


def dict_to_qos(d: dict[str, Any], depth: int = 10):
    """A QoSProfile to *offer* when replaying a recorded offer (history becomes keep_last)."""
    from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install
                           ReliabilityPolicy)

    q = dict(default_qos(), **d)

    def pick(enum: Any, value: str, fallback: Any) -> Any:
        member = getattr(enum, str(value).upper(), None)
        return member if member is not None and str(value) not in ("unknown",) else fallback

    rel = pick(ReliabilityPolicy, q["reliability"], ReliabilityPolicy.RELIABLE)
    dur = pick(DurabilityPolicy, q["durability"], DurabilityPolicy.VOLATILE)
    liv = pick(LivelinessPolicy, q["liveliness"], LivelinessPolicy.SYSTEM_DEFAULT)
    if rel.name == "BEST_AVAILABLE":
        rel = ReliabilityPolicy.RELIABLE
    if dur.name == "BEST_AVAILABLE":
        dur = DurabilityPolicy.VOLATILE
    if liv.name == "BEST_AVAILABLE":
        liv = LivelinessPolicy.SYSTEM_DEFAULT
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=max(depth, int(q.get("depth") or 0)),
                      reliability=rel, durability=dur, deadline=_duration(q["deadline"]),
                      lifespan=_duration(q["lifespan"]), liveliness=liv,
                      liveliness_lease_duration=_duration(q["liveliness_lease_duration"]),
                      avoid_ros_namespace_conventions=bool(q["avoid_ros_namespace_conventions"]))


def replay_offer(profiles: list[dict[str, Any]]) -> dict[str, Any]:
    """rosbag2's rule: offer the recorded profile when all publishers agreed, else the default."""
    if not profiles:
        return default_qos()
    keys = ("reliability", "durability", "deadline", "liveliness", "liveliness_lease_duration")
    first = profiles[0]
    if all(all(p.get(k) == first.get(k) for k in keys) for p in profiles[1:]):
        return dict(first)
    return default_qos()
