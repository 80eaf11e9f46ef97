"""Source similarity with copydetect (the winnowing fingerprints of MOSS: Schleimer, Wilkerson and
Aiken 2003): each counted file is tokenized by Pygments with identifiers, function and class names
and string contents replaced by one letter each, so renamed identifiers and reformatted code
(spacing, indentation, comments, blank lines) fingerprint alike; numbers and the code's structure
stay.

A submission is the union of its files' fingerprints minus the boilerplate's (the rubric's handout
and support packages, and an optional folder of the lab text's code): given code never counts.
Fingerprints that more than ``common_share`` of the class (and at least ``common_min``
submissions) hold are dropped as well, as MOSS does (its ``-m``): idioms every solution has are
no evidence. Every pair is then compared through an inverted index (fingerprint -> submissions),
so a class costs the sum of its fingerprints, not pairs x files. The share of A's fingerprints
found in B (and of B's in A) is the pair's source similarity; the side-by-side page asks
copydetect's ``compare_files`` for the matched regions of the files of one pair.

Interface files (``.msg``/``.srv``/``.action``) have no Pygments lexer: they are compared with
comments and whitespace removed.

copydetect 0.5 hashes each k-gram with Python's ``hash()``, which Python seeds anew in every
process (``PYTHONHASHSEED``): winnowing keeps each window's smallest hash, so another seed keeps
other fingerprints and the same class scored otherwise on every run (measured on the similarity
test class: honest_b/honest_c 0.253 in one run, 0.236 in the next). ``stable_hashes`` puts a
seedless 64-bit hash of the same k-grams in its place (a numpy polynomial hash, mixed), so a class scores the same on
every run and machine; copydetect's tokenizing, winnowing and region matching are unchanged.
"""

from __future__ import annotations

import io
import logging
import re
from typing import Any
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from grader.similarity.files import INTERFACE_SUFFIXES, read_text, source_files

#: copydetect's defaults: matches shorter than NOISE characters of filtered code are ignored, and
#: every match of GUARANTEE characters or more is found (window = GUARANTEE - NOISE + 1)
NOISE = 25
GUARANTEE = 30


def _lexer_language(rel: Path) -> str | None:
    name = rel.name
    if name.endswith(".py"):
        return "python"
    if name == "CMakeLists.txt":
        return "cmake"
    if name.endswith(".xml"):
        return "xml"
    if name.endswith((".yaml", ".yml")):
        return "yaml"
    return None


def _interface_text(text: str) -> str:
    """An interface definition without comments and blank lines, one space between words."""
    lines = [re.sub(r"\s+", " ", line.split("#", 1)[0]).strip() for line in text.splitlines()]
    return "\n".join(line for line in lines if line)


@dataclass
class FileFingerprint:
    rel: str                              # path inside the submission
    fp: Any                               # copydetect.CodeFingerprint (untyped library)

    @property
    def hashes(self) -> set[int]:
        return self.fp.hashes


@dataclass
class SourceSet:
    """One submission's (or known solution's) counted files and their fingerprints."""

    id: str
    files: list[FileFingerprint] = field(default_factory=list)
    hashes: set[int] = field(default_factory=set)
    problems: list[str] = field(default_factory=list)

    @property
    def size(self) -> int:
        return len(self.hashes)


def _kgram_hashes(string: str, k: int) -> np.ndarray:
    """copydetect's ``hashed_kgrams`` with a hash that is the same in every process: a polynomial
    hash of each k-gram's code points modulo 2**64, its bits mixed (splitmix64's finaliser) so
    that the smallest of a window is as good as random. Vectorized: k passes over the text."""
    codes = np.frombuffer(string.encode("utf-32-le", "surrogatepass"), dtype=np.uint32).astype(np.uint64)
    n = len(codes) - k + 1
    if n <= 0:
        return np.zeros(0, dtype=np.int64)
    h = np.zeros(n, dtype=np.uint64)
    base = np.uint64(1_000_003)
    with np.errstate(over="ignore"):
        for j in range(k):
            h = h * base + codes[j:j + n]
        h ^= h >> np.uint64(30)
        h *= np.uint64(0xBF58476D1CE4E5B9)
        h ^= h >> np.uint64(27)
        h *= np.uint64(0x94D049BB133111EB)
        h ^= h >> np.uint64(31)
    return h.view(np.int64)


def stable_hashes() -> None:
    """Make copydetect's k-gram hashes seedless (see the module docstring); idempotent."""
    import copydetect.utils  # noqa: PLC0415 - copydetect.utils: 916 ms CPU to import, paid only on this path

    copydetect.utils.hashed_kgrams = _kgram_hashes


def fingerprint_file(path: Path, rel: Path, boilerplate: np.ndarray | None = None):
    """copydetect's CodeFingerprint of one file (None: nothing to compare in it)."""
    from copydetect import CodeFingerprint  # noqa: PLC0415 - copydetect: 916 ms CPU to import, paid only on this path

    stable_hashes()

    text = read_text(path)
    language = _lexer_language(rel)
    if rel.name.endswith(INTERFACE_SUFFIXES):
        text, language = _interface_text(text), None
    if not text.strip():
        return None
    logging.getLogger().disabled, was = True, logging.getLogger().disabled
    try:
        return CodeFingerprint(str(rel), NOISE, GUARANTEE - NOISE + 1, boilerplate=boilerplate,
                               filter=language is not None, language=language, fp=io.StringIO(text))
    finally:
        logging.getLogger().disabled = was


