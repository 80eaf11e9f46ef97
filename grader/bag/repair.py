"""``grader bag repair BAG``: make a crashed recording a normal bag again.

A recorder killed with SIGKILL leaves an MCAP file without summary/footer (and possibly half a
chunk at its end) and no metadata.yaml. Every chunk that was completely written is still
readable (:func:`grader.bag.mcap_io.scan`); repair rewrites those messages into a fresh,
finalized MCAP file (keeping the damaged one as ``<name>.mcap.damaged`` unless told not to) and
writes metadata.yaml from what the files really hold, so rosbags, ``mcap`` and ``ros2 bag`` read it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from grader.bag.mcap_io import McapWriter, ScanResult
from grader.bag.reader import metadata_from_bag, open_bag
from grader.bag.writer import LIBRARY


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


def _rewrite(res: ScanResult, target: Path) -> int:
    """Write every message of a scan into a new, finalized MCAP file at ``target``."""
    w = McapWriter(target, library=LIBRARY, chunk_size=1 << 20, chunk_age_s=float("inf"))
    schema_ids = {sid: w.add_schema(s.name, s.encoding, s.data) for sid, s in res.schemas.items()}
    rows = []
    for cid, ch in res.channels.items():
        new = w.add_channel(schema_ids.get(ch.schema_id, 0), ch.topic, ch.message_encoding, ch.metadata)
        for blk in res.blocks.get(cid, []):
            mv = memoryview(blk.buf)
            for off, ln, lt, pt, sq in zip(blk.offsets.tolist(), blk.lengths.tolist(),
                                           blk.log_time.tolist(), blk.publish_time.tolist(),
                                           blk.sequence.tolist()):
                rows.append((lt, new, pt, sq, mv[off:off + ln]))
    order = np.argsort(np.array([r[0] for r in rows], dtype=np.int64), kind="stable")
    for i in order.tolist():
        lt, cid, pt, sq, data = rows[i]
        w.write_message(cid, lt, pt, bytes(data), sq)
    w.close()
    return len(rows)


def repair_bag(bag_dir: Path | str, keep_damaged: bool = True) -> RepairReport:
    bag_dir = Path(bag_dir)
    bag = open_bag(bag_dir)
    if bag.finalized:
        return RepairReport(bag_dir, [], bag.message_count, True)
    rewritten = []
    for f, res in zip(bag.files, bag.scans):
        if res.complete:
            continue
        tmp = f.with_suffix(".mcap.repairing")
        tmp.unlink(missing_ok=True)
        _rewrite(res, tmp)
        if keep_damaged:
            f.replace(f.with_suffix(".mcap.damaged"))
        tmp.replace(f)
        rewritten.append(f.name)
    fixed = open_bag(bag_dir)
    meta = metadata_from_bag(fixed)
    meta.custom_data.setdefault("repaired_by", "grader bag repair")
    meta.write(bag_dir)
    return RepairReport(bag_dir, rewritten, fixed.message_count, False)


def run(args: Any) -> int:
    report = repair_bag(args.bag, keep_damaged=not args.no_backup)
    print(report.summary())
    return 0
