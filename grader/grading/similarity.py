"""``grader similarity OUT``: source and behaviour similarity of a graded class, and against known
solutions, written to ``OUT/similarity/`` (``similarity.json`` for the class view, ``pairs.csv``,
one side-by-side page per listed pair).

Inputs are what ``grader grade`` left in OUT: ``<id>/source/`` (the counted source files, kept at
grade time), ``<id>/scenarios/<sc>/fingerprint.json`` (behaviour features, made when the bag was
analyzed; made here from the bag when missing) and ``<id>/result.json``. No student code runs.

It is the batch's last step, on the grading floor: it reads recordings as the analysis does
(``grading.analysis.scenario_frames``) and rewrites the class view (``grading.outputs``), so it
lived in ``grader.similarity`` (``similarity.run``) with three imports up a floor; the
fingerprints, the pair scores and the pages it composes stay in ``grader.similarity``.
"""

from __future__ import annotations

import csv
import io
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from grader.errors import GraderError
from grader.contracts.output_folder import OutputFolder, SubmissionFolder
from grader.similarity import behaviour, code
from grader.similarity.compare import analyse, BehaviourAnalysis, BehaviourMatch, TOLERANCE, UNIFORM_SHARE
from grader.similarity.files import SOURCE_DIR
from grader.similarity.summary import KNOWN_PREFIX, OUT_DIR, PAIRS_CSV, SUMMARY, read_summary
from grader import analyze
from grader.grading.analysis import scenario_frames
from grader.grading.outputs import write_batch_outputs
from grader.grading.repeat import scenario_of
from grader.contracts.result_document import ResultDocument
from grader.report.result import atomic_write, read_document
from grader.similarity.page import render_pair
from grader.workspace.source import extract_archive, is_archive

if TYPE_CHECKING:
    import numpy as np

    from grader.rubric.schema import Rubric

MAX_FEATURES = 40            # shared features kept per listed pair (most telling first)


@dataclass
class Settings:
    """What decides which pairs are listed; every number is written into similarity.json."""

    threshold: float = 0.5            # a pair is listed when its source similarity reaches this ...
    behaviour_threshold: float = 0.3  # ... or its behaviour similarity reaches this (another scale: a
    #                                   group of k alike among N holds log2(N/k) / log2(N/2) of its bits)
    min_shared: int = 8               # fingerprints two submissions must share for any source score
    common_share: float = 0.2         # fingerprints held by more of the class than this share ...
    common_min: int = 10              # ... and by more than this many submissions are not counted
    boilerplate: list[str] = field(default_factory=list)     # folders of given code (besides the rubric's)
    known: str | None = None
    max_pages: int = 50               # side-by-side pages (and class-view rows) for the most similar listed pairs


@dataclass
class Pair:
    a: str
    b: str
    source: float = 0.0
    a_in_b: float = 0.0
    b_in_a: float = 0.0
    shared_fingerprints: int = 0
    behaviour: float = 0.0
    behaviour_bits: float = 0.0
    features: list[dict[str, Any]] = field(default_factory=list)
    known: bool = False
    listed: bool = False
    cluster: int | None = None

    @property
    def score(self) -> float:
        return max(self.source, self.behaviour)

    def strength(self, settings: "Settings") -> float:
        """How far the pair reaches its thresholds (>= 1: listed); the class view's order."""
        return max(self.source / max(settings.threshold, 1e-9),
                   self.behaviour / max(settings.behaviour_threshold, 1e-9))

    @property
    def page(self) -> str:
        return pair_page_name(self.a, self.b)


def pair_page_name(a: str, b: str) -> str:
    return f"pair-{a.replace(':', '_')}--{b.replace(':', '_')}.html"


def graded_ids(out: Path) -> list[str]:
    return sorted(p.parent.name for p in Path(out).glob("*/result.json"))


def _scenario_features(sub_out: Path) -> list[behaviour.Feature]:
    """Stored fingerprints of a submission's scenarios; made from the bag where missing. A
    repeated scenario (``repeat:``) counts by its first run, as every submission has that one."""
    feats = []
    for sc_dir in _first_runs(sub_out):
        stored = behaviour.read_fingerprint(sc_dir)
        if stored is None and (sc_dir / "bag").exists():
            try:
                behaviour.write_fingerprint(sc_dir, scenario_frames(sc_dir))
            except Exception:  # noqa: BLE001 - an unreadable bag: that scenario has no features
                continue
            stored = behaviour.read_fingerprint(sc_dir)
        feats += stored or []
    return feats