def read_set(sid: str, root: Path, boilerplate: np.ndarray | None = None) -> SourceSet:
    """Fingerprints of the counted files under ``root``."""
    out = SourceSet(sid)
    for rel in source_files(root):
        try:
            fp = fingerprint_file(Path(root) / rel, rel, boilerplate)
        except Exception as exc:  # noqa: BLE001 - a file Pygments cannot read costs only that file
            out.problems.append(f"{rel}: not compared ({exc})")
            continue
        if fp is not None and fp.hashes:
            out.files.append(FileFingerprint(rel.as_posix(), fp))
            out.hashes |= fp.hashes
    return out


def boilerplate_hashes(roots: list[Path]) -> np.ndarray:
    """Every fingerprint of the given code (handout, support packages, lab text): never counted."""
    hashes: set[int] = set()
    for root in roots:
        for rel in source_files(root):
            fp = fingerprint_file(Path(root) / rel, rel)
            if fp is not None:
                hashes |= fp.hashes
    return np.array(sorted(hashes), dtype=np.int64)


def drop_common(sets: list[SourceSet], share: float, minimum: int) -> set[int]:
    """Remove fingerprints held by more than ``share`` of the sets and at least ``minimum`` of
    them (in place); the removed ones."""
    counts = Counter(h for s in sets for h in s.hashes)
    limit = max(minimum, share * len(sets))
    common = {h for h, n in counts.items() if n > limit}
    if common:
        for s in sets:
            s.hashes -= common
    return common


@dataclass(frozen=True)
class SourceMatch:
    a: str
    b: str
    shared: int              # fingerprints in both
    a_in_b: float            # share of A's fingerprints found in B
    b_in_a: float

    @property
    def score(self) -> float:
        return max(self.a_in_b, self.b_in_a)


def compare_all(sets: list[SourceSet], min_shared: int) -> dict[tuple[str, str], SourceMatch]:
    """Every pair with at least ``min_shared`` fingerprints in common (the others score 0): one
    sparse product (submissions x fingerprints) with scipy, so a class costs its fingerprints."""
    from scipy import sparse  # noqa: PLC0415 - scipy: 1108 ms CPU to import, paid only on this path

    column: dict[int, int] = {}
    rows, cols = [], []
    for i, s in enumerate(sets):
        for h in s.hashes:
            rows.append(i)
            cols.append(column.setdefault(h, len(column)))
    if not rows:
        return {}
    m = sparse.csr_matrix((np.ones(len(rows), dtype=np.int32), (rows, cols)), shape=(len(sets), len(column)))
    shared = sparse.triu(m @ m.T, k=1).tocoo()
    out = {}
    for i, j, n in zip(shared.row, shared.col, shared.data):
        if n < min_shared:
            continue
        a, b = sets[i], sets[j]
        out[a.id, b.id] = SourceMatch(a.id, b.id, int(n), n / max(1, a.size), n / max(1, b.size))
    return out


def compare_one(a: SourceSet, b: SourceSet) -> SourceMatch:
    n = len(a.hashes & b.hashes)
    return SourceMatch(a.id, b.id, n, n / max(1, a.size), n / max(1, b.size))


@dataclass
class FileRegions:
    """Matched regions of one file of A against its best file of B (character offsets)."""

    a_file: str
    b_file: str
    a_text: str
    b_text: str
    a_slices: list[tuple[int, int]]
    b_slices: list[tuple[int, int]]
    a_share: float
    b_share: float


def matched_regions(a: SourceSet, b: SourceSet) -> list[FileRegions]:
    """For each file of A with fingerprints in B: the file of B sharing most, and copydetect's
    matched slices of both (in the files' own text). Most shared first."""
    from copydetect import compare_files  # noqa: PLC0415 - copydetect: 916 ms CPU to import, paid only on this path

    out = []
    for fa in a.files:
        best, best_n = None, 0
        for fb in b.files:
            n = len(fa.hashes & fb.hashes & a.hashes & b.hashes)
            if n > best_n:
                best, best_n = fb, n
        if best is None:
            continue
        _, (sa, sb), (slices_a, slices_b) = compare_files(fa.fp, best.fp)
        pairs_a = [(int(s), int(e)) for s, e in zip(*slices_a)] if len(slices_a) and len(slices_a[0]) else []
        pairs_b = [(int(s), int(e)) for s, e in zip(*slices_b)] if len(slices_b) and len(slices_b[0]) else []
        out.append((best_n, FileRegions(fa.rel, best.rel, fa.fp.raw_code, best.fp.raw_code, pairs_a, pairs_b,
                                        float(sa), float(sb))))
    out.sort(key=lambda r: -r[0])
    return [r for _, r in out]


__all__ = ["FileRegions", "SourceMatch", "SourceSet", "boilerplate_hashes", "compare_all", "compare_one",
           "drop_common", "fingerprint_file", "matched_regions", "read_set", "stable_hashes"]
