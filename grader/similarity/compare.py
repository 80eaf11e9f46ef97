"""Behaviour similarity of every pair of a class, weighed by how unusual the shared behaviour is
in this class and by how little of it the lab forces.

For each feature (grader.similarity.behaviour) two submissions hold, with ``d`` their distance:

* closeness: 1 within the feature kind's tolerance (``TOLERANCE``: two recordings of one code
  differ by that much), falling to 0 at three times it;
* rarity: ``log2(N / n)`` bits, where ``n`` counts the class members (the two included) at least
  as close to one of them as they are to each other (within the tolerance counts as equal; the
  larger of the two neighbourhoods): a path two of 200 drive is worth 6.6 bits, one that 150
  drive 0.4;
* forced: how close both are to what the submissions that pass the scenario's items do (their
  medoid). Correct solutions converge on the same trajectory, gains and rate because the lab asks
  for them; agreeing there is expected, agreeing away from it is not. Tokens (log lines, names,
  failing items) are not discounted: rarity alone weighs them.

``N`` is the number of submissions with a recording of the feature's scenario (the class, but for
those whose build failed). A feature's evidence is closeness x rarity x (1 - forced). Features of
one scenario and group (paths, commands, ...) are averaged (tokens: summed), each group capped at
``log2(N / 2)`` bits, the most two submissions alone can share; a pair's behaviour score is its
evidence over the sum of those caps for the groups both have: 1 for a pair alone in the class with
identical, unforced behaviour. A group whose every feature ``UNIFORM_SHARE`` of the submissions
that ran the scenario hold alike (the topic the lab names, the rate every timer keeps, an action
server every solution gets right) cannot tell anyone apart and is left out of both.

Every pair of a class is scored with one matrix per (scenario, group), so 200 submissions (19,900
pairs, ~220 features each) take seconds (benchmarks/bench_similarity.py); the feature-by-feature
account of a pair (``Shared``, for its page) is made only for the pairs that are shown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping

import numpy as np

from grader.similarity.behaviour import Feature

#: distance within which two values count as the same (two gradings of the same code differ by less)
TOLERANCE = {"path": 0.05,      # m, RMS over the resampled path
             "series": 0.05,    # RMS difference over the class's spread of that field
             "scalar": 0.02}    # relative difference
#: a feature that this share of the submissions that ran its scenario hold alike (within the
#: tolerance of their medoid; tokens: the same value) cannot tell a pair apart from the class
UNIFORM_SHARE = 0.9
_FAR = 1e6                      # a distance that cannot be computed (series of other lengths, NaN)


@dataclass
class Shared:
    """One feature two submissions share, with why it counts."""

    key: str
    label: str
    group: str
    scenario: str
    distance: float | None        # None for tokens
    closeness: float
    holders: int                  # class members at least as close (the two included)
    bits: float                   # rarity
    forced: float
    evidence: float
    among: int = 0                # submissions with a recording of the scenario (N)


@dataclass
class BehaviourMatch:
    a: str
    b: str
    score: float
    bits: float
    groups: int
    shared: list[Shared] = field(default_factory=list)


def closeness(d: np.ndarray | float, tol: float) -> np.ndarray:
    d = np.asarray(d, dtype=float)
    return np.clip(1.0 - (d - tol) / (2.0 * tol), 0.0, 1.0)


def cap(n: int) -> float:
    """The most bits one group of features can give a pair among ``n`` submissions: what two
    of them alone share (``log2(n / 2)``)."""
    return math.log2(n / 2) if n > 2 else 1.0


def _distances(kind: str, values: list) -> np.ndarray:
    """Pairwise distances of one feature's values (k x k); ``_FAR`` where none can be computed."""
    if kind == "path":
        n = max(len(v) for v in values)
        arr = np.full((len(values), n, 2), np.nan)
        for i, v in enumerate(values):
            a = np.asarray(v, dtype=float).reshape(-1, 2)
            arr[i, :len(a)] = a
        diff = arr[:, None, :, :] - arr[None, :, :, :]
        with np.errstate(invalid="ignore"):
            d = np.sqrt(np.nanmean(np.sum(diff ** 2, axis=-1), axis=-1))
    elif kind == "series":
        n = max(len(v) for v in values)
        arr = np.full((len(values), n), np.nan)
        for i, v in enumerate(values):
            arr[i, :len(v)] = np.asarray(v, dtype=float)
        spread = float(np.nanstd(arr))
        scale = spread if spread > 1e-9 else 1.0
        with np.errstate(invalid="ignore"):
            d = np.sqrt(np.nanmean((arr[:, None, :] - arr[None, :, :]) ** 2, axis=-1)) / scale
    else:
        v = np.asarray(values, dtype=float)
        den = np.maximum(np.maximum(np.abs(v[:, None]), np.abs(v[None, :])), 1e-9)
        d = np.abs(v[:, None] - v[None, :]) / den
    return np.where(np.isfinite(d), d, _FAR)