def _first_runs(sub_out: Path) -> list[Path]:
    return sorted(p for p in SubmissionFolder(Path(sub_out)).scenarios.glob("*") if p.is_dir() and scenario_of(p.name) == p.name)


def _labels(rubric: Rubric) -> tuple[dict[str, list[str]], dict[str, dict]]:
    scenarios = {i.id: list(i.scenario) for i in rubric.items}
    labels = {}
    for item in rubric.items:
        if item.analyzer:
            try:
                labels[item.id] = analyze.evidence_labels(item.analyzer)
            except Exception:  # noqa: BLE001
                labels[item.id] = {}
    return scenarios, labels


def _passing(docs: dict[str, ResultDocument], item_scenarios: dict[str, list[str]]) -> dict[str, set[str]]:
    """scenario -> submissions whose every item on it passed."""
    out: dict[str, set[str]] = {}
    failed: dict[str, set[str]] = {}
    for sid, doc in docs.items():
        for item in doc.items:
            for sc in item_scenarios.get(item.id, []):
                out.setdefault(sc, set()).add(sid)
                if item.kind in ("auto", "advisory") and item.status != "pass":
                    failed.setdefault(sc, set()).add(sid)
    return {sc: subs - failed.get(sc, set()) for sc, subs in out.items()}


def _known_sets(root: Path, boilerplate: np.ndarray, work: Path) -> list[code.SourceSet]:
    """Each folder or archive under ``root`` as one known solution."""
    root = Path(root)
    if not root.is_dir():
        raise GraderError(f"--known {root}: not a folder (give a folder of workspaces or archives)")
    entries = sorted(p for p in root.iterdir() if not p.name.startswith(".") and (p.is_dir() or is_archive(p)))
    if not entries:
        raise GraderError(f"--known {root}: no folders or archives in it")
    sets = []
    for entry in entries:
        name = entry.name
        folder = entry
        if is_archive(entry):
            folder = extract_archive(entry, work / name)
        sets.append(code.read_set(KNOWN_PREFIX + name, folder, boilerplate))
    return sets


def _behaviour_worker(sub_out: str) -> tuple[str, list[dict]]:
    feats = _scenario_features(Path(sub_out))
    return Path(sub_out).name, [asdict(f) for f in feats]


def compute(out: Path, rubric: Rubric, settings: Settings, jobs: int = 2) -> dict[str, Any]:
    """Every pair of the class (and against known solutions); the summary written to OUT/similarity."""
    out = Path(out)
    ids = graded_ids(out)
    if len(ids) < 2 and not settings.known:
        raise GraderError(f"{out}: {len(ids)} graded submission(s); similarity needs two or more "
                          "(or --known)")
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    docs = {sid: read_document(OutputFolder(out).submission(sid).result_json) for sid in ids}
    feats, item_scenarios = _behaviour_features(out, ids, docs, rubric, jobs)
    timings["behaviour_features_s"] = time.perf_counter() - t0

    t1 = time.perf_counter()
    found = analyse(feats, _passing(docs, item_scenarios), ids)
    bmatches = found.matches
    timings["behaviour_pairs_s"] = time.perf_counter() - t1

    # source
    t2 = time.perf_counter()
    sets, boiler, no_source, common = _source_sets(out, ids, rubric, settings)
    timings["source_fingerprints_s"] = time.perf_counter() - t2
    t3 = time.perf_counter()
    smatches = code.compare_all(sets, settings.min_shared)
    known_pairs, known_sets = _known_matches(settings, boiler, common, sets)
    timings["source_pairs_s"] = time.perf_counter() - t3

    pairs = _pairs(smatches, known_pairs, bmatches, settings)
    t4 = time.perf_counter()
    _explain(pairs, bmatches, found)
    timings["behaviour_explained_s"] = time.perf_counter() - t4
    clusters = _assign_clusters(pairs)
    ranked = sorted(pairs.values(), key=lambda p: (not p.listed, -p.strength(settings), p.a, p.b))
    timings["total_s"] = time.perf_counter() - t0
    return {
        "schema": 1, "lab": next(iter(docs.values())).lab if docs else None,
        "submissions": ids, "class_size": len(ids), "pairs_compared": len(ids) * (len(ids) - 1) // 2,
        "known": [k.id[len(KNOWN_PREFIX):] for k in known_sets],
        "settings": {**asdict(settings), "noise_chars": code.NOISE, "guarantee_chars": code.GUARANTEE,
                     "tolerance": _tolerances(), "common_fingerprints_dropped": len(common)},
        "no_source": no_source,
        "clusters": [sorted(c) for c in clusters],
        "pairs": [asdict(p) | {"score": p.score, "strength": round(p.strength(settings), 4),
                               "page": p.page if p.listed and rank < settings.max_pages else None}
                  for rank, p in enumerate(ranked)],             # listed pairs come first
        "timings": {k: round(v, 3) for k, v in timings.items()},
        "_sets": {s.id: s for s in sets + known_sets},
        "_features": feats,
    }


