"""``grader bag repair BAG``: make a crashed (or old-format) recording a normal bag again.

A recorder killed with SIGKILL leaves an MCAP file without summary/footer (and possibly half a
chunk at its end) and no metadata.yaml. Every chunk that was completely written is still
readable (:func:`grader.bag.mcap_scan.scan`); repair rewrites those messages into a fresh,
finalized MCAP file through the ``mcap`` writer (keeping the damaged one as
``<name>.mcap.damaged`` unless told not to) and writes metadata.yaml and the ``rosbag2`` record
from what the files really hold, so rosbags, ``mcap`` and ``ros2 bag`` read it.

Bags written before the ``rosbag2`` record followed rosbag2 (their ``serialized_metadata`` was
wrapped in ``rosbag2_bagfile_information``, which ``ros2 bag`` cannot decode) are rewritten too.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from grader.bag.mcap_scan import ScanResult
from grader.bag.metadata import BagMetadata, qos_from_any, qos_yaml
from grader.bag.reader import Bag, metadata_from_bag, open_bag
from grader.bag.writer import METADATA_RECORD, open_mcap, rosbag2_record


@dataclass
class RepairReport:
    bag: Path
    rewritten: list[str]
    messages: int
    already_ok: bool

    def summary(self) -> str:
        if self.already_ok:
            return f"{self.bag}: bag is intact ({self.messages} messages); nothing to repair."
        files = ", ".join(self.rewritten) or "no MCAP file"
        return (f"{self.bag}: recovered {self.messages} messages; rewrote {files} and "
                "metadata.yaml.")


def wrapped_rosbag2_record(res: ScanResult) -> bool:
    """True when the file's ``rosbag2`` record holds metadata.yaml's wrapped form (our old bug)."""
    text = res.metadata.get(METADATA_RECORD, {}).get("serialized_metadata", "")
    try:
        doc = yaml.safe_load(text) if text else None
    except yaml.YAMLError:
        return False
    return isinstance(doc, dict) and "rosbag2_bagfile_information" in doc


def _keep_listed_offers(bag: Bag, rewrite: list[ScanResult]) -> None:
    """Old bags list offers in metadata.yaml that their channels lack: the rewritten channels
    carry them, so that the QoS survives and both places agree again."""
    listed = {t.name: t.offered_qos_profiles for t in bag.metadata.topics} if bag.metadata else {}
    for res in rewrite:
        for ch in res.channels.values():
            offers = listed.get(ch.topic)
            if offers and not qos_from_any(ch.metadata.get("offered_qos_profiles")):
                ch.metadata = {**ch.metadata, "offered_qos_profiles": qos_yaml(offers)}
                bag.topics[ch.topic].offered_qos_profiles = list(offers)


def _rewrite(res: ScanResult, target: Path, meta: BagMetadata) -> int:
    """Write every message of a scan into a new, finalized MCAP file at ``target``."""
    w, f = open_mcap(target)
    try:
        schema_ids = {sid: w.register_schema(s.name, s.encoding, s.data)
                      for sid, s in res.schemas.items()}
        rows = []
        for cid, ch in res.channels.items():
            new = w.register_channel(ch.topic, ch.message_encoding, schema_ids.get(ch.schema_id, 0),
                                     {"topic_type_hash": "", **ch.metadata})
            for blk in res.blocks.get(cid, []):
                mv = memoryview(blk.buf)
                for off, ln, lt, pt, sq in zip(blk.offsets.tolist(), blk.lengths.tolist(),
                                               blk.log_time.tolist(), blk.publish_time.tolist(),
                                               blk.sequence.tolist()):
                    rows.append((lt, new, pt, sq, mv[off:off + ln]))
        order = np.argsort(np.array([r[0] for r in rows], dtype=np.int64), kind="stable")
        for i in order.tolist():
            lt, cid, pt, sq, data = rows[i]
            w.add_message(cid, lt, bytes(data), pt, sq)
        w.add_metadata(METADATA_RECORD, rosbag2_record(meta))
        w.finish()
    finally:
        f.close()
    return len(rows)


def repair_bag(bag_dir: Path | str, keep_damaged: bool = True) -> RepairReport:
    bag_dir = Path(bag_dir)
    bag = open_bag(bag_dir)
    redo = [(f, res) for f, res in zip(bag.files, bag.scans)
            if not res.complete or wrapped_rosbag2_record(res)]
    if bag.finalized and not redo:
        return RepairReport(bag_dir, [], bag.message_count, True)
    _keep_listed_offers(bag, [res for _, res in redo])
    meta = metadata_from_bag(bag)       # what the rewritten files will hold, message for message
    meta.custom_data.setdefault("repaired_by", "grader bag repair")
    rewritten = []
    for f, res in redo:
        tmp = f.with_suffix(".mcap.repairing")
        tmp.unlink(missing_ok=True)
        _rewrite(res, tmp, meta)
        if keep_damaged:
            f.replace(f.with_suffix(".mcap.damaged"))
        tmp.replace(f)
        rewritten.append(f.name)
    meta.write(bag_dir)
    return RepairReport(bag_dir, rewritten, meta.message_count, False)

