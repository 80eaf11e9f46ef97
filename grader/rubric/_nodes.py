"""Reading YAML *nodes* (not plain Python objects) so every problem can name its file and line.

``yaml.safe_load`` throws line numbers away; ``yaml.compose`` keeps a ``start_mark`` on every
node. The validator walks that node tree with a :class:`Reader`, which collects *all* problems
instead of stopping at the first, because an instructor fixing a rubric wants the whole list
in one run.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Iterator

import yaml
from yaml.constructor import SafeConstructor
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

MERGE_TAG = "tag:yaml.org,2002:merge"
_IDENT_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")


@dataclass(frozen=True, order=True)
class Problem:
    """One rubric problem, printed as ``file:line: field.path: message``."""

    file: str
    line: int
    path: str
    message: str

    def __str__(self) -> str:
        where = f"{self.path}: " if self.path else ""
        return f"{self.file}:{self.line}: {where}{self.message}"


def join_path(parent: str, key: str | int) -> str:
    """Field path in the dotted style users type: ``items[3].points``, ``scenarios.ex1.steps[0]``."""
    if isinstance(key, int):
        return f"{parent}[{key}]"
    if _IDENT_KEY.match(key):
        return f"{parent}.{key}" if parent else key
    return f"{parent}[{key!r}]"


def describe(node: Node, value: Any = None) -> str:
    """How a wrong value is quoted back to the user: the value itself for scalars."""
    if isinstance(node, MappingNode):
        return "a mapping"
    if isinstance(node, SequenceNode):
        return "a list"
    if value is None:
        return "nothing (null)"
    return repr(value)


def parse(text: str, file: str) -> tuple[Node | None, list[Problem]]:
    """Compose one YAML document into nodes; a syntax error becomes a located Problem."""
    try:
        return yaml.compose(text, Loader=yaml.SafeLoader), []
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark else 1
        what = " ".join(p for p in (exc.context, exc.problem) if p) or str(exc)
        return None, [Problem(file, line, "", f"YAML syntax error: {what}")]
    except yaml.YAMLError as exc:  # pragma: no cover - unmarked errors are rare (encoding)
        return None, [Problem(file, 1, "", f"YAML error: {exc}")]


def suggest(word: str, candidates: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for a near miss, else an empty string."""
    close = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


