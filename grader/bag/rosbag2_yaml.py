"""rosbag2 Jazzy's rules for decoding bag metadata, as checks that name what would fail.

``ros2 bag`` decodes metadata.yaml (under ``rosbag2_bagfile_information``) and the MCAP record
``rosbag2`` (``serialized_metadata``, the bare map) with ``YAML::convert<BagMetadata>::decode``
(``rosbag2_storage/yaml.hpp``) and QoS profiles with ``convert<rclcpp::QoS>::decode``
(``rosbag2_storage/qos.cpp``): a missing field or a value of the wrong kind throws there. There
is no rosbag2 on the machines the grader runs on, so these checks restate those rules field by
field (which fields a version requires, and their kinds) for :mod:`grader.bag.conformance`.
"""

from __future__ import annotations

from typing import Any

QOS_ENUMS = {
    "history": {"system_default", "keep_last", "keep_all", "unknown"},
    "reliability": {"system_default", "reliable", "best_effort", "unknown", "best_available"},
    "durability": {"system_default", "transient_local", "volatile", "unknown", "best_available"},
    "liveliness": {"system_default", "automatic", "manual_by_topic", "unknown", "best_available"},
}
QOS_TIMES = ("deadline", "lifespan", "liveliness_lease_duration")


def _is_str(v: Any) -> bool:
    return isinstance(v, (str, int, float, bool)) and v is not None


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def rosbag2_map_problems(doc: Any, where: str) -> list[str]:
    """What ``YAML::convert<rosbag2_storage::BagMetadata>::decode`` would fail on, for ``doc``.

    ``doc`` is the bare map (the record's ``serialized_metadata``, or what metadata.yaml holds
    under ``rosbag2_bagfile_information``). Fields are required by version as yaml.hpp reads them.
    """
    if isinstance(doc, dict) and "rosbag2_bagfile_information" in doc and "version" not in doc:
        return [f"{where} is wrapped in 'rosbag2_bagfile_information'; rosbag2 reads the bare "
                "BagMetadata map there (run `grader bag repair BAG` to rewrite it)"]
    if not isinstance(doc, dict):
        return [f"{where} is not a YAML map"]
    p: list[str] = []

    def need(d: dict, key: str, check, what: str, at: str) -> Any:
        if key not in d:
            p.append(f"{where}: {at}{key} is missing")
            return None
        if not check(d[key]):
            p.append(f"{where}: {at}{key} must be {what}, not {d[key]!r}")
            return None
        return d[key]

    version = need(doc, "version", _is_int, "an integer", "")
    if version is None:
        return p
    need(doc, "storage_identifier", _is_str, "a string", "")
    for key, sub in (("duration", "nanoseconds"), ("starting_time", "nanoseconds_since_epoch")):
        d = need(doc, key, lambda v: isinstance(v, dict), "a map", "")
        if d is not None:
            need(d, sub, lambda v: _is_int(v) and v >= 0, "a non-negative integer", f"{key}.")
    need(doc, "message_count", lambda v: _is_int(v) and v >= 0, "a non-negative integer", "")
    topics = need(doc, "topics_with_message_count", lambda v: isinstance(v, list), "a list", "") or []
    for i, entry in enumerate(topics):
        at = f"topics_with_message_count[{i}]."
        if not isinstance(entry, dict):
            p.append(f"{where}: {at[:-1]} must be a map")
            continue
        need(entry, "message_count", _is_int, "an integer", at)
        tm = need(entry, "topic_metadata", lambda v: isinstance(v, dict), "a map", at)
        if tm is None:
            continue
        at += "topic_metadata."
        for key in ("name", "type", "serialization_format"):
            need(tm, key, _is_str, "a string", at)
        if version >= 9:
            qos = need(tm, "offered_qos_profiles", lambda v: isinstance(v, list),
                       "a list (version 9)", at)
            p += qos_problems(qos or [], f"{where}: {at}offered_qos_profiles")
        elif version >= 4:
            need(tm, "offered_qos_profiles", lambda v: isinstance(v, str), "a YAML string", at)
        if version >= 7:
            need(tm, "type_description_hash", _is_str, "a string", at)
    need(doc, "relative_file_paths", lambda v: isinstance(v, list) and all(map(_is_str, v)),
         "a list of strings", "")
    if version >= 3:
        need(doc, "compression_format", _is_str, "a string", "")
        need(doc, "compression_mode", _is_str, "a string", "")
    if version >= 5:
        for i, f in enumerate(need(doc, "files", lambda v: isinstance(v, list), "a list", "") or []):
            at = f"files[{i}]."
            if not isinstance(f, dict):
                p.append(f"{where}: {at[:-1]} must be a map")
                continue
            need(f, "path", _is_str, "a string", at)
            need(f, "message_count", _is_int, "an integer", at)
            for key, sub in (("duration", "nanoseconds"), ("starting_time", "nanoseconds_since_epoch")):
                d = need(f, key, lambda v: isinstance(v, dict), "a map", at)
                if d is not None:
                    need(d, sub, _is_int, "an integer", f"{at}{key}.")
    if version >= 6:
        need(doc, "custom_data", lambda v: v is None or (isinstance(v, dict) and all(
            _is_str(k) and _is_str(x) for k, x in v.items())), "a map of strings", "")
    if version >= 8:
        need(doc, "ros_distro", _is_str, "a string", "")
    return p


def qos_problems(profiles: Any, where: str) -> list[str]:
    """rosbag2's ``convert<rclcpp::QoS>::decode`` (version 9 strings or version 8 integers)."""
    if not isinstance(profiles, list):
        return [f"{where} must be a YAML list of QoS profiles"]
    p = []
    for i, q in enumerate(profiles):
        at = f"{where}[{i}]"
        if not isinstance(q, dict):
            p.append(f"{at} must be a map")
            continue
        missing = [k for k in (*QOS_ENUMS, "depth", *QOS_TIMES, "avoid_ros_namespace_conventions")
                   if k not in q]
        if missing:
            p.append(f"{at} lacks {', '.join(missing)}")
            continue
        numeric = _is_int(q["history"])
        for key, allowed in QOS_ENUMS.items():
            ok = _is_int(q[key]) if numeric else q[key] in allowed
            if not ok:
                p.append(f"{at}.{key} = {q[key]!r} is not one of {sorted(allowed)}")
        if not _is_int(q["depth"]):
            p.append(f"{at}.depth must be an integer")
        for key in QOS_TIMES:
            t = q[key]
            if not (isinstance(t, dict) and _is_int(t.get("sec")) and _is_int(t.get("nsec"))):
                p.append(f"{at}.{key} must be a map of integer sec and nsec")
        if not isinstance(q["avoid_ros_namespace_conventions"], bool):
            p.append(f"{at}.avoid_ros_namespace_conventions must be true or false")
    return p
