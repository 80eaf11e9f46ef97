"""Behaviour similarity of every pair of a class, weighed by how unusual the shared behaviour is
in this class and by how little of it the lab forces.

For each feature (grader.similarity.behaviour) two submissions hold, with ``d`` their distance:

* closeness: 1 within the feature kind's tolerance (``TOLERANCE``: two recordings of one code
  differ by that much), falling to 0 at three times it;
* rarity: ``log2(N / n)`` bits, where ``n`` counts the class members (the two included) at least
  as close to either of them (within the tolerance counts as equal): a path two of 200 drive is
  worth 6.6 bits, one that 150 drive 0.4;
* forced: how close both are to what the submissions that pass the scenario's items do (their
  medoid). Correct solutions converge on the same trajectory, gains and rate because the lab asks
  for them; agreeing there is expected, agreeing away from it is not. Tokens (log lines, names,
  failing items) are not discounted: rarity alone weighs them.

``N`` is the number of submissions with a recording of the feature's scenario (the class, but for
those whose build failed). A feature's evidence is closeness x rarity x (1 - forced). Features of
one scenario and group (paths, commands, ...) are averaged (tokens: summed), each group capped at
``log2(N / 2)`` bits, the most two submissions alone can share; a pair's behaviour score is its
evidence over the sum of those caps for the groups both have: 1 for a pair alone in the class with
identical, unforced behaviour. A group in which every submission that ran the scenario holds the
same (the topic the lab names, the rate every timer keeps) cannot tell anyone apart and is left
out of both.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Iterable, Mapping

import numpy as np

from grader.similarity.behaviour import Feature

#: distance within which two values count as the same (two gradings of the same code differ by less)
TOLERANCE = {"path": 0.05,      # m, RMS over the resampled path
             "series": 0.05,    # RMS difference over the class's spread of that field
             "scalar": 0.02}    # relative difference


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


def _distances(kind: str, values: list) -> np.ndarray:
    """Pairwise distances of one feature's values (k x k)."""
    if kind == "path":
        n = max(len(v) for v in values)
        arr = np.full((len(values), n, 2), np.nan)
        for i, v in enumerate(values):
            a = np.asarray(v, dtype=float).reshape(-1, 2)
            arr[i, :len(a)] = a
        diff = arr[:, None, :, :] - arr[None, :, :, :]
        return np.sqrt(np.nanmean(np.sum(diff ** 2, axis=-1), axis=-1))
    if kind == "series":
        n = max(len(v) for v in values)
        arr = np.full((len(values), n), np.nan)
        for i, v in enumerate(values):
            arr[i, :len(v)] = np.asarray(v, dtype=float)
        spread = float(np.nanstd(arr))
        scale = spread if spread > 1e-9 else 1.0
        with np.errstate(invalid="ignore"):
            d = np.sqrt(np.nanmean((arr[:, None, :] - arr[None, :, :]) ** 2, axis=-1)) / scale
        return np.nan_to_num(d, nan=np.inf)
    v = np.asarray(values, dtype=float)
    den = np.maximum(np.maximum(np.abs(v[:, None]), np.abs(v[None, :])), 1e-9)
    return np.abs(v[:, None] - v[None, :]) / den


def compare_behaviour(features: Mapping[str, list[Feature]], passing: Mapping[str, set[str]],
                      ids: list[str]) -> dict[tuple[str, str], BehaviourMatch]:
    """Every pair with any shared evidence. ``features``: submission -> its features;
    ``passing``: scenario -> submissions whose items on it all passed (for the forced part).

    Rarity is counted among the submissions that have the feature's scenario at all (``N`` of
    the module docstring): a submission whose build failed, or a regrade from bags of some
    scenarios only, does not make what the others share look rare."""
    if len(ids) < 2:
        return {}
    order = {sid: i for i, sid in enumerate(ids)}
    by_key: dict[str, dict[str, Feature]] = defaultdict(dict)
    ran: dict[str, set[str]] = defaultdict(set)            # scenario -> submissions with features of it
    for sid, feats in features.items():
        for f in feats:
            by_key[f.key][sid] = f
            ran[f.scenario].add(sid)
    n_of = {sc: len(subs) for sc, subs in ran.items()}
    held: dict[str, dict[tuple[str, str], set[str]]] = defaultdict(lambda: defaultdict(set))  # sid -> group -> keys
    per_pair: dict[tuple[str, str], list[Shared]] = defaultdict(list)
    uniform: set[str] = set()          # keys every submission that ran the scenario holds alike
    for key, holders in by_key.items():
        first = next(iter(holders.values()))
        for sid in holders:
            held[sid][first.scenario, first.group].add(key)
        if len(holders) < 2:
            continue
        sids = sorted(holders, key=order.__getitem__)
        if first.kind == "token":
            alike = _tokens(key, first, sids, holders, n_of[first.scenario], per_pair)
        else:
            alike = _continuous(key, first, sids, holders, n_of[first.scenario],
                                passing.get(first.scenario, set()), per_pair)
        if alike and len(holders) == n_of[first.scenario]:
            uniform.add(key)
    out = {}
    for (a, b), shared in per_pair.items():
        groups: dict[tuple[str, str], list[Shared]] = defaultdict(list)
        for s in shared:
            groups[s.scenario, s.group].append(s)
        bits = 0.0
        for (sc, group), items in groups.items():
            counts = len(held[a][sc, group] & held[b][sc, group])
            if items[0].distance is None:
                bits += min(cap(n_of[sc]), sum(s.evidence for s in items))
            else:
                bits += min(cap(n_of[sc]), sum(s.evidence for s in items) / max(1, counts))
        # the groups that could tell them apart: both have it, and it is not the same in everyone
        telling = [g for g in held[a].keys() & held[b].keys() if (held[a][g] | held[b][g]) - uniform]
        possible = sum(cap(n_of[sc]) for sc, _group in telling)
        score = bits / possible if possible else 0.0
        if bits > 0:
            shared.sort(key=lambda s: -s.evidence)
            out[a, b] = BehaviourMatch(a, b, round(min(1.0, score), 4), round(bits, 3), len(telling), shared)
    return out


