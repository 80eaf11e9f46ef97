"""Is a bag what ``ros2 bag``, rosbags and Foxglove expect? ``check_bag`` and ``grader bag verify``.

A bag conforms when:

* the three readers the field uses see the same messages per topic: ``rosbags``
  (``AnyReader``, every message deserialised), ``mcap`` with ``mcap-ros2-support``'s decoder
  (what Foxglove's Python tooling uses, every message decoded) and ours (:func:`load_frames`,
  every message decoded), and those counts are metadata.yaml's;
* each MCAP file's summary (profile, schemas, channels, per-channel counts, start/end) agrees
  with metadata.yaml, channel QoS and type hash included (rosbags matches topics by them and
  yields nothing on a mismatch);
* metadata.yaml and the MCAP Metadata record ``rosbag2`` decode the way rosbag2 Jazzy's
  ``rosbag2_storage/yaml.hpp`` decodes them (:mod:`grader.bag.rosbag2_yaml`): the file wraps the
  map in ``rosbag2_bagfile_information``, the record's ``serialized_metadata`` is the bare map.

Pure (no rclpy), so the grading pipeline and tests can call it on any bag.
"""

from __future__ import annotations

import contextlib
import io
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from grader.bag.metadata import (METADATA_FILE, BagMetadata, parse_metadata, parse_serialized,
                                 qos_from_any)
from grader.bag.reader import find_files
from grader.bag.rosbag2_yaml import qos_problems, rosbag2_map_problems
from grader.errors import GraderError



@dataclass
class Conformance:
    """The verdict on one bag: problems (none = conformant) and what the readers counted."""

    bag: Path
    problems: list[str] = field(default_factory=list)
    counts: dict[str, dict[str, int]] = field(default_factory=dict)   # reader -> topic -> n
    notes: list[str] = field(default_factory=list)   # known limits of a reader, not problems

    @property
    def ok(self) -> bool:
        return not self.problems


def check_bag(bag_dir: Path | str) -> list[str]:
    """One line per way the bag fails ``ros2 bag``/rosbags/Foxglove expectations; [] = conformant."""
    return verify(bag_dir).problems


def verify(bag_dir: Path | str) -> Conformance:
    bag_dir = Path(bag_dir)
    if not bag_dir.is_dir():
        raise GraderError(f"{bag_dir} is not a bag directory; pass the folder that holds "
                          "metadata.yaml and the .mcap file(s).")
    out = Conformance(bag_dir)
    p = out.problems
    meta: BagMetadata | None = None
    meta_file = bag_dir / METADATA_FILE
    if not meta_file.is_file():
        p.append(f"no {METADATA_FILE} (the recorder did not finish): run `grader bag repair {bag_dir}`")
    else:
        text = meta_file.read_text(errors="replace")
        try:
            meta = parse_metadata(text, METADATA_FILE)
        except GraderError as exc:
            p.append(str(exc))
        else:
            p += rosbag2_map_problems(yaml.safe_load(text).get("rosbag2_bagfile_information"),
                                      METADATA_FILE)
    try:
        files, _, _ = find_files(bag_dir)
    except GraderError as exc:
        p.append(str(exc))
        return out
    for f in files:
        p += _file_problems(f, meta, single=len(files) == 1)
    if meta is not None:
        p += _summary_problems(files, meta)
    expected = {t.name: t.message_count for t in meta.topics} if meta else None
    for name, count in (("rosbags", _rosbags_counts), ("mcap", _mcap_counts),
                        ("grader", _grader_counts)):
        try:
            out.counts[name] = count(bag_dir, files, out.notes)
        except Exception as exc:  # noqa: BLE001 - any failure of a reader is the finding
            msg = " ".join(str(exc).split())[:300]
            p.append(f"{name} cannot read the bag: {type(exc).__name__}: {msg}")
    topics = sorted(set(expected or {}).union(*(c.keys() for c in out.counts.values())))
    for topic in topics:
        seen = {name: c.get(topic, 0) for name, c in out.counts.items()}
        if expected is not None:
            seen = {METADATA_FILE: expected.get(topic, 0), **seen}
        if len(set(seen.values())) > 1:
            p.append(f"topic {topic}: readers disagree on the message count ("
                     + ", ".join(f"{k} {v}" for k, v in seen.items()) + ")")
    return out


# --------------------------------------------------------------------------------------------
# the three readers

def _rosbags_counts(bag_dir: Path, files: list[Path], notes: list[str]) -> dict[str, int]:
    from rosbags.highlevel import AnyReader  # noqa: PLC0415 - rosbags.highlevel: 50 ms CPU to import, paid only on this path
    from rosbags.typesys.msg import normalize_msgtype  # noqa: PLC0415 - rosbags.typesys.msg: 50 ms CPU to import, paid only on this path

    counts: Counter = Counter()
    with AnyReader([bag_dir]) as r:
        for conn, _, raw in r.messages():
            # rosbags 0.11 registers pkg/srv/Name types as pkg/srv/msg/Name (its own name for
            # them), while the connection keeps the bag's type name
            typ = conn.msgtype
            if typ not in r.typestore.fielddefs:
                typ = normalize_msgtype(typ)
            r.deserialize(raw, typ)
            counts[conn.topic] += 1
    return dict(counts)


