"""Write a rosbag2 bag directory (MCAP storage, metadata.yaml version 9) — no ROS needed.

Used by the recorder (live CDR from rclpy), by ``bag repair`` (rewriting what survived a crash),
and by tests/benchmarks that synthesise bags. Conventions follow rosbag2 Jazzy's MCAP plugin:
profile ``ros2``, schema encoding ``ros2msg``, channel metadata ``offered_qos_profiles`` (YAML
text) and ``topic_type_hash``, a ``rosbag2`` Metadata record holding the metadata.yaml text.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from grader.bag.mcap_io import McapWriter
from grader.bag.metadata import BagMetadata, FileInfo, TopicInfo, qos_from_any
from grader.errors import GraderError

LIBRARY = "grader-bag/0.1 (rosbag2-compatible MCAP)"


@dataclass
class _Topic:
    info: TopicInfo
    definition: str
    definition_encoding: str
    channel_id: int = 0                       # 0 until the channel record is written
    late_offers: list[dict[str, Any]] = field(default_factory=list)


#: custom_data key for offers of publishers that appeared after a topic's channel was written
LATE_QOS_KEY = "grader.late_offered_qos_profiles"


def qos_yaml(profiles: list[dict[str, Any]]) -> str:
    """Offered QoS profiles as the YAML text rosbag2 puts in MCAP channel metadata."""
    return yaml.safe_dump(profiles, sort_keys=False, default_flow_style=False) if profiles else ""


def rosbags_safe_hash(type_name: str, type_hash: str) -> str:
    """The hash to put in metadata.yaml: empty for ``pkg/srv/...`` types.

    rosbags (0.11) files service types under ``pkg/srv/msg/Name`` when it parses their stored
    definition, so a metadata hash for ``pkg/srv/Name_Event`` makes its AnyReader fail to open the
    bag. The hash stays in the MCAP channel metadata (``topic_type_hash``), where we read it.
    """
    return "" if "/srv/" in type_name else type_hash


class BagWriter:
    """Create ``bag_dir`` and write messages to ``<name>_0.mcap`` in it.

    ``close()`` writes the MCAP summary and metadata.yaml; until then every chunk older than
    ``chunk_age_s`` or larger than ``chunk_size`` is already on disk (see :class:`McapWriter`).

    A topic's MCAP channel is written with its first message (or at close), carrying the QoS
    offers known by then; metadata.yaml repeats exactly those (readers such as rosbags match
    the two). Offers of publishers that appear later go to custom_data[LATE_QOS_KEY].
    """

    def __init__(self, bag_dir: Path | str, *, chunk_size: int = 1 << 20, chunk_age_s: float = 1.0,
                 custom_data: dict[str, str] | None = None) -> None:
        self.path = Path(bag_dir)
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            raise GraderError(f"output bag {self.path} already exists; choose a new directory "
                              "(the recorder never overwrites a bag).")
        self.path.mkdir(parents=True, exist_ok=True)
        self.file_name = f"{self.path.name}_0.mcap"
        self.mcap = McapWriter(self.path / self.file_name, library=LIBRARY,
                               chunk_size=chunk_size, chunk_age_s=chunk_age_s)
        self.topics: dict[str, _Topic] = {}
        self._schemas: dict[str, int] = {}
        self.custom_data = dict(custom_data or {})
        self.message_count = 0

    def add_topic(self, name: str, type_name: str, definition: str = "", *,
                  offered_qos_profiles: list[dict[str, Any]] | None = None,
                  type_hash: str = "", definition_encoding: str = "ros2msg") -> None:
        """Declare a topic (once). ``definition`` is the complete ros2msg text."""
        if name in self.topics:
            return
        info = TopicInfo(name, type_name, 0, "cdr", qos_from_any(list(offered_qos_profiles or [])),
                         type_hash)
        self.topics[name] = _Topic(info, definition, definition_encoding if definition else "")

    def _channel(self, t: _Topic) -> int:
        info = t.info
        sid = self._schemas.get(info.type)
        if sid is None:
            sid = self.mcap.add_schema(info.type, t.definition_encoding, t.definition.encode())
            self._schemas[info.type] = sid
        meta = {"offered_qos_profiles": qos_yaml(info.offered_qos_profiles)}
        if info.type_description_hash:
            meta["topic_type_hash"] = info.type_description_hash
        t.channel_id = self.mcap.add_channel(sid, info.name, "cdr", meta)
        return t.channel_id

    def update_qos(self, name: str, profiles: list[dict[str, Any]]) -> None:
        """All offers seen so far for a topic (see the class docstring for where they go)."""
        t = self.topics[name]
        profiles = qos_from_any(list(profiles))
        if not t.channel_id:
            t.info.offered_qos_profiles = list(profiles)
        else:
            # ``profiles`` grows in discovery order, so what the channel holds is a prefix of it
            t.late_offers = list(profiles[len(t.info.offered_qos_profiles):])

    def write(self, topic: str, log_time_ns: int, data: bytes, publish_time_ns: int = 0,
              sequence: int = 0) -> None:
        t = self.topics[topic]
        cid = t.channel_id or self._channel(t)
        self.mcap.write_message(cid, log_time_ns, publish_time_ns, data, sequence)
        t.info.message_count += 1
        self.message_count += 1

    def poll(self) -> None:
        self.mcap.poll()

    def metadata(self) -> BagMetadata:
        start = self.mcap.start_time or 0
        end = self.mcap.end_time or 0
        custom = dict(self.custom_data)
        late = {n: t.late_offers for n, t in self.topics.items() if t.late_offers}
        if late:
            custom[LATE_QOS_KEY] = yaml.safe_dump(late, sort_keys=False)
        topics = [TopicInfo(t.info.name, t.info.type, t.info.message_count, "cdr",
                            t.info.offered_qos_profiles,
                            rosbags_safe_hash(t.info.type, t.info.type_description_hash))
                  for t in self.topics.values()]
        return BagMetadata(
            topics=topics,
            files=[FileInfo(self.file_name, start, end - start, self.message_count)],
            starting_time_ns=start, duration_ns=end - start, message_count=self.message_count,
            custom_data=custom)

    def close(self) -> BagMetadata:
        if self.mcap.closed:
            return self.metadata()
        for t in self.topics.values():
            if not t.channel_id:
                self._channel(t)      # topics without messages are listed too, like rosbag2
        meta = self.metadata()
        text = meta.to_yaml()
        self.mcap.add_metadata("rosbag2", {"serialized_metadata": text, "ROS_DISTRO": meta.ros_distro})
        self.mcap.close()
        meta.write(self.path)
        return meta

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