def _behaviour_features(out: Path, ids: list[str], docs: dict[str, ResultDocument], rubric: Any,
                        jobs: int) -> tuple[dict[str, list[behaviour.Feature]], dict[str, list[str]]]:
    """Behaviour features per submission (bags read, on ``jobs`` processes, only where none are stored)."""
    missing = [sid for sid in ids if any((d / "bag").exists() and not (d / behaviour.FINGERPRINT_FILE).exists()
                                         for d in _first_runs(out / sid))]
    feats: dict[str, list[behaviour.Feature]] = {}
    if missing and jobs > 1 and len(missing) > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for sid, fl in pool.map(_behaviour_worker, [str(out / s) for s in missing]):
                feats[sid] = [behaviour.Feature.from_dict(f) for f in fl]
    item_scenarios, labels = _labels(rubric)
    for sid in ids:
        if sid not in feats:
            feats[sid] = _scenario_features(out / sid)
        feats[sid] += behaviour.result_features(docs[sid].items, item_scenarios, labels)
    return feats, item_scenarios


def _source_sets(out: Path, ids: list[str], rubric: Any,
                 settings: Settings) -> tuple[list[code.SourceSet], Any, list[str], set[int]]:
    """Source sets without given or class-wide code; also the boilerplate and dropped hashes known solutions need."""
    given = [Path(p) for p in ([rubric.handout] if rubric.handout else []) + list(rubric.support.values())]
    given += [Path(p) for p in settings.boilerplate]
    boiler = code.boilerplate_hashes(given)
    sets = [code.read_set(sid, out / sid / SOURCE_DIR, boiler) for sid in ids]
    no_source = [s.id for s in sets if not (out / s.id / SOURCE_DIR).is_dir()]
    common = code.drop_common(sets, settings.common_share, settings.common_min)
    return sets, boiler, no_source, common


def _known_matches(settings: Settings, boiler: Any, common: set[int], sets: list[code.SourceSet]
                   ) -> tuple[dict[tuple[str, str], code.SourceMatch], list[code.SourceSet]]:
    """Each submission against each ``--known`` solution (kept when they share enough), and those solutions."""
    known_pairs: dict[tuple[str, str], code.SourceMatch] = {}
    known_sets: list[code.SourceSet] = []
    if settings.known:
        with tempfile.TemporaryDirectory(prefix="grader-known-") as tmp:
            known_sets = _known_sets(Path(settings.known), boiler, Path(tmp))
        for k in known_sets:
            k.hashes -= common
            for s in sets:
                m = code.compare_one(s, k)
                if m.shared >= settings.min_shared:
                    known_pairs[s.id, k.id] = m
    return known_pairs, known_sets


def _pairs(smatches: dict[tuple[str, str], code.SourceMatch], known_pairs: dict[tuple[str, str], code.SourceMatch],
           bmatches: dict[tuple[str, str], BehaviourMatch], settings: Settings) -> dict[tuple[str, str], Pair]:
    """Source and behaviour scores merged into one Pair per pair, each marked listed or not."""
    pairs: dict[tuple[str, str], Pair] = {}
    for (a, b), m in list(smatches.items()) + list(known_pairs.items()):
        pairs[a, b] = Pair(a, b, round(float(m.score), 4), round(float(m.a_in_b), 4), round(float(m.b_in_a), 4),
                           int(m.shared), known=b.startswith(KNOWN_PREFIX))
    for (a, b), bm in bmatches.items():
        p = pairs.setdefault((a, b), Pair(a, b))
        p.behaviour, p.behaviour_bits = float(bm.score), float(bm.bits)
    for p in pairs.values():
        p.listed = bool(p.source >= settings.threshold or p.behaviour >= settings.behaviour_threshold)
    return pairs