def _mcap_counts(bag_dir: Path, files: list[Path], notes: list[str]) -> dict[str, int]:
    from mcap.reader import make_reader  # noqa: PLC0415 - mcap.reader: 43 ms CPU to import, paid only on this path
    from mcap_ros2.decoder import DecoderFactory  # noqa: PLC0415 - mcap_ros2.decoder: 40 ms CPU to import, paid only on this path

    counts: Counter = Counter()
    for f in files:
        factory = DecoderFactory()          # it caches by schema id: one per file
        decoders: dict[int, Any] = {}
        with open(f, "rb") as fh:
            for schema, channel, message in make_reader(fh, validate_crcs=True).iter_messages():
                if channel.id not in decoders:
                    decoders[channel.id] = _mcap_decoder(factory, schema, channel, notes)
                decode = decoders[channel.id]
                if decode is not None:
                    decode(message.data)
                counts[channel.topic] += 1
    return dict(counts)


def _mcap_decoder(factory: Any, schema: Any, channel: Any, notes: list[str]) -> Any:
    """mcap-ros2-support's decoder for a channel; None for the types it cannot parse by design.

    Its parser (a copy of rosidl_adapter) accepts only ``.msg``-style names: it rejects the
    service and action parts that appear on hidden topics (``pkg/srv/X_Event``,
    ``pkg/action/X_FeedbackMessage``, ...), whatever their definition says. Those channels are
    counted undecoded and noted; any other failure is a problem of the bag.
    """
    try:
        from mcap_ros2._vendor.rosidl_adapter.parser import InvalidResourceName  # noqa: PLC0415 - mcap_ros2._vendor.rosidl_adapter.parser: 40 ms CPU to import, paid only on this path
        name_errors: tuple = (InvalidResourceName,)
    except ImportError:      # a later release without that parser: every failure is a problem
        name_errors = ()
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            decode = factory.decoder_for(channel.message_encoding, schema)   # it prints on errors
    except name_errors:
        if schema is None or "/msg/" in schema.name:
            raise
        notes.append(f"mcap-ros2-support cannot parse {schema.name} (service/action part "
                     f"names are outside its .msg grammar); {channel.topic} counted undecoded")
        return None
    if decode is None:
        raise ValueError(f"no decoder for {channel.topic} (message encoding "
                         f"{channel.message_encoding!r}, schema {schema.encoding if schema else None!r})")
    return decode


def _grader_counts(bag_dir: Path, files: list[Path], notes: list[str]) -> dict[str, int]:
    from grader.bag.frames import load_frames  # noqa: PLC0415 - bag.frames loads pandas (424 ms CPU), only on this path

    return {name: len(df) for name, df in load_frames(bag_dir, time_scale=1.0).items() if len(df)}


# --------------------------------------------------------------------------------------------
# MCAP files against metadata.yaml

def _file_problems(path: Path, meta: BagMetadata | None, single: bool) -> list[str]:
    """Header, channels and the ``rosbag2`` record of one file, read as rosbag2 reads them."""
    from mcap.reader import make_reader  # noqa: PLC0415 - mcap.reader: 43 ms CPU to import, paid only on this path

    p: list[str] = []
    name = path.name
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        try:
            header = reader.get_header()
            summary = reader.get_summary()
        except Exception as exc:  # noqa: BLE001
            return [f"{name}: mcap cannot read the file ({type(exc).__name__}: {exc}); "
                    "run `grader bag repair BAG`"]
        if header.profile != "ros2":
            p.append(f"{name}: MCAP profile is {header.profile!r}, rosbag2 writes 'ros2'")
        if summary is None or summary.statistics is None:
            return p + [f"{name}: no MCAP summary/statistics (the writer did not finish); "
                        "run `grader bag repair BAG`"]
        for ch in summary.channels.values():
            schema = summary.schemas.get(ch.schema_id)
            if schema is None:
                p.append(f"{name}: channel {ch.topic} has no schema (rosbag2 refuses to open it)")
            elif schema.encoding != "ros2msg":
                p.append(f"{name}: {ch.topic} ({schema.name}) has schema encoding "
                         f"{schema.encoding!r}, not 'ros2msg': Foxglove cannot decode it")
            if ch.message_encoding != "cdr":
                p.append(f"{name}: {ch.topic} is encoded as {ch.message_encoding!r}, not 'cdr'")
            for key in ("offered_qos_profiles", "topic_type_hash"):
                if key not in ch.metadata:
                    p.append(f"{name}: channel {ch.topic} lacks the metadata key {key!r}")
            qos = ch.metadata.get("offered_qos_profiles", "")
            try:
                doc = yaml.safe_load(qos) if qos else []
            except yaml.YAMLError:
                doc = "not YAML"
            p += qos_problems(doc or [], f"{name}: channel {ch.topic} offered_qos_profiles")
        records = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
    if not records:
        return p + [f"{name}: no MCAP metadata record 'rosbag2' (ros2 bag reads the bag's "
                    "version and ROS distro from it)"]
    where = f"{name}: record 'rosbag2'"
    text = records[-1].metadata.get("serialized_metadata")
    if text is None:
        return p + [f"{where} has no key 'serialized_metadata'"]
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        return p + [f"{where}: serialized_metadata is not YAML ({exc.__class__.__name__})"]
    p += rosbag2_map_problems(doc, f"{where} serialized_metadata")
    if single and meta is not None and not p:
        rec = parse_serialized(text)
        if _core(rec) != _core(meta):
            p.append(f"{where} serialized_metadata disagrees with {METADATA_FILE} (topics, counts "
                     "or times)")
    return p