def cap(n: int) -> float:
    """The most bits one group of features can give a pair among ``n`` submissions: what two
    of them alone share (``log2(n / 2)``)."""
    return math.log2(n / 2) if n > 2 else 1.0


def _pair(a: str, b: str, order: list[str]) -> tuple[str, str]:
    return (a, b) if order.index(a) < order.index(b) else (b, a)


def _tokens(key: str, first: Feature, sids: list[str], holders: Mapping[str, Feature], n_class: int,
            per_pair: dict) -> bool:
    """Pairs holding the same value; True when every holder holds the same one."""
    by_value: dict[str, list[str]] = defaultdict(list)
    for sid in sids:
        by_value[str(holders[sid].value)].append(sid)
    for value, same in by_value.items():
        if len(same) < 2:
            continue
        bits = math.log2(n_class / len(same))
        if bits <= 0:
            continue
        label = holders[same[0]].label
        for i in range(len(same)):
            for j in range(i + 1, len(same)):
                per_pair[same[i], same[j]].append(Shared(key, label, first.group, first.scenario, None, 1.0,
                                                         len(same), round(bits, 3), 0.0, round(bits, 3), n_class))
    return len(by_value) == 1


def _continuous(key: str, first: Feature, sids: list[str], holders: Mapping[str, Feature], n_class: int,
                passing: set[str], per_pair: dict) -> bool:
    """Pairs within three tolerances; True when every holder is within one of every other."""
    tol = TOLERANCE[first.kind]
    try:
        d = _distances(first.kind, [holders[s].value for s in sids])
    except (ValueError, TypeError):
        return False
    close = closeness(d, tol)
    iu, ju = np.nonzero(np.triu(close > 0, k=1))
    if not len(iu):
        return False
    radius = np.maximum(d[iu, ju], tol)
    near = (d[iu] <= radius[:, None]) | (d[ju] <= radius[:, None])
    holders_n = near.sum(axis=1)
    bits = np.log2(n_class / np.maximum(holders_n, 2))
    # forced: both near the medoid of the submissions that pass this scenario
    ok = [i for i, s in enumerate(sids) if s in passing]
    forced = np.zeros(len(iu))
    if ok:
        sub = d[np.ix_(ok, ok)]
        medoid = ok[int(np.argmin(np.nansum(np.where(np.isfinite(sub), sub, 1e9), axis=1)))]
        to_medoid = closeness(d[:, medoid], tol)
        forced = np.minimum(to_medoid[iu], to_medoid[ju])
    evidence = close[iu, ju] * bits * (1.0 - forced)
    for k in range(len(iu)):
        if evidence[k] <= 0:
            continue
        a, b = sids[iu[k]], sids[ju[k]]
        per_pair[a, b].append(Shared(key, first.label, first.group, first.scenario, round(float(d[iu[k], ju[k]]), 5),
                                     round(float(close[iu[k], ju[k]]), 3), int(holders_n[k]), round(float(bits[k]), 3),
                                     round(float(forced[k]), 3), round(float(evidence[k]), 3), n_class))
    return bool(np.all(d <= tol))


def iter_pairs(ids: Iterable[str]):
    ids = list(ids)
    for i in range(len(ids)):
        for j in range(i + 1, len(ids)):
            yield ids[i], ids[j]


__all__ = ["BehaviourMatch", "Shared", "TOLERANCE", "cap", "closeness", "compare_behaviour", "iter_pairs"]
