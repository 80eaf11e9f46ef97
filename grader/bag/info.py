"""``grader bag info BAG [--json]``: what ``ros2 bag info`` prints, plus per-topic rates.

Counts and times come from the messages actually in the MCAP files (not from metadata.yaml), so
a crashed recording reports what is really readable, and says that it needs ``bag repair``.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path
from typing import Any

import numpy as np

from grader.bag.reader import open_bag

SERVICE_EVENT_SUFFIX = "/_service_event"


def _rate(lt: np.ndarray) -> dict[str, float | None]:
    """Mean rate over the topic's own span (what ``ros2 topic hz`` averages), the rate of the
    median period (robust to a publisher that skipped ticks), and period statistics (seconds)."""
    if len(lt) < 2:
        return {"rate_hz": None, "rate_median_hz": None, "period_median_s": None,
                "period_std_s": None, "period_max_s": None}
    span = (int(lt[-1]) - int(lt[0])) / 1e9
    d = np.diff(lt) / 1e9
    med = float(np.median(d))
    return {"rate_hz": (len(lt) - 1) / span if span > 0 else None,
            "rate_median_hz": 1.0 / med if med > 0 else None,
            "period_median_s": med, "period_std_s": float(np.std(d)),
            "period_max_s": float(np.max(d))}


def bag_info(bag_dir: Path | str) -> dict[str, Any]:
    """The numbers behind ``bag info`` as a JSON-serialisable dict."""
    bag = open_bag(bag_dir)
    lo, hi = bag.time_range()
    size = sum(f.stat().st_size for f in bag.files)
    topics = []
    for name in sorted(bag.topics):
        td = bag.topics[name]
        lt = td.log_times()
        entry: dict[str, Any] = {"name": name, "type": td.type, "count": td.count,
                 "serialization_format": td.serialization_format,
                 "first": float(lt[0]) / 1e9 if len(lt) else None,
                 "last": float(lt[-1]) / 1e9 if len(lt) else None,
                 "offered_qos_profiles": td.offered_qos_profiles,
                 "type_description_hash": td.type_description_hash,
                 "has_definition": bool(td.definition)}
        entry.update(_rate(lt))
        topics.append(entry)
    meta = bag.metadata
    return {
        "path": str(bag.path), "files": [f.name for f in bag.files], "size_bytes": size,
        "storage_identifier": "mcap", "ros_distro": (meta.ros_distro if meta else "") or "",
        "finalized": bag.finalized, "problems": bag.problems,
        "start": lo / 1e9 if bag.message_count else None,
        "end": hi / 1e9 if bag.message_count else None,
        "duration_s": (hi - lo) / 1e9, "message_count": bag.message_count,
        "topics": [t for t in topics if not t["name"].endswith(SERVICE_EVENT_SUFFIX)],
        "services": [dict(t, service=t["name"][: -len(SERVICE_EVENT_SUFFIX)])
                     for t in topics if t["name"].endswith(SERVICE_EVENT_SUFFIX)],
    }


def _size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{n} B"
        n /= 1024
    return f"{n} B"


def _when(t: float | None) -> str:
    if t is None:
        return "-"
    stamp = _dt.datetime.fromtimestamp(t).strftime("%b %d %Y %H:%M:%S.%f")[:-3]
    return f"{stamp} ({t:.9f})"


def format_info(info: dict[str, Any]) -> str:
    lines = [
        f"Files:             {', '.join(info['files'])}",
        f"Bag size:          {_size(info['size_bytes'])}",
        f"Storage id:        {info['storage_identifier']}",
        f"ROS Distro:        {info['ros_distro'] or 'unknown'}",
        f"Duration:          {info['duration_s']:.9f}s",
        f"Start:             {_when(info['start'])}",
        f"End:               {_when(info['end'])}",
        f"Messages:          {info['message_count']}",
        f"Status:            {'finalized' if info['finalized'] else 'NOT FINALIZED'}",
    ]
    for p in info["problems"]:
        lines.append(f"  ! {p}")

    def rate(t: dict) -> str:
        if not t["rate_hz"]:
            return "-"
        return f"{t['rate_hz']:.2f} Hz (median period {t['period_median_s'] * 1e3:.2f} ms)"

    width = max([len(t["name"]) for t in info["topics"] + info["services"]] + [5])
    lines.append(f"Topic information: {len(info['topics'])} topic(s)")
    for t in info["topics"]:
        lines.append(f"  Topic: {t['name']:<{width}} | Type: {t['type']} | Count: {t['count']} | "
                     f"Serialization Format: {t['serialization_format']} | Rate: {rate(t)}")
    lines.append(f"Service information: {len(info['services'])} service(s)")
    for t in info["services"]:
        lines.append(f"  Service: {t['service']:<{width}} | Type: {t['type'].removesuffix('_Event')} | "
                     f"Event Count: {t['count']} | Serialization Format: {t['serialization_format']}")
    return "\n".join(lines)

