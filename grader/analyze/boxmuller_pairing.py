"""How the numbers a student's Box-Muller subscriber printed are paired with the (u1, u2) inputs
that produced them, and which formula (the right one or a classic mistake) explains them.
The analyzers in ``grader.analyze.boxmuller`` use it; the method is described there.

The catalogue of formulas it tests against (the right one and the classic mistakes, each with its
feedback) is ``grader.analyze.boxmuller_formulas``; what the report shows of a pairing (examples,
unanswered inputs, the scatter) is ``grader.analyze.boxmuller_evidence``."""

from __future__ import annotations

import re
import threading
import weakref
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pydantic import Field

from grader.analyze import AnalyzerParams
from grader.analyze.boxmuller_formulas import FORMULAS
from grader.analyze._common import (Frames, end_time, rosout_lines, stdout_lines,
                                    times, topic, traceback_mask)


_NUM = re.compile(
    r"(?<![\w.])([-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf(?:inity)?)\b)(?![\w])(?!\.\d)",
    re.IGNORECASE,
)

class BoxMullerInputParams(AnalyzerParams):
    """Where the Box-Muller analyzers find the inputs and the student's printed values, and how
    printed lines are paired with inputs (shared by ``boxmuller``, ``boxmuller_logging`` and
    ``normality``)."""

    topic: str = Field("/random_numbers", description="where the uniform pairs are (recorded in the bag)")
    logger: str | None = Field(None, description="student's logger name on /rosout; None = detect")
    process: str | None = Field(None, description="runner process name for /grader/stdout; None = detect")
    exclude_loggers: tuple[str, ...] = Field(
        ("turtlesim", "rosbag2_recorder", "rosbag2_player", "grader", "simple_publisher"),
        description="loggers whose lines are not the student's values")
    max_lag_s: float = Field(2.0, ge=0, description="s: a printed value may answer inputs up to this much earlier")
    lead_s: float = Field(0.25, ge=0, description="s: ... or this much later (clock skew log stamp vs recorder)")
    max_chance_full: float = Field(0.02, ge=0, le=1, description="the full lag window may decide only where "
                                                                 "chance matches stay below this share")


def parse_numbers(text: str) -> list[tuple[float, float]]:
    """Numbers in a free-text line with half a unit in their last printed digit.

    '0.123' -> (0.123, 0.0005); '1.2e-05' -> (1.2e-05, 5e-07); 'nan' -> (nan, 0).
    """
    out = []
    for m in _NUM.finditer(str(text)):
        tok = m.group(1)
        low = tok.lower().lstrip("+-")
        if low.startswith(("nan", "inf")):
            out.append((float("nan"), 0.0))
            continue
        mant, _, exp = tok.lower().partition("e")
        decimals = len(mant.split(".", 1)[1]) if "." in mant else 0
        e = int(exp) if exp else 0
        try:
            out.append((float(tok), 0.5 * 10.0 ** (e - decimals)))
        except ValueError:
            continue
    return out