def _explain(pairs: dict[tuple[str, str], Pair], bmatches: dict[tuple[str, str], BehaviourMatch],
             found: BehaviourAnalysis) -> None:
    """The shared features behind each listed behaviour pair: only the pairs the class view shows pay for them."""
    for p in pairs.values():
        if p.listed and (p.a, p.b) in bmatches:
            p.features = [vars(s).copy() for s in found.shared(p.a, p.b)[:MAX_FEATURES]]


def _assign_clusters(pairs: dict[tuple[str, str], Pair]) -> list[set[str]]:
    """The clusters of listed class pairs, with each listed pair inside one numbered by it."""
    clusters = _clusters([p for p in pairs.values() if p.listed and not p.known])
    for i, members in enumerate(clusters):
        for p in pairs.values():
            if p.listed and p.a in members and p.b in members:
                p.cluster = i
    return clusters


def _tolerances() -> dict[str, float]:
    return {**TOLERANCE, "uniform_share": UNIFORM_SHARE}


def _clusters(pairs: list[Pair]) -> list[set[str]]:
    """Groups of three or more submissions joined by listed pairs."""
    parent: dict[str, str] = {}

    def find(x: str) -> str:
        parent.setdefault(x, x)
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for p in pairs:
        parent[find(p.a)] = find(p.b)
    groups: dict[str, set[str]] = {}
    for x in list(parent):
        groups.setdefault(find(x), set()).add(x)
    return sorted((g for g in groups.values() if len(g) >= 3), key=lambda g: (-len(g), sorted(g)))


def pairs_csv(summary: dict[str, Any]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["a", "b", "score", "source", "a_in_b", "b_in_a", "shared_fingerprints", "behaviour",
                "behaviour_bits", "known_solution", "listed", "cluster", "top_features"])
    for p in summary["pairs"]:
        top = "; ".join(f["label"] for f in p["features"][:5])
        w.writerow([p["a"], p["b"], f"{p['score']:.4f}", f"{p['source']:.4f}", f"{p['a_in_b']:.4f}",
                    f"{p['b_in_a']:.4f}", p["shared_fingerprints"], f"{p['behaviour']:.4f}",
                    f"{p['behaviour_bits']:.3f}", p["b"][len(KNOWN_PREFIX):] if p["known"] else "",
                    "yes" if p["listed"] else "", "" if p["cluster"] is None else p["cluster"] + 1, top])
    return buf.getvalue()


def write(out: Path, summary: dict[str, Any]) -> Path:
    """similarity.json, pairs.csv and the listed pairs' pages under OUT/similarity/."""
    folder = Path(out) / OUT_DIR
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("pair-*.html"):
        old.unlink()
    public = {k: v for k, v in summary.items() if not k.startswith("_")}
    t = time.perf_counter()
    for p in summary["pairs"]:
        if p["page"]:
            atomic_write(folder / p["page"], render_pair(p, summary, Path(out)))
    public["timings"]["pages_s"] = round(time.perf_counter() - t, 3)
    atomic_write(folder / SUMMARY, json.dumps(public, indent=1) + "\n")
    atomic_write(folder / PAIRS_CSV, pairs_csv(public))
    return folder


def run_similarity(out: Path, rubric: Rubric, settings: Settings | None = None, jobs: int = 2) -> dict[str, Any]:
    """Compute, write OUT/similarity/ and rewrite the class view with it; the summary."""
    summary = compute(Path(out), rubric, settings or Settings(), jobs=jobs)
    write(Path(out), summary)
    write_batch_outputs(Path(out), rubric)
    return summary


__all__ = ["KNOWN_PREFIX", "OUT_DIR", "Pair", "Settings", "compute", "pair_page_name", "pairs_csv",
           "read_summary", "run_similarity", "write"]