def _core(m: BagMetadata) -> tuple:
    return (m.version, m.message_count, m.starting_time_ns, m.duration_ns,
            sorted((t.name, t.type, t.message_count) for t in m.topics))


def _summary_problems(files: list[Path], meta: BagMetadata) -> list[str]:
    """metadata.yaml's topics, counts, QoS, hashes and times against the MCAP summaries."""
    from mcap.reader import make_reader  # noqa: PLC0415 - mcap.reader: 43 ms CPU to import, paid only on this path

    p: list[str] = []
    channels: dict[str, tuple[str, dict[str, str]]] = {}
    counts: Counter = Counter()
    starts, ends, total = [], [], 0
    by_file = {f.path: f for f in meta.files}
    for path in files:
        with open(path, "rb") as fh:
            try:
                summary = make_reader(fh).get_summary()
            except Exception:  # noqa: BLE001 - reported by _file_problems
                return p
        if summary is None or summary.statistics is None:
            return p
        stats = summary.statistics
        for cid, ch in summary.channels.items():
            schema = summary.schemas.get(ch.schema_id)
            channels.setdefault(ch.topic, (schema.name if schema else "", ch.metadata))
            counts[ch.topic] += stats.channel_message_counts.get(cid, 0)
        total += stats.message_count
        if stats.message_count:
            starts.append(stats.message_start_time)
            ends.append(stats.message_end_time)
        fi = by_file.get(path.name)
        if fi is not None and (fi.message_count, fi.starting_time_ns, fi.duration_ns) != (
                stats.message_count, stats.message_start_time,
                stats.message_end_time - stats.message_start_time):
            p.append(f"{METADATA_FILE}: files entry {path.name} (count {fi.message_count}, start "
                     f"{fi.starting_time_ns}, duration {fi.duration_ns}) disagrees with its MCAP "
                     f"statistics ({stats.message_count}, {stats.message_start_time}, "
                     f"{stats.message_end_time - stats.message_start_time})")
    listed = {t.name: t for t in meta.topics}
    for topic in sorted(set(listed) - set(channels)):
        p.append(f"{METADATA_FILE} lists {topic}, which has no MCAP channel")
    for topic in sorted(set(channels) - set(listed)):
        p.append(f"MCAP channel {topic} is missing from {METADATA_FILE}")
    for topic in sorted(set(listed) & set(channels)):
        t, (schema_name, cmeta) = listed[topic], channels[topic]
        if t.type != schema_name:
            p.append(f"{topic}: {METADATA_FILE} type {t.type} but MCAP schema {schema_name}")
        if t.message_count != counts[topic]:
            p.append(f"{topic}: {METADATA_FILE} counts {t.message_count} messages, the MCAP "
                     f"statistics {counts[topic]}")
        try:
            offered = qos_from_any(cmeta.get("offered_qos_profiles"))
        except GraderError:
            offered = None
        if offered != t.offered_qos_profiles:
            p.append(f"{topic}: offered_qos_profiles of {METADATA_FILE} ({len(t.offered_qos_profiles)}"
                     f" profile(s)) differ from its MCAP channel's ({len(offered or [])}); rosbags "
                     "then yields no message of the topic")
        h = cmeta.get("topic_type_hash", "")
        if t.type_description_hash != h and not (t.type_description_hash == "" and "/srv/" in t.type):
            p.append(f"{topic}: type_description_hash {t.type_description_hash!r} of "
                     f"{METADATA_FILE} differs from the channel's {h!r}")
    if total != meta.message_count:
        p.append(f"{METADATA_FILE} message_count {meta.message_count}, MCAP statistics {total}")
    start, end = (min(starts), max(ends)) if starts else (0, 0)
    if (meta.starting_time_ns, meta.duration_ns) != (start, end - start):
        p.append(f"{METADATA_FILE} starting_time/duration {meta.starting_time_ns}/{meta.duration_ns}"
                 f" ns, MCAP statistics {start}/{end - start} ns")
    return p