def _neighbours(d: np.ndarray, rows: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """For each (row, radius): how many columns of ``d[row]`` are within ``radius`` (one sort per
    row, one binary search per query)."""
    k = d.shape[0]
    step = 4.0 * _FAR
    flat = (np.sort(d, axis=1) + np.arange(k)[:, None] * step).ravel()
    return np.searchsorted(flat, radius + rows * step, side="right") - rows * k


@dataclass
class _Key:
    """What a pair's account needs of one feature: its holders and their distances."""

    first: Feature
    sids: list[str]
    pos: dict[str, int]
    n: int                              # N of its scenario
    uniform: bool
    d: np.ndarray | None = None         # continuous: k x k distances
    to_medoid: np.ndarray | None = None  # continuous: closeness to the passing medoid
    same: dict[str, int] | None = None  # token: value -> holders


class _Group:
    """Accumulated evidence of one (scenario, group) over every pair (upper triangle)."""

    def __init__(self, n: int, token: bool) -> None:
        self.evidence = np.zeros((n, n))
        self.counts = np.zeros((n, n), dtype=np.int32)     # keys both hold that can tell
        self.holds = np.zeros(n, dtype=bool)
        self.tells = np.zeros(n, dtype=bool)               # holds a key not everyone holds alike
        self.token = token


class BehaviourAnalysis:
    """Scores of every pair (``matches``) and, on demand, the features behind one (``shared``)."""

    def __init__(self, features: Mapping[str, list[Feature]], passing: Mapping[str, set[str]], ids: list[str]):
        self.ids = list(ids)
        order = {sid: i for i, sid in enumerate(self.ids)}
        by_key: dict[str, dict[str, Feature]] = {}
        ran: dict[str, set[str]] = {}
        for sid, feats in features.items():
            for f in feats:
                by_key.setdefault(f.key, {})[sid] = f
                ran.setdefault(f.scenario, set()).add(sid)
        self.n_of = {sc: len(subs) for sc, subs in ran.items()}
        self.keys: dict[str, _Key] = {}
        self.held: dict[str, set[str]] = {sid: set() for sid in self.ids}
        n = len(self.ids)
        groups: dict[tuple[str, str], _Group] = {}
        for key, holders in by_key.items():
            first = next(iter(holders.values()))
            sids = sorted(holders, key=order.__getitem__)
            for sid in sids:
                self.held[sid].add(key)
            gi = np.array([order[s] for s in sids])
            g = groups.setdefault((first.scenario, first.group), _Group(n, first.kind == "token"))
            g.holds[gi] = True
            k = _Key(first, sids, {s: i for i, s in enumerate(sids)}, self.n_of[first.scenario], False)
            self.keys[key] = k
            if first.kind == "token":
                self._token(k, holders, gi, g)
            else:
                self._continuous(k, holders, gi, g, passing.get(first.scenario, set()))
        self.matches = self._score(groups)

    def _token(self, k: _Key, holders: Mapping[str, Feature], gi: np.ndarray, g: _Group) -> None:
        values = [str(holders[s].value) for s in k.sids]
        k.same = {}
        for v in values:
            k.same[v] = k.same.get(v, 0) + 1
        k.uniform = max(k.same.values()) >= UNIFORM_SHARE * k.n
        if k.uniform:
            return
        g.tells[gi] = True
        for value, count in k.same.items():
            bits = math.log2(k.n / count)
            if count < 2 or bits <= 0:
                continue
            idx = gi[[i for i, v in enumerate(values) if v == value]]
            g.evidence[np.ix_(idx, idx)] += bits

    def _continuous(self, k: _Key, holders: Mapping[str, Feature], gi: np.ndarray, g: _Group,
                    passing: set[str]) -> None:
        tol = TOLERANCE[k.first.kind]
        try:
            d = _distances(k.first.kind, [holders[s].value for s in k.sids])
        except (ValueError, TypeError):
            return
        medoid = int(np.argmin(d.sum(axis=1)))
        k.uniform = bool((d[medoid] <= tol).sum() >= UNIFORM_SHARE * k.n)
        if k.uniform:
            return
        g.tells[gi] = True
        g.counts[np.ix_(gi, gi)] += 1
        if len(k.sids) < 2:
            return
        ok = [i for i, s in enumerate(k.sids) if s in passing]
        k.to_medoid = np.zeros(len(k.sids))
        if ok:
            sub = d[np.ix_(ok, ok)]
            k.to_medoid = closeness(d[:, ok[int(np.argmin(sub.sum(axis=1)))]], tol)
        k.d = d.astype(np.float32)
        close = closeness(d, tol)
        iu, ju = np.nonzero(np.triu(close > 0, k=1))
        if not len(iu):
            return
        radius = np.maximum(d[iu, ju], tol)
        n_near = np.maximum(_neighbours(d, iu, radius), _neighbours(d, ju, radius))
        bits = np.log2(k.n / np.maximum(n_near, 2))
        forced = np.minimum(k.to_medoid[iu], k.to_medoid[ju])
        g.evidence[gi[iu], gi[ju]] += close[iu, ju] * bits * (1.0 - forced)

    def _score(self, groups: Mapping[tuple[str, str], _Group]) -> dict[tuple[str, str], BehaviourMatch]:
        n = len(self.ids)
        bits = np.zeros((n, n))
        possible = np.zeros((n, n))
        telling = np.zeros((n, n), dtype=np.int32)
        for (sc, _group), g in groups.items():
            c = cap(self.n_of[sc])
            got = g.evidence if g.token else g.evidence / np.maximum(g.counts, 1)
            bits += np.minimum(c, got)
            tell = np.outer(g.holds, g.holds) & (g.tells[:, None] | g.tells[None, :])
            possible += tell * c
            telling += tell
        iu, ju = np.nonzero(np.triu(bits > 1e-9, k=1))
        score = bits[iu, ju] / np.maximum(possible[iu, ju], 1e-9)
        return {(self.ids[i], self.ids[j]): BehaviourMatch(self.ids[i], self.ids[j], round(min(1.0, float(s)), 4),
                                                           round(float(bits[i, j]), 3), int(telling[i, j]))
                for i, j, s in zip(iu, ju, score)}

    def shared(self, a: str, b: str) -> list[Shared]:
        """The features ``a`` and ``b`` share, each with its evidence, most telling first."""
        out = []
        for key in self.held.get(a, set()) & self.held.get(b, set()):
            k = self.keys[key]
            if k.uniform:
                continue
            ia, ib = k.pos[a], k.pos[b]
            f = k.first
            if k.same is not None:
                va = str(self._value(key, a))
                if va != str(self._value(key, b)):
                    continue
                count = k.same[va]
                bits = math.log2(k.n / count)
                if bits > 0:
                    out.append(Shared(key, f.label, f.group, f.scenario, None, 1.0, count, round(bits, 3), 0.0,
                                      round(bits, 3), k.n))
                continue
            if k.d is None:
                continue
            tol = TOLERANCE[f.kind]
            dist = float(k.d[ia, ib])
            close = float(closeness(dist, tol))
            if close <= 0:
                continue
            radius = max(dist, tol)
            near = int(max((k.d[ia] <= radius).sum(), (k.d[ib] <= radius).sum()))
            bits = math.log2(k.n / max(near, 2))
            medoid = k.to_medoid if k.to_medoid is not None else np.zeros(k.n)
            forced = float(min(medoid[ia], medoid[ib]))
            evidence = close * bits * (1.0 - forced)
            if evidence > 0:
                out.append(Shared(key, f.label, f.group, f.scenario, round(dist, 5), round(close, 3), near,
                                  round(bits, 3), round(forced, 3), round(evidence, 3), k.n))
        out.sort(key=lambda s: (-s.evidence, s.key))
        return out

    def _value(self, key: str, sid: str):
        return self._features_of[sid][key]

    def keep_values(self, features: Mapping[str, list[Feature]]) -> None:
        self._features_of = {sid: {f.key: f.value for f in feats if f.kind == "token"}
                             for sid, feats in features.items()}


def analyse(features: Mapping[str, list[Feature]], passing: Mapping[str, set[str]],
            ids: list[str]) -> BehaviourAnalysis:
    """Score every pair (``.matches``: pairs with any shared evidence); ``.shared(a, b)`` tells why.
    ``features``: submission -> its features; ``passing``: scenario -> submissions whose items on
    it all passed (for the forced part)."""
    out = BehaviourAnalysis(features, passing, ids)
    out.keep_values(features)
    return out


def compare_behaviour(features: Mapping[str, list[Feature]], passing: Mapping[str, set[str]],
                      ids: list[str]) -> dict[tuple[str, str], BehaviourMatch]:
    """Every pair with any shared evidence, each with its shared features (for a small class or
    a test; a class view explains only the pairs it shows, with ``analyse``)."""
    if len(ids) < 2:
        return {}
    found = analyse(features, passing, ids)
    for (a, b), m in found.matches.items():
        m.shared = found.shared(a, b)
    return found.matches


def iter_pairs(ids: Iterable[str]):
    ids = list(ids)
    for i in range(len(ids)):
        for j in range(i + 1, len(ids)):
            yield ids[i], ids[j]


__all__ = ["BehaviourAnalysis", "BehaviourMatch", "Shared", "TOLERANCE", "UNIFORM_SHARE", "analyse", "cap",
           "closeness", "compare_behaviour", "iter_pairs"]
