"""Exercise 1, subscriber side: does the student's node print z = sqrt(-2 ln u1) cos(2 pi u2)?

Inputs are the (u1, u2) pairs on /random_numbers recorded in the bag (replayed by the grader, or
published by the student's own publisher). Outputs are the numbers the student's subscriber
printed: /rosout rows of its logger (``self.get_logger().info``), or, when it did not log,
``print()`` lines captured on /grader/stdout.

How outputs are paired with inputs, and why:
* Student lines are free text ("z = 0.42", "Normal: 0.42 from (0.1, 0.7)"), so every number in a
  line is a candidate; the (source, position-in-line, formula) that explains most lines wins.
* A line can only answer an input sent shortly before it (``max_lag_s``) or marginally after it
  (``lead_s``, clock skew). Among all (line, input) matches the largest set increasing in both is
  kept (longest increasing subsequence), so a few dropped or extra lines (a startup banner, a node
  started late) do not shift every later pair; the lag band is then narrowed to the lags the real
  pairs show.
* "Matches" means within what the student printed: half a unit in the last printed digit (3
  decimals -> 0.0005), plus the effect of one float32 ulp on the inputs, plus 1e-6 relative.
* Coarse printing against a fast replay matches by coincidence: the chance level is measured on
  windows shifted far away in time and the matched share is corrected for it.
When the correct formula does not explain the lines, the classic mistakes are tried (log10,
missing sqrt, sin for cos, swapped u1/u2, degrees, ...) and the best one is named in feedback.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy import stats

from grader.analyze import Finding, graded, register
from grader.analyze._common import (ROSOUT, STDOUT, Frames, end_time, meta_row, rosout_lines, stdout_lines,
                                    thin, times, topic)
from grader.analyze.evidence import SHARE

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    "exclude_loggers": ("loggers whose lines are not the student's values", ''),
    "max_lag_s": ('latest a value may be logged after its input', 's'),
    "lead_s": ('earliest before its input', 's'),
    "bug_min_ratio": ('share of values a known bug must explain', SHARE),
    "max_chance": ('chance a match is a coincidence, at most', ''),
    "tail_grace_s": ('time after the last input still read', 's'),
    "bug_credit": ('credit when a known bug explains the values', SHARE),
    "max_shapiro": ('values used in the Shapiro-Wilk test, at most', ''),
    "n_inputs": ("(u1, u2) pairs published", ""),
    "source": ("output read", ""),
    "source.kind": ("where the values were found (rosout = ROS logger, stdout = print)", ""),
    "source.name": ("logger or process", ""),
    "number_position": None,
    "n_numeric_lines": ("printed lines with a number", ""),
    "matched": ("values matching the correct z", ""),
    "expected": ("values expected", ""),
    "raw_ratio": ("share matched", SHARE),
    "chance": ("share a random input would match", SHARE),
    "ratio": ("share matched, corrected for chance", SHARE),
    "lag_window_s": None,
    "matches_per_formula": None,
    "best_formula": None,
    "best_formula_text": ("formula that explains the values best", ""),
    "best_ratio": ("share explained by that formula", SHARE),
    "bug": None,
    "examples": ("examples", ""),
    "u1": ("u1", ""), "u2": ("u2", ""), "printed": ("printed", ""),
    "expected_z": ("correct z", ""), "line": ("printed line", ""),
    "pairs": None,
    "pass_ratio": ("share needed", SHARE),
    "min_outputs": ("printed values needed", ""),
    # boxmuller_logging
    "rosout_loggers": ("ROS loggers seen", ""),
    "stdout_processes": ("processes that printed", ""),
    "logger": ("logger", ""),
    "matched_correct": ("logged values matching the correct z", ""),
    # normality
    "mean": ("mean", ""), "std": ("standard deviation", ""),
    "shapiro_W": ("Shapiro-Wilk W", ""), "shapiro_p": ("Shapiro-Wilk p-value", ""),
    "anderson_stat": ("Anderson-Darling statistic", ""), "anderson_p": ("Anderson-Darling p-value", ""),
    "mean_bound": ("largest |mean| accepted", ""), "std_bound": ("largest |std − 1| accepted", ""),
    "alpha": ("significance level", ""), "z_bound": ("standard errors allowed", ""),
    "min_samples": ("values needed", ""),
    "histogram": None, "qq": None,
}

TWO_PI = 2.0 * math.pi


def _sqrt_m2ln(u: np.ndarray) -> np.ndarray:
    return np.sqrt(-2.0 * np.log(u))


#: name -> (formula text, function, feedback when the student's values match it)
FORMULAS: dict[str, tuple[str, Callable[[np.ndarray, np.ndarray], np.ndarray], str]] = {
    "correct": ("sqrt(-2 ln u1) cos(2 pi u2)",
                lambda a, b: _sqrt_m2ln(a) * np.cos(TWO_PI * b), ""),
    "log10": ("sqrt(-2 log10 u1) cos(2 pi u2)",
              lambda a, b: np.sqrt(-2.0 * np.log10(a)) * np.cos(TWO_PI * b),
              "Your values match z computed with log10 instead of the natural log: use math.log / np.log "
              "(natural logarithm), not math.log10."),
    "log2": ("sqrt(-2 log2 u1) cos(2 pi u2)",
             lambda a, b: np.sqrt(-2.0 * np.log2(a)) * np.cos(TWO_PI * b),
             "Your values match z computed with log2 instead of the natural log: use math.log / np.log."),
    "missing_2": ("sqrt(-ln u1) cos(2 pi u2)",
                  lambda a, b: np.sqrt(-np.log(a)) * np.cos(TWO_PI * b),
                  "Your values match sqrt(-ln u1)·cos(2πu2): the factor 2 under the square root is missing; "
                  "use math.sqrt(-2 * math.log(u1))."),
    "missing_sqrt": ("-2 ln u1 cos(2 pi u2)",
                     lambda a, b: -2.0 * np.log(a) * np.cos(TWO_PI * b),
                     "Your values match -2·ln(u1)·cos(2πu2): the square root is missing; "
                     "use math.sqrt(-2 * math.log(u1))."),
    "power_precedence": ("(-2 ln u1)/2 cos(2 pi u2)",
                         lambda a, b: -np.log(a) * np.cos(TWO_PI * b),
                         "Your values match (-2·ln u1)/2·cos(2πu2): '** 1/2' is parsed as (x**1)/2 in Python; "
                         "write x ** 0.5 or math.sqrt(x)."),
    "sin_for_cos": ("sqrt(-2 ln u1) sin(2 pi u2)",
                    lambda a, b: _sqrt_m2ln(a) * np.sin(TWO_PI * b),
                    "Your values match sqrt(-2 ln u1)·sin(2πu2): that is the other Box-Muller output and is "
                    "also Normal, but the lab's formula (†) uses cos(2πu2)."),
    "swapped": ("sqrt(-2 ln u2) cos(2 pi u1)",
                lambda a, b: _sqrt_m2ln(b) * np.cos(TWO_PI * a),
                "Your values match the formula with u1 and u2 swapped: the logarithm takes u1 = msg.data[0] "
                "and the cosine takes u2 = msg.data[1]."),
    "u1_twice": ("sqrt(-2 ln u1) cos(2 pi u1)",
                 lambda a, b: _sqrt_m2ln(a) * np.cos(TWO_PI * a),
                 "Your values match a formula that uses u1 in both places: the cosine must take u2."),
    "u2_twice": ("sqrt(-2 ln u2) cos(2 pi u2)",
                 lambda a, b: _sqrt_m2ln(b) * np.cos(TWO_PI * b),
                 "Your values match a formula that uses u2 in both places: the logarithm must take u1."),
    "degrees_radians": ("sqrt(-2 ln u1) cos(radians(2 pi u2))",
                        lambda a, b: _sqrt_m2ln(a) * np.cos(np.radians(TWO_PI * b)),
                        "Your values match cos(radians(2πu2)): 2πu2 is already in radians, so do not convert it; "
                        "use math.cos(2 * math.pi * u2)."),
    "cos_360": ("sqrt(-2 ln u1) cos(360 u2)",
                lambda a, b: _sqrt_m2ln(a) * np.cos(360.0 * b),
                "Your values match cos(360·u2): math.cos expects radians, so the angle is 2·math.pi·u2, not 360·u2."),
    "missing_2_in_2pi": ("sqrt(-2 ln u1) cos(pi u2)",
                         lambda a, b: _sqrt_m2ln(a) * np.cos(math.pi * b),
                         "Your values match cos(π·u2): the angle must be 2·π·u2."),
    "missing_pi": ("sqrt(-2 ln u1) cos(2 u2)",
                   lambda a, b: _sqrt_m2ln(a) * np.cos(2.0 * b),
                   "Your values match cos(2·u2): π is missing; the angle must be 2·math.pi·u2."),
    "cos_precedence": ("sqrt(-2 ln u1) cos(2 pi) u2",
                       lambda a, b: _sqrt_m2ln(a) * b,
                       "Your values match sqrt(-2 ln u1)·cos(2π)·u2: u2 must be inside the cosine, "
                       "math.cos(2 * math.pi * u2)."),
    "negated": ("-sqrt(-2 ln u1) cos(2 pi u2)",
                lambda a, b: -_sqrt_m2ln(a) * np.cos(TWO_PI * b),
                "Your values have the wrong sign: z = +sqrt(-2 ln u1)·cos(2πu2)."),
}

_NUM = re.compile(
    r"(?<![\w.])([-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf(?:inity)?)\b)(?![\w])(?!\.\d)",
    re.IGNORECASE,
)

COMMON_DEFAULTS = {
    "topic": "/random_numbers",     # where the uniform pairs are (recorded in the bag)
    "logger": None,                 # student's logger name on /rosout; None = detect
    "process": None,                # runner process name for /grader/stdout; None = detect
    "exclude_loggers": ["turtlesim", "rosbag2_recorder", "rosbag2_player", "grader", "simple_publisher"],
    "max_lag_s": 2.0,               # a printed value may answer inputs up to this much earlier
    "lead_s": 0.25,                 # ... or this much later (clock skew log stamp vs recorder)
}


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


def _sources(frames: Frames, p: dict) -> list[Source]:
    """Candidate output streams: each /rosout logger, then each process's stdout/stderr."""
    out: list[Source] = []
    excl = {str(x).lstrip("/") for x in (p.get("exclude_loggers") or [])}
    ro = rosout_lines(frames)
    if len(ro):
        for name, g in ro.groupby("logger", sort=False):
            if p.get("logger"):
                if str(name).lstrip("/") != str(p["logger"]).lstrip("/"):
                    continue
            elif str(name).lstrip("/") in excl or str(name).startswith("grader"):
                continue
            g = g.sort_values("time", kind="stable")
            out.append(Source("rosout", str(name), g["time"].to_numpy(float), g["text"].tolist()))
    so = stdout_lines(frames)
    if len(so):
        for name, g in so.groupby("process", sort=False):
            if p.get("process") and str(name) != str(p["process"]):
                continue
            g = g.sort_values("time", kind="stable")
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

    @property
    def raw_ratio(self) -> float:
        return min(1.0, self.matched / self.expected) if self.expected else 0.0

    @property
    def ratio(self) -> float:
        """Matched share corrected for chance: (raw - c) / (1 - c), 0 when chance explains it all."""
        if self.chance >= 1.0:
            return 0.0
        return max(0.0, (self.raw_ratio - self.chance) / (1.0 - self.chance))