@dataclass
class Source:
    kind: str            # "rosout" | "stdout"
    name: str            # logger or process name
    time: np.ndarray     # per line
    text: list[str]
    numbers: list[list[tuple[float, float]]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.numbers = [parse_numbers(t) for t in self.text]

    @property
    def n_numeric(self) -> int:
        return sum(1 for n in self.numbers if n)

    def column(self, pos: int) -> tuple[np.ndarray, np.ndarray]:
        """Value and half-ulp of the pos-th number of each line (NaN where the line has none)."""
        v = np.full(len(self.numbers), np.nan)
        h = np.zeros(len(self.numbers))
        for j, nums in enumerate(self.numbers):
            if -len(nums) <= pos < len(nums):
                v[j], h[j] = nums[pos]
        return v, h


def _sources(frames: Frames, p: BoxMullerInputParams) -> list[Source]:
    """Candidate output streams: each /rosout logger, then each process's stdout/stderr."""
    out: list[Source] = []
    excl = {str(x).lstrip("/") for x in (p.exclude_loggers or ())}
    ro = rosout_lines(frames)
    if len(ro):
        for name, g in ro.groupby("logger", sort=False):
            if p.logger:
                if str(name).lstrip("/") != str(p.logger).lstrip("/"):
                    continue
            elif str(name).lstrip("/") in excl or str(name).startswith("grader"):
                continue
            g = g.sort_values("time", kind="stable")
            out.append(Source("rosout", str(name), g["time"].to_numpy(float), g["text"].tolist()))
    so = stdout_lines(frames)
    if len(so):
        for name, g in so.groupby("process", sort=False):
            if p.process and str(name) != str(p.process):
                continue
            g = g.sort_values("time", kind="stable")
            g = g[~traceback_mask(g["text"])]
            out.append(Source("stdout", str(name), g["time"].to_numpy(float), g["text"].tolist()))
    return [s for s in out if s.n_numeric > 0]


@dataclass
class Inputs:
    t: np.ndarray
    u1: np.ndarray
    u2: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


def _inputs(frames: Frames, name: str) -> Inputs | None:
    df = topic(frames, name)
    if df is None or "data[0]" not in df.columns or "data[1]" not in df.columns:
        return None
    u1 = df["data[0]"].to_numpy(float)
    u2 = df["data[1]"].to_numpy(float)
    t = times(df)
    if "pub_t" in df.columns:
        # send time: a subscriber can only print after it, whatever the recorder's own delay
        pt = df["pub_t"].to_numpy(float)
        t = np.where(np.isfinite(pt), pt, t)
    ok = np.isfinite(u1) & np.isfinite(u2)
    order = np.argsort(t[ok], kind="stable")
    return Inputs(t[ok][order], u1[ok][order], u2[ok][order])


def _predict(inp: Inputs) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per formula: predicted z and its sensitivity to one float32 ulp on each input."""
    eps = 2.0 ** -23
    out = {}
    with np.errstate(all="ignore"):
        for name, (_, f, _) in FORMULAS.items():
            z = f(inp.u1, inp.u2)
            s = np.abs(f(inp.u1 * (1 + eps), inp.u2) - z) + np.abs(f(inp.u1, inp.u2 * (1 + eps)) - z)
            out[name] = (z, np.where(np.isfinite(s), s, 0.0))
    return out


@dataclass
class Pairing:
    source: Source
    pos: int
    formula: str
    pairs: list[tuple[int, int, bool]]   # (output line j, input i, matched)
    matched: int
    expected: int
    first_i: int | None
    lag_window: tuple[float, float] = (0.0, 0.0)   # accepted (output time - input time), s
    chance: float = 0.0                            # share of lines a random input would match
    span: tuple[float, float] = (0.0, 0.0)         # input times counted in ``expected``

    @property
    def raw_ratio(self) -> float:
        return min(1.0, self.matched / self.expected) if self.expected else 0.0

    @property
    def ratio(self) -> float:
        """Matched share corrected for chance: (raw - c) / (1 - c), 0 when chance explains it all."""
        if self.chance >= 1.0:
            return 0.0
        return max(0.0, (self.raw_ratio - self.chance) / (1.0 - self.chance))


def _windows(inp: Inputs, t_out: np.ndarray, p: BoxMullerInputParams,
             lag: tuple[float, float] | None = None, shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Index range of inputs each line may answer: t_in in [t_out - lag_max, t_out - lag_min]."""
    lag_min, lag_max = lag if lag is not None else (-p.lead_s, p.max_lag_s)
    lo = np.searchsorted(inp.t, t_out + shift - lag_max, side="left")
    hi = np.searchsorted(inp.t, t_out + shift - lag_min, side="right")
    return lo, hi


def _count_any(z: np.ndarray, sens: np.ndarray, v: np.ndarray, h: np.ndarray,
               lo: np.ndarray, hi: np.ndarray) -> int:
    """Number of output lines with at least one matching input in their window (vectorised)."""
    width = int((hi - lo).max()) if len(lo) else 0
    if width <= 0 or len(z) == 0:
        return 0
    idx = lo[:, None] + np.arange(width)[None, :]
    valid = idx < hi[:, None]
    idx = np.minimum(idx, len(z) - 1)
    zz = z[idx]
    tol = h[:, None] + sens[idx] + 1e-6 * np.abs(zz) + 1e-12
    with np.errstate(invalid="ignore"):
        m = valid & (np.abs(zz - v[:, None]) <= tol)
    return int(m.any(axis=1).sum())


def _pair(inp: Inputs, src: Source, pos: int, z: np.ndarray, sens: np.ndarray, v: np.ndarray,
          h: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> list[tuple[int, int, bool]]:
    """Largest set of (line, input) matches increasing in both (longest increasing subsequence).

    Why not greedy: with coarse printing and a fast replay a line can also match an unrelated input
    by coincidence; a greedy choice of such a later input would push every following line off its
    own input. The longest chain keeps the true pairs, which all line up.
    """
    cand_j: list[int] = []
    cand_i: list[int] = []
    present: list[int] = []
    for j in range(len(v)):
        nums = src.numbers[j]
        if not -len(nums) <= pos < len(nums):
            continue          # no number at this position: a banner or unrelated line
        present.append(j)
        if lo[j] >= hi[j] or not np.isfinite(v[j]):
            continue
        cand = np.arange(lo[j], hi[j])
        tol = h[j] + sens[cand] + 1e-6 * np.abs(z[cand]) + 1e-12
        with np.errstate(invalid="ignore"):
            ok = cand[np.abs(z[cand] - v[j]) <= tol]
        for i in ok[::-1]:            # descending i within a line: at most one per line in a chain
            cand_j.append(j)
            cand_i.append(int(i))
    # longest strictly increasing subsequence of cand_i (patience sorting with back-pointers)
    tails: list[int] = []            # tails[k] = index into cand of the smallest tail of a chain of length k+1
    tail_vals: list[int] = []
    back = [-1] * len(cand_i)
    for n, i in enumerate(cand_i):
        k = int(np.searchsorted(tail_vals, i, side="left"))
        back[n] = tails[k - 1] if k > 0 else -1
        if k == len(tails):
            tails.append(n)
            tail_vals.append(i)
        else:
            tails[k] = n
            tail_vals[k] = i
    chain: dict[int, int] = {}
    n = tails[-1] if tails else -1
    while n >= 0:
        chain[cand_j[n]] = cand_i[n]
        n = back[n]
    pairs: list[tuple[int, int, bool]] = []
    for j in present:
        if j in chain:
            pairs.append((j, chain[j], True))
        elif lo[j] < hi[j]:
            near = np.arange(lo[j], hi[j])
            pairs.append((j, int(near[np.argmin(np.abs(src.time[j] - inp.t[near]))]), False))
    return pairs


def _chance(inp: Inputs, src: Source, pos: int, z: np.ndarray, sens: np.ndarray, v: np.ndarray,
            h: np.ndarray, p: BoxMullerInputParams, lag: tuple[float, float], lo: np.ndarray,
            hi: np.ndarray) -> float | None:
    """Share of lines a random input in the lag band would match: the same lines against inputs
    far away in time (full windows only, not cut by the bag's ends); None when the bag is too
    short to shift any window that far."""
    span = lag[1] - lag[0] + 1.0
    have = np.array([-len(n) <= pos < len(n) for n in src.numbers]) & np.isfinite(v)
    hits = tot = 0
    width = max(1.0, 0.8 * float(np.median(hi - lo))) if len(hi) else 1.0
    for shift in (-3 * span, -2 * span, 2 * span, 3 * span):
        slo, shi = _windows(inp, src.time, p, lag, shift)
        ok = have & (shi - slo >= width)
        if ok.sum():
            hits += _count_any(z, sens, v[ok], h[ok], slo[ok], shi[ok])
            tot += int(ok.sum())
    return hits / tot if tot else None


def _pairing(inp: Inputs, src: Source, pos: int, formula: str, pred: Any, p: BoxMullerInputParams,
             t_cut: float) -> Pairing:
    """Pair lines with inputs (see _pair) and measure the share matched, corrected for chance.

    Two passes: the first uses the full window; when it finds real matches their time lags are
    usually tight (a node logs within milliseconds of receiving), so the second pass only accepts
    lags in that band (2nd to 98th percentile, +-50 ms). For each, the chance that a random input
    in the band matches a line is measured on windows shifted far away in time, and the matched
    share is corrected for it, so coarse printing ("%.1f") against a fast replay cannot earn credit
    by coincidence. The full pass decides instead when it matches more and chance plays no part
    in it (``max_chance_full``): a node starved of CPU (a MultiThreadedExecutor on a loaded 2-core
    machine) answers one pair in ten 0.1-1 s late, and a band fitted to the other nine must not
    turn its correct values into "wrong lines" (a CI run graded such a correct subscriber
    894/1000); with four or five printed decimals a chance match in the full 2 s window is ~1e-3.
    Coarse printing keeps the band: there the correction, not the pairing, would decide.
    """
    z, sens = pred[formula]
    v, h = src.column(pos)
    full = (-p.lead_s, p.max_lag_s)
    lo, hi = _windows(inp, src.time, p)
    pairs = _pair(inp, src, pos, z, sens, v, h, lo, hi)
    passes = [(full, pairs, lo, hi)]
    lags = np.array([src.time[j] - inp.t[i] for j, i, m in pairs if m])
    if len(lags) >= 5:
        band = (max(full[0], float(np.quantile(lags, 0.02)) - 0.05),
                min(full[1], float(np.quantile(lags, 0.98)) + 0.05))
        blo, bhi = _windows(inp, src.time, p, band)
        passes.append((band, _pair(inp, src, pos, z, sens, v, h, blo, bhi), blo, bhi))
    best: Pairing | None = None
    for lag, pairs, lo, hi in reversed(passes):          # the band first: it wins a tie
        measured = _chance(inp, src, pos, z, sens, v, h, p, lag, lo, hi)
        chance = 0.0 if measured is None else measured
        matched_i = [i for _, i, m in pairs if m]
        cut = t_cut
        if matched_i:
            first_i: int | None = min(matched_i)
            t0 = inp.t[min(matched_i)]
            cut = max(t_cut, float(inp.t[max(matched_i)]))
        else:
            first_i = None
            t0 = float(src.time[0]) - p.max_lag_s if len(src.time) else float("inf")
        expected = int(((inp.t >= t0 - 1e-9) & (inp.t <= cut)).sum())
        expected = max(expected, len(matched_i))
        cand = Pairing(src, pos, formula, pairs, len(matched_i), expected, first_i, lag, chance, (t0, cut))
        if best is None or (cand.ratio > best.ratio and measured is not None
                            and measured <= p.max_chance_full):
            best = cand
    assert best is not None
    return best


@dataclass
class Selection:
    inputs: Inputs | None
    sources: list[Source]
    best: Pairing | None                      # best (source, pos, formula)
    correct: Pairing | None                   # correct formula at best (source, pos)
    counts: dict[str, int]                    # per formula, best count over sources/positions (<= 300 lines)


_POSITIONS = (-1, 0, -2, 1, -3, 2)


#: the selections made on the frames a thread analyzes now (see :func:`select`)
_RECENT = threading.local()


def select(frames: Frames, p: BoxMullerInputParams, sources: list[Source] | None = None, *,
           tail_grace_s: float = 2.0) -> Selection:
    """Find the (source, number position, formula) that explains most printed lines; inputs in
    the last ``tail_grace_s`` seconds of the bag may go unanswered.

    ``boxmuller`` and ``normality`` ask the same question of the same frames (Lab 3: the same
    inputs and tolerances), so a selection from the thread's latest frames is given again, not
    made again: 0.14-0.22 s CPU a call on the reference's bag, one call of three saved. The
    selection is read only by its callers. Only the frames analyzed last are remembered, by a
    weak reference to their ``__meta__`` table (a frames dict has none of its own) and the
    identity of every table in them, so they are never kept alive by it and a table replaced
    makes a new selection; with ``sources`` given there is no reuse."""
    key = (tuple(getattr(p, name) for name in BoxMullerInputParams.model_fields), tail_grace_s)
    memo = _memo_for(frames) if sources is None else None
    if memo is not None and key in memo:
        return memo[key]
    made = _select(frames, p, sources, tail_grace_s)
    if memo is not None:
        memo[key] = made
    return made


def _memo_for(frames: Frames) -> dict[tuple, Selection] | None:
    """The thread's selections made on ``frames`` (emptied when the frames are others), or None
    when frames cannot be told apart (no ``__meta__`` table)."""
    meta = frames.get("__meta__")
    if meta is None:
        return None
    tables = tuple(id(v) for v in frames.values())        # a table replaced: other frames
    held = getattr(_RECENT, "frames", None)
    if held is None or held[0] != tables or held[1]() is not meta:
        _RECENT.frames = (tables, weakref.ref(meta))
        _RECENT.memo = {}
    memo: dict[tuple, Selection] = _RECENT.memo
    return memo


def _select(frames: Frames, p: BoxMullerInputParams, sources: list[Source] | None,
            tail_grace_s: float) -> Selection:
    inp = _inputs(frames, p.topic)
    srcs = _sources(frames, p) if sources is None else sources
    if inp is None or len(inp) == 0 or not srcs:
        return Selection(inp, srcs, None, None, {})
    pred = _predict(inp)
    order = list(FORMULAS)
    best_key = None
    best = None
    counts = {f: 0 for f in order}
    for si, src in enumerate(srcs):
        maxlen = max(len(n) for n in src.numbers)
        # choosing (source, position, formula) needs no more than ~300 evenly spaced lines
        rows = np.unique(np.linspace(0, len(src.numbers) - 1, min(len(src.numbers), 300)).astype(int))
        lo, hi = _windows(inp, src.time[rows], p)
        for pi, pos in enumerate(_POSITIONS):
            if pos >= maxlen or -pos > maxlen:
                continue
            v, h = src.column(pos)
            v, h = v[rows], h[rows]
            for fi, f in enumerate(order):
                c = _count_any(pred[f][0], pred[f][1], v, h, lo, hi)
                counts[f] = max(counts[f], c)
                key = (c, -fi, -si, -pi)
                if best_key is None or key > best_key:
                    best_key, best = key, (src, pos, f)
    assert best is not None and best_key is not None
    t_cut = end_time(frames) - tail_grace_s
    src, pos, f = best
    if best_key[0] == 0:
        # Nothing matches anything: pair the busiest source's last number for evidence.
        src = max(srcs, key=lambda s: (s.kind == "rosout", s.n_numeric))
        pos, f = -1, "correct"
    bp = _pairing(inp, src, pos, f, pred, p, t_cut)
    cp = bp if f == "correct" else _pairing(inp, src, pos, "correct", pred, p, t_cut)
    return Selection(inp, srcs, bp, cp, counts)
