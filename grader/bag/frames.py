"""Bag → pandas DataFrames: what analyzers consume (contract in docs/ARCHITECTURE.md).

Pure: reads MCAP bytes and the message definitions stored in the bag; never imports rclpy, so
every grade can be recomputed from its bag on any machine. Fixed-layout types (Pose, Twist, ...)
are decoded for all messages at once with numpy (see :mod:`grader.bag.cdr`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from grader.bag import cdr
from grader.bag.msgdefs import (DefinitionNotFound, DefinitionSource, from_rosbag2_service_definition,
                                 normalize_type)
from grader.bag.reader import Bag, TopicData, open_bag
from grader.bag.timebase import CLOCK_TOPIC, TIMEBASE, bag_lockstep, bag_time_scale, time_map
from grader.errors import GraderError
from grader.sim.canvas import TURTLE_BODY, TURTLE_HEAD, read_png
from grader.sim.physics import DEFAULT_BACKGROUND, METER


@dataclass
class TopicMeta:
    name: str
    type: str
    count: int
    offered_qos_profiles: list[dict[str, Any]]   # every publisher's offer, late ones included
    type_description_hash: str
    definition: str


@dataclass
class BagMeta:
    """What a bag holds, without decoding messages (``load_bag_meta``)."""

    path: Path
    topics: dict[str, TopicMeta]
    start: float            # epoch seconds of the first message (0.0 if empty)
    end: float
    finalized: bool         # False: the recorder did not finish; `grader bag repair` fixes it
    problems: list[str] = field(default_factory=list)

    @property
    def duration(self) -> float:
        return self.end - self.start

    @property
    def types(self) -> dict[str, str]:
        return {n: t.type for n, t in self.topics.items()}

    @property
    def counts(self) -> dict[str, int]:
        return {n: t.count for n, t in self.topics.items()}


def load_bag_meta(bag_dir: Path | str) -> BagMeta:
    """Topics, types, counts and offered QoS of a bag (counts come from the data, not the YAML)."""
    bag = open_bag(bag_dir)
    lo, hi = bag.time_range()
    topics = {n: TopicMeta(n, t.type, t.count,
                           t.offered_qos_profiles + t.late_offered_qos_profiles,
                           t.type_description_hash, t.definition) for n, t in bag.topics.items()}
    return BagMeta(bag.path, topics, lo / 1e9, hi / 1e9, bag.finalized, list(bag.problems))


def load_frames(bag_dir: Path | str, topics: list[str] | None = None, *,
                time_scale: float | None = None, lockstep: bool = False) -> dict[str, pd.DataFrame]:
    """One DataFrame per topic: index ``t`` (receive time, epoch s), ``pub_t``, flattened fields.

    ``topics`` selects topics; naming one the bag lacks is an error (a typo would otherwise look
    like a student who never published). Each frame's ``attrs`` holds ``topic``, ``type``, ``bag``
    and ``finalized`` (False: read from a crashed recording, up to its last complete chunk).

    A bag recorded on simulated time (``time_scale`` > 1; None: what the bag's metadata notes,
    lockstep included; ``lockstep``: a lockstep run whose bag was never finalised, so its
    metadata cannot say so) has its times mapped to simulated seconds through its ``/clock``
    (:mod:`grader.bag.timebase`); the map is left under ``frames[TIMEBASE]``.
    """
    bag = open_bag(bag_dir, topics)
    if topics is not None:
        missing = [t for t in topics if t not in bag.topics]
        if missing:
            have = ", ".join(sorted(open_bag(bag_dir).topics)) or "none"
            raise GraderError(f"bag {bag_dir} has no topic {', '.join(missing)} (topics: {have}).")
    frames = {name: topic_frame(bag, td) for name, td in bag.topics.items()}
    custom = bag.metadata.custom_data if bag.metadata else None
    # a time_scale given (1.0: the times as recorded) is taken as it is
    if time_scale is None:
        time_scale = bag_time_scale(custom)
        lockstep = lockstep or bag_lockstep(custom)
    if time_scale > 1 or lockstep:
        _to_simulated_time(frames, bag, time_scale, lockstep)
    return frames


def _to_simulated_time(frames: dict[str, Any], bag: Bag, scale: float, stepwise: bool = False) -> None:
    clock = frames.get(CLOCK_TOPIC)
    if clock is None and CLOCK_TOPIC in open_bag(bag.path).topics:
        clock_bag = open_bag(bag.path, [CLOCK_TOPIC])
        clock = topic_frame(clock_bag, clock_bag.topics[CLOCK_TOPIC])
    tmap = time_map(clock, scale, stepwise)
    if tmap is None:
        raise GraderError(f"bag {bag.path} was recorded on simulated time ({scale:g}x) but holds no "
                          f"{CLOCK_TOPIC} messages, so its times cannot be mapped; grade it again.")
    for df in frames.values():
        df.index = pd.Index(tmap(df.index.to_numpy(float)), name="t")
        if "pub_t" in df.columns:
            df["pub_t"] = tmap(df["pub_t"].to_numpy(float))
    frames[TIMEBASE] = tmap


def _definition(bag: Bag, td: TopicData) -> str:
    """The stored ros2msg definition; bags without one fall back to installed interfaces.

    rosbag2 Jazzy stores no usable definition for some hidden types (service events) and IDL
    for types that only have ``.idl`` files; the local lookup synthesises the former.
    """
    if "SRV: " in td.definition:
        converted = from_rosbag2_service_definition(td.definition, td.type)
        if converted:
            return converted
    elif td.definition and td.definition_encoding in ("ros2msg", ""):
        return td.definition
    try:
        return DefinitionSource().full_text(td.type)
    except DefinitionNotFound as exc:
        stored = ("an IDL definition, which the grader cannot decode"
                  if td.definition_encoding == "ros2idl" else "no message definition")
        raise GraderError(f"topic {td.name} ({td.type}) of {bag.path} has {stored}, and the type "
                          f"is not installed here ({exc}); source the workspace that defines it.") from None


def topic_frame(bag: Bag, td: TopicData) -> pd.DataFrame:
    t = td.log_times().astype(np.float64) / 1e9
    pt_ns = td.publish_times()
    lt_ns = td.log_times()
    pub_t = np.where((pt_ns == 0) | (pt_ns == lt_ns), np.nan, pt_ns / 1e9)
    cols: dict[str, Any] = {"pub_t": pub_t}
    if td.serialization_format != "cdr":
        raise GraderError(f"topic {td.name} is serialized as {td.serialization_format!r}; only CDR "
                          "is supported.")
    text = _definition(bag, td)
    root = normalize_type(td.type)
    try:
        types = cdr.parse_definition(text, td.type)
        fixed = cdr.is_fixed(types, root)
    except cdr.DefinitionError as exc:
        raise GraderError(f"cannot read the stored definition of {td.type} (topic {td.name}): {exc}") from None
    decoded = None
    if fixed and td.count:
        leaves, size = cdr.fixed_layout(types, root)
        got = td.body_matrix(size)
        if got is not None:
            mat, head = got
            little = bool(np.all(head == 1))
            if little or bool(np.all(head == 0)):
                decoded = cdr.decode_fixed(mat, leaves, little)
                for name, n in cdr.array_lengths(types, root).items():
                    decoded[name] = np.full(td.count, n, np.int64)
    if decoded is not None:
        cols.update(decoded)
        df = pd.DataFrame(cols, index=pd.Index(t, name="t"))
    elif td.count:
        rows = _decode_rows(td, text)
        body = pd.DataFrame.from_records(rows)
        body.insert(0, "pub_t", pub_t)
        body.index = pd.Index(t, name="t")
        df = body
    else:
        names = ["pub_t"] + cdr.scalar_columns(types, root)
        df = pd.DataFrame({c: pd.Series(dtype="float64") for c in names},
                          index=pd.Index([], dtype="float64", name="t"))
    df.attrs.update({"topic": td.name, "type": td.type, "bag": str(bag.path),
                     "finalized": bag.finalized})
    return df


def _decode_rows(td: TopicData, text: str) -> list[dict]:
    decoders: dict = {}
    rows = []
    for i, payload in enumerate(td.payloads()):
        if len(payload) < 4:
            raise GraderError(f"message {i} on {td.name} is truncated ({len(payload)} bytes).")
        little = payload[1] == 1
        dec = decoders.get(little)
        if dec is None:
            dec = decoders[little] = cdr.message_decoder(text, td.type, little)
        try:
            rows.append(dec(payload[4:]))
        except Exception as exc:  # noqa: BLE001 - struct.error/ValueError/IndexError alike
            raise GraderError(f"message {i} on {td.name} ({td.type}) does not match its stored "
                              f"definition ({exc}); the bag is corrupt.") from None
    return rows


def canvas_frame(png: Path | str) -> pd.DataFrame:
    """The simulator's saved canvas as one row per drawn pixel: ``x_m``, ``y_m`` (world metres,
    pixel centres), ``r``, ``g``, ``b``. Background and turtle-marker pixels are left out, so the
    frame holds the pen trails (what "the canvas shows blue right of x = 5.5" is judged on)."""
    import numpy as np  # noqa: PLC0415 - numpy: 147 ms CPU to import, paid only on this path

    rgb = read_png(png)[..., :3].astype(np.int32)
    height = rgb.shape[0]
    skip = np.zeros(rgb.shape[:2], dtype=bool)
    for colour in (DEFAULT_BACKGROUND, TURTLE_BODY, TURTLE_HEAD):
        skip |= np.all(rgb == np.asarray(colour, np.int32), axis=2)
    rows, cols = np.nonzero(~skip)
    return pd.DataFrame({"x_m": cols / METER, "y_m": (height - 1 - rows) / METER,
                         "r": rgb[rows, cols, 0], "g": rgb[rows, cols, 1], "b": rgb[rows, cols, 2]})