class Reader:
    """Collects problems while converting nodes to values; never raises on bad input."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.problems: list[Problem] = []
        self._constructor = SafeConstructor()

    # -- reporting -------------------------------------------------------------------------
    def error(self, where: Node | int, path: str, message: str) -> None:
        line = where if isinstance(where, int) else where.start_mark.line + 1
        self.problems.append(Problem(self.file, line, path, message))

    # -- conversion ------------------------------------------------------------------------
    def plain(self, node: Node) -> Any:
        """The Python value of any node (for free-form data such as analyzer ``params``)."""
        value = self._constructor.construct_object(node, deep=True)
        self._constructor.constructed_objects.clear()
        self._constructor.recursive_objects.clear()
        return value

    def pairs(self, node: MappingNode, path: str) -> list[tuple[Node, Node, bool]]:
        """``(key, value, explicit)`` of a mapping with YAML merge keys (``<<: *anchor``)
        expanded: explicit keys first, then merged ones (which explicit keys override)."""
        explicit, merged = [], []
        for key_node, value_node in node.value:
            if key_node.tag != MERGE_TAG:
                explicit.append((key_node, value_node, True))
                continue
            sources = value_node.value if isinstance(value_node, SequenceNode) else [value_node]
            for source in sources:
                if not isinstance(source, MappingNode):
                    self.error(source, path, "'<<' merges a mapping (an &anchor), got "
                                             f"{describe(source, self.scalar(source))}")
                    continue
                merged.extend((k, v, False) for k, v, _ in self.pairs(source, path))
        return explicit + merged

    def scalar(self, node: Node) -> Any:
        return self.plain(node) if isinstance(node, ScalarNode) else None

    def fields(self, node: Node, path: str, allowed: Iterable[str],
               required: Iterable[str] = ()) -> "Fields | None":
        """Open a mapping: unknown keys, duplicate keys and missing required keys are problems."""
        if not isinstance(node, MappingNode):
            self.error(node, path, f"expected a mapping, got {describe(node, self.scalar(node))}")
            return None
        allowed = tuple(allowed)
        entries: dict[str, tuple[Node, Node]] = {}
        for key_node, value_node, explicit in self.pairs(node, path):
            key = self.scalar(key_node)
            if not isinstance(key, str):
                self.error(key_node, path, f"keys must be text, got {describe(key_node, key)}")
                continue
            if key in entries:
                if not explicit:
                    continue          # a merged key, overridden by an explicit one
                first = entries[key][0].start_mark.line + 1
                self.error(key_node, join_path(path, key), f"duplicate key (first given on line {first})")
                continue
            if key not in allowed:
                hint = suggest(key, allowed) or f" (allowed: {', '.join(allowed)})"
                self.error(key_node, join_path(path, key), f"unknown key {key!r}{hint}")
                continue
            entries[key] = (key_node, value_node)
        for key in required:
            if key not in entries:
                self.error(node, join_path(path, key), "required key is missing")
        return Fields(self, node, path, entries)

    def items(self, node: Node, path: str) -> Iterator[tuple[int, Node, str]]:
        """Elements of a list node as ``(index, node, path)``; a non-list is a problem."""
        if not isinstance(node, SequenceNode):
            self.error(node, path, f"expected a list, got {describe(node, self.scalar(node))}")
            return
        for index, child in enumerate(node.value):
            yield index, child, join_path(path, index)

    def mapping_entries(self, node: Node, path: str) -> Iterator[tuple[str, Node, Node, str]]:
        """Entries of a free-key mapping (ids, package names) as ``(key, key_node, value, path)``."""
        if not isinstance(node, MappingNode):
            self.error(node, path, f"expected a mapping, got {describe(node, self.scalar(node))}")
            return
        seen: dict[str, int] = {}
        for key_node, value_node, explicit in self.pairs(node, path):
            key = self.scalar(key_node)
            if not isinstance(key, str):
                self.error(key_node, path, f"keys must be text, got {describe(key_node, key)}")
                continue
            if key in seen:
                if not explicit:
                    continue
                self.error(key_node, join_path(path, key), f"duplicate key (first given on line {seen[key]})")
                continue
            seen[key] = key_node.start_mark.line + 1
            yield key, key_node, value_node, join_path(path, key)

    # -- typed scalars ---------------------------------------------------------------------
    def string(self, node: Node, path: str, *, pattern: re.Pattern[str] | None = None,
               what: str = "text", choices: Iterable[str] | None = None) -> str | None:
        value = self.scalar(node)
        if not isinstance(value, str) or (not value.strip()):
            got = describe(node, value) if value != "" else "an empty string"
            quote = " (quote it)" if isinstance(value, (int, float, bool)) else ""
            self.error(node, path, f"expected {what}{quote}, got {got}")
            return None
        if choices is not None:
            choices = tuple(choices)
            if value not in choices:
                hint = suggest(value, choices)
                self.error(node, path, f"expected one of {', '.join(choices)}, got {value!r}{hint}")
                return None
        if pattern is not None and not pattern.match(value):
            self.error(node, path, f"expected {what}, got {value!r}")
            return None
        return value

    def number(self, node: Node, path: str, *, minimum: float | None = None,
               maximum: float | None = None, exclusive_minimum: bool = False,
               integer: bool = False) -> float | None:
        value = self.scalar(node)
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if ok and integer and not (float(value).is_integer()):
            ok = False
        if ok and not math.isfinite(value):
            ok = False
        if ok and minimum is not None:
            ok = value > minimum if exclusive_minimum else value >= minimum
        if ok and maximum is not None:
            ok = value <= maximum
        if not ok:
            kind = "an integer" if integer else "a number"
            bounds = []
            if minimum is not None:
                bounds.append(f"{'>' if exclusive_minimum else '>='} {_fmt(minimum)}")
            if maximum is not None:
                bounds.append(f"<= {_fmt(maximum)}")
            self.error(node, path, f"expected {kind}{' ' + ' and '.join(bounds) if bounds else ''}, "
                                   f"got {describe(node, value)}")
            return None
        return int(value) if integer else value

    def boolean(self, node: Node, path: str) -> bool | None:
        value = self.scalar(node)
        if not isinstance(value, bool):
            self.error(node, path, f"expected true or false, got {describe(node, value)}")
            return None
        return value


class Fields:
    """The validated keys of one mapping, with typed getters that record problems."""

    def __init__(self, reader: Reader, node: MappingNode, path: str,
                 entries: dict[str, tuple[Node, Node]]) -> None:
        self.reader = reader
        self.node = node
        self.path = path
        self.entries = entries

    @property
    def line(self) -> int:
        return self.node.start_mark.line + 1

    def __contains__(self, key: str) -> bool:
        return key in self.entries

    def keys(self) -> list[str]:
        return list(self.entries)

    def value_node(self, key: str) -> Node:
        return self.entries[key][1]

    def key_node(self, key: str) -> Node:
        return self.entries[key][0]

    def sub(self, key: str) -> str:
        return join_path(self.path, key)

    def error(self, key: str | None, message: str) -> None:
        """A problem about ``key`` (at its line), or about the whole mapping when key is None."""
        if key is not None and key in self.entries:
            self.reader.error(self.entries[key][1], self.sub(key), message)
        else:
            self.reader.error(self.node, self.sub(key) if key else self.path, message)

    def get(self, key: str, convert: Callable[..., Any], default: Any = None, **kwargs: Any) -> Any:
        """``convert(node, path, **kwargs)`` on the key's node, or ``default`` when absent."""
        if key not in self.entries:
            return default
        return convert(self.entries[key][1], self.sub(key), **kwargs)

    def string(self, key: str, default: str | None = None, **kwargs: Any) -> str | None:
        return self.get(key, self.reader.string, default, **kwargs)

    def number(self, key: str, default: float | None = None, **kwargs: Any) -> float | None:
        return self.get(key, self.reader.number, default, **kwargs)

    def boolean(self, key: str, default: bool | None = None) -> bool | None:
        return self.get(key, self.reader.boolean, default)

    def plain(self, key: str, default: Any = None) -> Any:
        return self.reader.plain(self.entries[key][1]) if key in self.entries else default

    def mapping(self, key: str) -> dict[str, Any]:
        """A free-form mapping (params, msg fields) as plain Python; ``{}`` when absent."""
        if key not in self.entries:
            return {}
        node = self.entries[key][1]
        if not isinstance(node, MappingNode):
            self.reader.error(node, self.sub(key),
                              f"expected a mapping, got {describe(node, self.reader.scalar(node))}")
            return {}
        value = self.reader.plain(node)
        for k in value:
            if not isinstance(k, str):
                self.reader.error(node, self.sub(key), f"keys must be text, got {k!r}")
                return {}
        return value


def _fmt(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else str(x)
