"""Mutants of a ROS 2 Python workspace: small, realistic bugs made with Python AST operators.

Why: a rubric that gives full marks to broken code has a blind spot. ``grader rubric audit``
mutates a lab's reference solution with these operators and grades every mutant; issue 22's
flake benchmark builds a class of realistic buggy submissions from them. Both need the same
mutants, in the same order, from the same input, so everything here is deterministic and pure
(no ROS, no randomness except :func:`sample` with an explicit seed).

API (all of it)::

    from grader.audit.mutate import OPERATORS, Mutant, mutants, sample

    found = mutants(Path("fixtures/submissions/wall_pen/reference"))      # list[Mutant], stable order
    found = mutants(root, operators=["flip_sign", "drop_call"])            # a subset of OPERATORS
    some = sample(found, 10, seed=1)                                       # n of them, same seed = same n
    m = found[0]
    m.id, m.operator, m.file, m.line, m.description     # "flip_sign-1a2b3c4d", ..., "src/pkg/pkg/node.py", 27, "..."
    print(m.diff)                                        # unified diff (a/<file>, b/<file>)
    m.write(Path("/tmp/mutant"))                         # copy of the workspace with the mutation applied
    m.mutated_source()                                   # the mutated file's text

``root`` is a submission: a colcon workspace (``src/...``), a folder of packages or one package.
Every ``*.py`` file under it is mutated except ``setup.py`` and tests (``test/``, ``tests/``,
``test_*.py``); ``__pycache__`` and hidden folders are skipped.

Operators (``OPERATORS``, in this order):

* ``flip_sign``: a numeric constant ``c`` -> ``-c``; ``-e`` -> ``e``; ``a + b`` <-> ``a - b``
  (numbers only: not next to a string) and ``+=`` <-> ``-=``.
* ``scale_constant``: a numeric constant ``c`` -> ``2 * c`` (not 0; timer periods and rates
  belong to ``change_timer_period``).
* ``swap_args``: two neighbouring arguments of a call (positional, or the values of two
  keywords) or elements of a list/tuple literal, when both are of the same kind (two names, two
  calls, two numbers...): ``atan2(dy, dx)``, ``Point(x=a, y=b)``, ``[u1, u2]``. Not swapped:
  strings, classes, ``self``, attributes given by keyword (callbacks) and constructor calls:
  such a swap only breaks start-up (a type where a topic name goes), which says nothing about
  a rubric.
* ``rename_topic``: a topic, service or action name (a string argument of ``create_publisher``,
  ``create_subscription``, ``create_service``, ``create_client``, ``ActionServer``,
  ``ActionClient``, or any string constant that looks like an absolute ROS name ``/a/b``) gets
  ``_renamed`` appended.
* ``drop_call``: a statement that is only a call is replaced by ``pass``: a publish, a log line,
  any other call (the description says which). Not in ``except``/``finally`` blocks (clean-up)
  and not ``super().__init__`` (the node would not exist).
* ``remove_angle_wrap``: ``atan2(sin(e), cos(e))`` -> ``e`` (math, numpy: ``arctan2``),
  ``math.remainder(e, 2*pi)`` -> ``e``, ``x % (2*pi)`` (or ``% tau``) -> ``x``, and a
  ``while``/``if`` that adds or subtracts ``2*pi`` when an angle passes ``pi`` -> ``pass``.
* ``change_timer_period``: the period of ``create_timer(period, ...)`` doubled and halved, the
  frequency of ``create_rate(f)`` / ``Rate(f)`` halved and doubled (two mutants each).

Not mutated, because the change cannot matter or cannot be read: docstrings and every part of
an f-string, annotations, subscript indices (``data[0]``), QoS depths (``qos_profile`` and the
last positional argument of ``create_publisher``/``create_subscription``), ``num_threads``, the
exception types of an ``except`` clause, and the body of ``if __name__ == "__main__":`` (dead
code under ``ros2 run``, whose console script calls ``main`` itself).

Identity: a mutant's ``id`` is ``<operator>-<8 hex>``, a hash of the file's path, the enclosing
function, the operator, the original and mutated source of the changed part and its occurrence
among identical changes in that function. It survives edits elsewhere in the file (lines
moving), so a rubric can record an equivalent mutant by id. Mutants that produce a file
identical to the original or to an earlier mutant are left out.
"""

from __future__ import annotations

import ast
import difflib
import hashlib
import random
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from grader.audit import aspects
from grader.audit.operators import MAKERS, Edit, Source, parents_of, scope_of, unmutable
from grader.contracts.mutants import OPERATORS


#: every operator ``mutants`` takes: the audit's (``OPERATORS``, its default) and the one-aspect
#: operators of the collateral-loss audit (``grader.audit.aspects``)
KNOWN: tuple[str, ...] = OPERATORS + tuple(o for o in aspects.ASPECT_OPERATORS if o not in OPERATORS)
ALL_MAKERS = {**MAKERS, **aspects.MAKERS}

#: files and folders a mutant copy leaves out (grading artefacts, expectations of the original)
COPY_IGNORE = ("__pycache__", ".grader-check", "expected.yaml", "*.pyc")