def _windows(inp: Inputs, t_out: np.ndarray, p: dict, lag: tuple[float, float] | None = None,
             shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Index range of inputs each line may answer: t_in in [t_out - lag_max, t_out - lag_min]."""
    lag_min, lag_max = lag if lag is not None else (-p["lead_s"], p["max_lag_s"])
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
            k = np.arange(lo[j], hi[j])
            pairs.append((j, int(k[np.argmin(np.abs(src.time[j] - inp.t[k]))]), False))
    return pairs


def _pairing(inp: Inputs, src: Source, pos: int, formula: str, pred, p: dict, t_cut: float) -> Pairing:
    """Pair lines with inputs (see _pair) and measure the share matched, corrected for chance.

    Two passes: the first uses the full window; when it finds real matches their time lags are
    tight (a node logs within milliseconds of receiving), so the second pass only accepts lags in
    that band (+-50 ms). Then the chance that a random input in the band matches a line is
    measured on windows shifted far away in time, and the matched share is corrected for it, so
    coarse printing ("%.1f") against a fast replay cannot earn credit by coincidence.
    """
    z, sens = pred[formula]
    v, h = src.column(pos)
    full = (-p["lead_s"], p["max_lag_s"])
    lo, hi = _windows(inp, src.time, p)
    pairs = _pair(inp, src, pos, z, sens, v, h, lo, hi)
    lag = full
    lags = np.array([src.time[j] - inp.t[i] for j, i, m in pairs if m])
    if len(lags) >= 5:
        lag = (max(full[0], float(np.quantile(lags, 0.02)) - 0.05),
               min(full[1], float(np.quantile(lags, 0.98)) + 0.05))
        lo, hi = _windows(inp, src.time, p, lag)
        pairs = _pair(inp, src, pos, z, sens, v, h, lo, hi)
    # chance level: the same lines against inputs far away in time
    span = lag[1] - lag[0] + 1.0
    have = np.array([-len(n) <= pos < len(n) for n in src.numbers]) & np.isfinite(v)
    hits = tot = 0
    width = max(1.0, 0.8 * float(np.median(hi - lo))) if len(hi) else 1.0
    for shift in (-3 * span, -2 * span, 2 * span, 3 * span):
        slo, shi = _windows(inp, src.time, p, lag, shift)
        ok = have & (shi - slo >= width)      # full windows only (not cut by the bag's ends)
        if ok.sum():
            hits += _count_any(z, sens, v[ok], h[ok], slo[ok], shi[ok])
            tot += int(ok.sum())
    chance = hits / tot if tot else 0.0
    matched_i = [i for _, i, m in pairs if m]
    if matched_i:
        first_i = min(matched_i)
        t0 = inp.t[first_i]
        t_cut = max(t_cut, float(inp.t[max(matched_i)]))
    else:
        first_i = None
        t0 = float(src.time[0]) - p["max_lag_s"] if len(src.time) else float("inf")
    expected = int(((inp.t >= t0 - 1e-9) & (inp.t <= t_cut)).sum())
    expected = max(expected, len(matched_i))
    return Pairing(src, pos, formula, pairs, len(matched_i), expected, first_i, lag, chance)


@dataclass
class Selection:
    inputs: Inputs | None
    sources: list[Source]
    best: Pairing | None                      # best (source, pos, formula)
    correct: Pairing | None                   # correct formula at best (source, pos)
    counts: dict[str, int]                    # per formula, best count over sources/positions (<= 300 lines)


_POSITIONS = (-1, 0, -2, 1, -3, 2)


def select(frames: Frames, p: dict, sources: list[Source] | None = None) -> Selection:
    """Find the (source, number position, formula) that explains most printed lines."""
    inp = _inputs(frames, p["topic"])
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
    assert best is not None
    t_cut = end_time(frames) - p.get("tail_grace_s", 2.0)
    src, pos, f = best
    if best_key[0] == 0:
        # Nothing matches anything: pair the busiest source's last number for evidence.
        src = max(srcs, key=lambda s: (s.kind == "rosout", s.n_numeric))
        pos, f = -1, "correct"
    bp = _pairing(inp, src, pos, f, pred, p, t_cut)
    cp = bp if f == "correct" else _pairing(inp, src, pos, "correct", pred, p, t_cut)
    return Selection(inp, srcs, bp, cp, counts)


def _examples(sel: Selection, pairing: Pairing, k: int = 5, only_unmatched: bool = False) -> list[dict]:
    inp = sel.inputs
    assert inp is not None
    v, _ = pairing.source.column(pairing.pos)
    zc = FORMULAS["correct"][1]
    out = []
    for j, i, m in pairing.pairs:
        if only_unmatched and m:
            continue
        with np.errstate(all="ignore"):
            z = float(zc(np.array([inp.u1[i]]), np.array([inp.u2[i]]))[0])
        out.append({"u1": float(inp.u1[i]), "u2": float(inp.u2[i]), "printed": float(v[j]),
                    "line": pairing.source.text[j][:120], "expected_z": z, "matched": bool(m)})
        if len(out) >= k:
            break
    return out


def _pair_series(sel: Selection, pairing: Pairing, max_points: int = 300) -> dict:
    """Printed value against the correct z of the input it answers (the report's scatter plot);
    ``formula``: the formula the pairing followed (a named mistake, or "correct")."""
    inp = sel.inputs
    assert inp is not None
    v, _ = pairing.source.column(pairing.pos)
    pairs = pairing.pairs
    keep = thin(len(pairs), max_points)
    j = np.array([pairs[k][0] for k in keep], dtype=int)
    i = np.array([pairs[k][1] for k in keep], dtype=int)
    with np.errstate(all="ignore"):
        z = FORMULAS["correct"][1](inp.u1[i], inp.u2[i]) if len(i) else np.array([])
    return {"formula": pairing.formula, "expected_z": np.round(z, 5).tolist(),
            "printed": np.round(v[j], 6).tolist() if len(j) else [],
            "matched": [bool(pairs[k][2]) for k in keep]}


def _no_output_finding(frames: Frames, p: dict, sel: Selection) -> Finding | None:
    if sel.inputs is None or len(sel.inputs) == 0:
        row = meta_row(frames, p["topic"])
        return Finding.error(
            f"No (u1, u2) pairs were recorded on {p['topic']}, so the subscriber could not be tested "
            "(scenario problem).", {"topic": p["topic"], "meta": row})
    if topic(frames, ROSOUT) is None and topic(frames, STDOUT) is None:
        return Finding.error("Neither /rosout nor /grader/stdout was recorded: the subscriber's output "
                             "cannot be checked (scenario problem).", {"n_inputs": len(sel.inputs)})
    if not sel.sources:
        return Finding.fail(
            f"Your subscriber printed no numbers while {len(sel.inputs)} pairs were published on "
            f"{p['topic']}: subscribe to /random_numbers and log z with self.get_logger().info(...).",
            {"n_inputs": len(sel.inputs)})
    return None


@register("boxmuller", evidence={**EVIDENCE, "value": ("printed values", "")},
          expect="z = sqrt(−2 ln u1)·cos(2π u2) printed for at least {pass_ratio:.0%} of the published pairs",
          defaults={
    **COMMON_DEFAULTS,
    "min_outputs": 10,       # fewer numeric lines -> not enough evidence
    "pass_ratio": 0.9,       # matched / expected at or above this -> full credit
    "bug_min_ratio": 0.8,    # a named mistake must explain at least this share to be reported
    "max_chance": 0.5,       # not passing, and a random input would match this share: "print more decimals"
    "tail_grace_s": 2.0,     # inputs in the last seconds of the bag may go unanswered
    "bug_credit": {"sin_for_cos": 0.5},   # fraction granted when the values match a named variant
})
def boxmuller(frames: Frames, p: dict) -> Finding:
    """Share of published pairs for which the student printed the correct Box-Muller z."""
    sel = select(frames, p)
    early = _no_output_finding(frames, p, sel)
    if early:
        return early
    best, cp = sel.best, sel.correct
    assert best is not None and cp is not None and sel.inputs is not None
    ev = {
        "n_inputs": len(sel.inputs),
        "source": {"kind": best.source.kind, "name": best.source.name},
        "number_position": best.pos,
        "n_numeric_lines": best.source.n_numeric,
        "matched": cp.matched, "expected": cp.expected, "raw_ratio": cp.raw_ratio,
        "chance": cp.chance, "ratio": cp.ratio, "lag_window_s": list(cp.lag_window),
        "matches_per_formula": {f: c for f, c in sel.counts.items() if c},   # on <= 300 sampled lines
        "best_formula": best.formula,
        "best_formula_text": FORMULAS[best.formula][0],
        "best_ratio": best.ratio,
    }
    shown = best if best.formula != "correct" and best.ratio >= p["bug_min_ratio"] else cp
    ev["pairs"] = _pair_series(sel, shown)
    if best.source.n_numeric < p["min_outputs"]:
        ev["examples"] = _examples(sel, best)
        return Finding(f"{best.source.n_numeric} lines", 0.0, "fail",
                       f"Only {best.source.n_numeric} printed value(s) for {len(sel.inputs)} published pairs: "
                       "log one z per received message.", ev)
    value = f"{cp.matched}/{cp.expected} matched"
    if cp.ratio >= p["pass_ratio"]:
        ev["examples"] = _examples(sel, cp, 3)
        return Finding(value, 1.0, "pass",
                       f"{cp.matched} of {cp.expected} printed values match z = sqrt(-2 ln u1)·cos(2πu2).", ev)
    if best.formula != "correct" and best.ratio >= p["bug_min_ratio"]:
        frac = float((p.get("bug_credit") or {}).get(best.formula, 0.0))
        ev["examples"] = _examples(sel, best, 3)
        ev["bug"] = best.formula
        value = f"values follow {FORMULAS[best.formula][0]}"
        return Finding(value, frac, graded(frac), FORMULAS[best.formula][2], ev)
    if cp.chance > p["max_chance"]:
        ev["examples"] = _examples(sel, cp, 3)
        return Finding(value, 0.0, "fail",
                       f"Your values are printed too coarsely to be checked (a random number would match "
                       f"{cp.chance:.0%} of them): print z with at least 4 decimals, e.g. f\"{{z:.6f}}\".", ev)
    ev["examples"] = _examples(sel, cp, 5, only_unmatched=cp.matched > 0) or _examples(sel, cp, 5)
    ex = next(iter(ev["examples"]), None)
    detail = ""
    if ex:
        detail = (f" For example, for u1={ex['u1']:.6g}, u2={ex['u2']:.6g} you printed {ex['printed']:.6g} "
                  f"but z = {ex['expected_z']:.6g}.")
    if cp.ratio > 0:
        frac = cp.ratio
        return Finding(value, frac, "partial",
                       f"Only {cp.matched} of {cp.expected} published pairs got a correct z printed "
                       f"(missing or wrong lines).{detail}", ev)
    return Finding(value, 0.0, "fail",
                   "Your printed values do not match z = sqrt(-2 ln u1)·cos(2πu2) nor a common variant of it."
                   + detail, ev)


@register("boxmuller_logging", evidence={**EVIDENCE, "value": ("values written by", "")},
          expect="values logged with self.get_logger().info (at least {min_outputs} lines on /rosout)",
          defaults={
    **COMMON_DEFAULTS,
    "tail_grace_s": 2.0,
    "min_outputs": 10,       # numeric lines a logger needs to count as "logs its values"
})
def boxmuller_logging(frames: Frames, p: dict) -> Finding:
    """The subscriber reports z through ROS logging (/rosout), as the lab asks, not print().

    Why: ``self.get_logger().info`` output is visible to every ROS tool (rqt_console, /rosout,
    log files); print() only reaches the terminal.
    """
    inp = _inputs(frames, p["topic"])
    if inp is None or len(inp) == 0:
        return Finding.error(f"No pairs were recorded on {p['topic']}, so logging could not be tested.",
                             {"topic": p["topic"]})
    has_rosout = topic(frames, ROSOUT) is not None or meta_row(frames, ROSOUT) is not None
    if not has_rosout:
        return Finding.error("/rosout was not recorded, so logging cannot be checked (scenario problem).")
    srcs = _sources(frames, p)
    ros = [s for s in srcs if s.kind == "rosout"]
    ev: dict = {"rosout_loggers": sorted({s.name for s in ros}),
                "stdout_processes": sorted({s.name for s in srcs if s.kind == "stdout"})}
    if ros:
        sel = select(frames, p, ros)
        src = sel.best.source if sel.best else max(ros, key=lambda s: s.n_numeric)
        ev.update({"logger": src.name, "n_numeric_lines": src.n_numeric,
                   "matched_correct": sel.correct.matched if sel.correct else 0})
        if src.n_numeric >= p["min_outputs"]:
            return Finding(src.name, 1.0, "pass",
                           f"Values are logged through ROS logging (logger '{src.name}', {src.n_numeric} lines).", ev)
        return Finding(src.name, 0.0, "fail",
                       f"Logger '{src.name}' logged only {src.n_numeric} numeric line(s) for {len(inp)} received "
                       "pairs: log z once per message with self.get_logger().info(...).", ev)
    std = [s for s in srcs if s.kind == "stdout"]
    if std:
        s = max(std, key=lambda s: s.n_numeric)
        ev.update({"process": s.name, "n_numeric_lines": s.n_numeric, "examples": s.text[:3]})
        return Finding("print()", 0.0, "fail",
                       "Your subscriber prints its values with print(), which does not reach /rosout: "
                       "use self.get_logger().info(f\"{z}\") as the lab asks.", ev)
    return Finding.fail("No logged values were found: log z in sub_callback with self.get_logger().info(...).", ev)


@register("normality", evidence={**EVIDENCE, "value": ("printed values", "")},
          expect=("standard normal values: Shapiro-Wilk and Anderson-Darling p ≥ {alpha:g}, mean 0 and "
                  "standard deviation 1 within {z_bound:g} standard errors"),
          defaults={
    **COMMON_DEFAULTS,
    "tail_grace_s": 2.0,
    "min_samples": 20,
    "max_shapiro": 5000,     # scipy's Shapiro-Wilk is accurate up to 5000 samples
    "alpha": 0.01,           # Shapiro-Wilk and Anderson-Darling significance level
    "z_bound": 3.0,          # |mean| and |std - 1| allowed in standard errors
})
def normality(frames: Frames, p: dict) -> Finding:
    """The printed values look standard Normal: Shapiro-Wilk and Anderson-Darling (shape) plus mean
    ~ 0 and std ~ 1 within ``z_bound`` standard errors (a Normal with the wrong scale, e.g. the log10
    bug, passes the shape tests but not this one). Half credit for each part.
    """
    sel = select(frames, p)
    if sel.best is not None:
        src, pos = sel.best.source, sel.best.pos
    elif sel.sources:
        src, pos = max(sel.sources, key=lambda s: (s.kind == "rosout", s.n_numeric)), -1
    else:
        early = _no_output_finding(frames, p, sel)
        return early or Finding.fail("No printed values to test.")
    v, _ = src.column(pos)
    x = v[np.isfinite(v)]
    n = len(x)
    ev: dict = {"source": {"kind": src.kind, "name": src.name}, "number_position": pos, "n": n}
    if n < p["min_samples"]:
        return Finding(n, 0.0, "fail",
                       f"Only {n} printed value(s): at least {p['min_samples']} are needed to test normality.", ev)
    mean, std = float(np.mean(x)), float(np.std(x, ddof=1))
    sw = stats.shapiro(x[: p["max_shapiro"]])
    try:
        ad = stats.anderson(x, "norm", method="interpolate")
        ad_stat, ad_p = float(ad.statistic), float(ad.pvalue)
    except TypeError:  # scipy < 1.17
        ad = stats.anderson(x, "norm")
        crit = dict(zip(ad.significance_level, ad.critical_values))
        ad_stat = float(ad.statistic)
        ad_p = 0.0 if ad_stat > crit.get(1.0, np.inf) else 1.0
    se_mean, se_std = 1.0 / math.sqrt(n), 1.0 / math.sqrt(2.0 * (n - 1))
    ev.update({"mean": mean, "std": std, "shapiro_W": float(sw.statistic), "shapiro_p": float(sw.pvalue),
               "anderson_stat": ad_stat, "anderson_p": ad_p,
               "mean_bound": p["z_bound"] * se_mean, "std_bound": p["z_bound"] * se_std})
    counts, edges = np.histogram(np.clip(x, -4.0, 4.0), bins=np.linspace(-4.0, 4.0, 33))
    ev["histogram"] = {"bins": edges.round(3).tolist(), "counts": counts.tolist(),
                       "reference": "normal", "xlabel": "z"}
    xs = np.sort(x)
    keep = thin(n, 300)
    ev["qq"] = {"theoretical": np.round(stats.norm.ppf((keep + 1 - 0.375) / (n + 0.25)), 4).tolist(),
                "sample": np.round(xs[keep], 4).tolist()}
    shape_ok = sw.pvalue >= p["alpha"] and ad_p >= p["alpha"]
    std_ok = abs(mean) <= p["z_bound"] * se_mean and abs(std - 1.0) <= p["z_bound"] * se_std
    frac = 0.5 * shape_ok + 0.5 * std_ok
    value = f"mean {mean:.3f}, std {std:.3f}, n {n}"
    if shape_ok and std_ok:
        return Finding(value, 1.0, "pass", f"Your {n} values look standard Normal (mean {mean:.3f}, std {std:.3f}).", ev)
    parts = []
    if not shape_ok:
        parts.append(f"the values are not Normal-shaped (Shapiro-Wilk p = {sw.pvalue:.2g}, "
                     f"Anderson-Darling p = {ad_p:.2g})")
    if not std_ok:
        parts.append(f"mean {mean:.3f} / std {std:.3f} are not those of a standard Normal (0 / 1)")
    return Finding(value, frac, graded(frac),
                   "Your values: " + " and ".join(parts) + ". Check the Box-Muller formula (†).", ev)