@dataclass(frozen=True)
class Mutant:
    """One mutation of one file of a workspace.

    ``file`` is relative to ``root`` (POSIX form); ``line`` and ``col`` (1-based) locate the
    change in the original file; ``original``/``replacement`` are the source text of the changed
    part before and after.
    """

    id: str
    operator: str
    file: str
    line: int
    col: int
    description: str
    original: str
    replacement: str
    root: Path = field(repr=False)
    _source: str = field(repr=False, compare=False)
    _mutated: str = field(repr=False, compare=False)

    def mutated_source(self) -> str:
        """The whole mutated file."""
        return self._mutated

    @property
    def diff(self) -> str:
        """A unified diff of the file (``a/<file>`` -> ``b/<file>``, 2 lines of context)."""
        return "".join(difflib.unified_diff(self._source.splitlines(keepends=True),
                                            self._mutated.splitlines(keepends=True),
                                            f"a/{self.file}", f"b/{self.file}", n=2))

    def write(self, dest: Path) -> Path:
        """Copy the workspace to ``dest`` (which must not exist) with this mutation applied;
        returns ``dest``. ``COPY_IGNORE`` entries are left out."""
        dest = Path(dest)
        shutil.copytree(self.root, dest, ignore=shutil.ignore_patterns(*COPY_IGNORE), symlinks=True)
        (dest / self.file).write_text(self._mutated, encoding="utf-8")
        return dest

    def summary(self) -> dict[str, object]:
        """JSON-friendly description (no file contents)."""
        return {"id": self.id, "operator": self.operator, "file": self.file, "line": self.line,
                "col": self.col, "description": self.description, "original": self.original,
                "replacement": self.replacement}


def source_files(root: Path) -> list[Path]:
    """The Python files of a workspace that are mutated, sorted by relative path."""
    root = Path(root)
    out = []
    for path in root.rglob("*.py"):
        rel = path.relative_to(root)
        parts = rel.parts
        if any(p.startswith(".") or p in ("__pycache__", "test", "tests", "build", "install", "log")
               for p in parts[:-1]):
            continue
        if rel.name == "setup.py" or rel.name.startswith("test_") or not path.is_file():
            continue
        out.append(path)
    return sorted(out, key=lambda p: p.relative_to(root).as_posix())


def mutants(root: Path, operators: Iterable[str] | None = None) -> list[Mutant]:
    """Every mutant of the workspace at ``root``, deterministic: files by path, then by
    position in the file, then by operator order. ``operators``: a subset of ``OPERATORS``
    (unknown names raise ValueError)."""
    root = Path(root).resolve()
    chosen = OPERATORS if operators is None else tuple(operators)
    unknown = [o for o in chosen if o not in KNOWN]
    if unknown:
        raise ValueError(f"unknown mutation operator(s) {', '.join(unknown)}; known: {', '.join(KNOWN)}")
    out: list[Mutant] = []
    for path in source_files(root):
        source = path.read_text(encoding="utf-8", errors="replace")
        try:
            tree = ast.parse(source)
        except SyntaxError:
            continue          # a file that does not parse has nothing to mutate
        rel = path.relative_to(root).as_posix()
        out += _file_mutants(root, rel, source, tree, [o for o in KNOWN if o in chosen])
    return out


def sample(found: list[Mutant], n: int | None, seed: int = 0) -> list[Mutant]:
    """``n`` mutants chosen with ``random.Random(seed)``, kept in their original order (all of
    them when n is None or not smaller)."""
    if n is None or n >= len(found):
        return list(found)
    picked = set(random.Random(seed).sample(range(len(found)), n))
    return [m for i, m in enumerate(found) if i in picked]


# ------------------------------------------------------------------------------ one file
def _file_mutants(root: Path, rel: str, source: str, tree: ast.Module, operators: list[str]) -> list[Mutant]:
    src = Source(source)
    parents = parents_of(tree)
    skip = unmutable(tree, parents)
    edits: list[tuple[tuple[int, int, int, int], Edit]] = []
    for op_index, op in enumerate(operators):
        for order, edit in enumerate(ALL_MAKERS[op](tree, parents, skip, src)):
            node = edit.node
            edits.append(((node.lineno, node.col_offset, op_index, order), edit))
    edits.sort(key=lambda e: e[0])
    out: list[Mutant] = []
    seen = {source}
    occurrences: dict[str, int] = {}
    for _, edit in edits:
        a, b = src.span(edit.node)
        text = edit.text
        if edit.statement:
            text = "pass"
        mutated = source[:a] + text + source[b:]
        if mutated in seen:
            continue
        try:
            ast.parse(mutated)
        except SyntaxError:
            continue
        seen.add(mutated)
        original = source[a:b]
        scope = scope_of(getattr(edit.node, "first", edit.node), parents)
        key = f"{rel}|{scope}|{edit.operator}|{original}|{text}"
        occurrences[key] = occurrences.get(key, 0) + 1
        digest = hashlib.sha1(f"{key}|{occurrences[key]}".encode()).hexdigest()[:8]
        out.append(Mutant(id=f"{edit.operator}-{digest}", operator=edit.operator, file=rel,
                          line=edit.node.lineno, col=_col(src, edit.node), description=edit.description,
                          original=original, replacement=text, root=root, _source=source, _mutated=mutated))
    return out


def _col(src: Source, node: Any) -> int:
    return src.offset(node.lineno, node.col_offset) - src.starts[node.lineno - 1] + 1
