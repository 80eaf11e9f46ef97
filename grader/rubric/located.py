"""YAML with line numbers, and validation errors turned into ``file:line: field: message``.

``yaml.safe_load`` throws line numbers away; ``yaml.compose`` keeps a ``start_mark`` on every
node. :func:`load_located` turns the node tree into plain data (merge keys ``<<: *anchor``
expanded, duplicate keys reported) plus a map from each value's path to its line.
:func:`problems_from` turns pydantic's validation errors, which name a path (``loc``) but no line,
into :class:`Problem` lines an instructor can fix in one pass, in words ("expected a number >=
0, got 'ten'"), not pydantic's.
"""

from __future__ import annotations

import re
import typing
from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Sequence

import yaml
from pydantic import BaseModel, RootModel
from yaml.constructor import SafeConstructor
from yaml.nodes import MappingNode, Node, SequenceNode

from grader.contracts.text import PATTERN_WHAT, suggest

MERGE_TAG = "tag:yaml.org,2002:merge"
_IDENT_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")
Path_ = tuple  # a path into the data: keys (str) and list indices (int)


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


def dotted(path: Iterable[Any]) -> str:
    """``items[3].points``, ``scenarios.ex1.steps[0]`` (the style users type)."""
    out = ""
    for key in path:
        if isinstance(key, int):
            out += f"[{key}]"
        elif _IDENT_KEY.match(str(key)):
            out += f".{key}" if out else str(key)
        else:
            out += f"[{key!r}]"
    return out


class Located:
    """Plain data of one YAML document plus the line of every value (and of every key)."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.lines: dict[Path_, int] = {}       # path -> line of the value
        self.key_lines: dict[Path_, int] = {}   # path -> line of its key
        self.problems: list[Problem] = []
        self._constructor = SafeConstructor()

    def line(self, path: Path_) -> int:
        """The line of ``path``'s key, else of its value, else of the nearest parent."""
        path = tuple(path)
        while path:
            if path in self.key_lines:
                return self.key_lines[path]
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return self.lines.get((), 1)

    def error(self, path: Path_, message: str, line: int | None = None) -> None:
        self.problems.append(Problem(self.file, line or self.line(path), dotted(path), message))

    def data(self, node: Node, path: Path_ = ()) -> Any:
        self.lines[path] = node.start_mark.line + 1
        if isinstance(node, MappingNode):
            out: dict[Any, Any] = {}
            first: dict[Any, int] = {}
            for key_node, value_node, explicit in self._pairs(node, path):
                key = self._scalar(key_node)
                if not isinstance(key, str):
                    self.error(path, f"keys must be text, got {key!r}", key_node.start_mark.line + 1)
                    continue
                if key in out:
                    if explicit:
                        self.error(path + (key,), f"duplicate key (first given on line {first[key]})",
                                   key_node.start_mark.line + 1)
                    continue
                first[key] = key_node.start_mark.line + 1
                self.key_lines[path + (key,)] = first[key]
                out[key] = self.data(value_node, path + (key,))
            return out
        if isinstance(node, SequenceNode):
            return [self.data(child, path + (i,)) for i, child in enumerate(node.value)]
        return self._scalar(node)

    def _scalar(self, node: Node) -> Any:
        value = self._constructor.construct_object(node, deep=True)
        self._constructor.constructed_objects.clear()
        return value

    def _pairs(self, node: MappingNode, path: Path_) -> list[tuple[Node, Node, bool]]:
        """Explicit keys first, then keys merged in with ``<<`` (which explicit keys override)."""
        explicit: list[tuple[Node, Node, bool]] = []
        merged: list[tuple[Node, Node, bool]] = []
        for key_node, value_node in node.value:
            if key_node.tag != MERGE_TAG:
                explicit.append((key_node, value_node, True))
                continue
            sources = value_node.value if isinstance(value_node, SequenceNode) else [value_node]
            for source in sources:
                if not isinstance(source, MappingNode):
                    self.error(path, "'<<' merges a mapping (an &anchor)", source.start_mark.line + 1)
                    continue
                merged.extend((k, v, False) for k, v, _ in self._pairs(source, path))
        return explicit + merged


#: libyaml's parser where PyYAML was built with it (the wheels are): the same nodes and marks as
#: the pure-Python one, composed in 3 ms instead of 35 ms for Lab 3's rubric
_FAST_LOADER: Any = getattr(yaml, "CSafeLoader", None)


def _compose(text: str) -> Node | None:
    """The document's node tree. A document libyaml refuses is composed again by PyYAML's own
    parser, so that a syntax error is worded (and located) as it always was."""
    if _FAST_LOADER is not None:
        try:
            return yaml.compose(text, Loader=_FAST_LOADER)
        except yaml.YAMLError:
            pass
    return yaml.compose(text, Loader=yaml.SafeLoader)


def load_located(text: str, file: str, empty: str = "the file is empty") -> tuple[Any, Located]:
    """Compose one YAML document; a syntax error becomes a located Problem."""
    located = Located(file)
    try:
        root = _compose(text)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        what = " ".join(p for p in (exc.context, exc.problem) if p) or str(exc)
        located.problems.append(Problem(file, mark.line + 1 if mark else 1, "", f"YAML syntax error: {what}"))
        return None, located
    except yaml.YAMLError as exc:  # pragma: no cover - unmarked errors are rare (encoding)
        located.problems.append(Problem(file, 1, "", f"YAML error: {exc}"))
        return None, located
    if root is None:
        located.problems.append(Problem(file, 1, "", empty))
        return None, located
    return located.data(root), located


# ----------------------------------------------------------------------------------------------
# pydantic errors -> problems

def problems_from(errors: Sequence[Mapping[str, Any]], data: Any, located: Located, model: type) -> list[Problem]:
    """One Problem per validation error, located at the path's line, worded for a person."""
    nested = {tuple(e["loc"][:-1]) for e in errors if len(e["loc"]) > 1}
    by_path: dict[Path_, list[tuple[str, Any]]] = {}
    for err in errors:
        if err["type"] == "too_short" and any(n[:len(err["loc"])] == tuple(err["loc"]) for n in nested):
            continue                     # "at least one item" because an item was invalid
        path = _data_path(err["loc"], data, names_key=err["type"] in ("missing", "extra_forbidden", "rule"))
        by_path.setdefault(path, []).append((_message(err, path, model), err.get("input")))
    out = []
    for path, found in by_path.items():
        messages = list(dict.fromkeys(m for m, _ in found))
        expects = [m for m in messages if m.startswith("expected ") and ", got " in m]
        if len(expects) > 1 and len(expects) == len(messages):
            # one value tried against each member of a union: say it once
            wanted = [m[len("expected "):m.rindex(", got ")] for m in expects]
            got = expects[0][expects[0].rindex(", got ") + 6:]
            messages = [f"expected {', '.join(wanted[:-1])} or {wanted[-1]}, got {got}"]
        out += [Problem(located.file, located.line(path), dotted(path), m) for m in messages]
    return sorted(set(out))


def _data_path(loc: tuple, data: Any, names_key: bool) -> Path_:
    """``loc`` without the elements pydantic adds (union tags, ``root``), following the data."""
    path: list[Any] = []
    node = data
    for element in loc:
        if isinstance(node, dict) and element in node:
            path.append(element)
            node = node[element]
        elif isinstance(node, list) and isinstance(element, int) and 0 <= element < len(node):
            path.append(element)
            node = node[element]
        elif names_key and isinstance(node, dict) and isinstance(element, str) \
                and element not in node and element == loc[-1]:
            path.append(element)         # a missing or unknown key: name it
            node = None
    return tuple(path)


def _describe(value: Any) -> str:
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    if value is None:
        return "nothing (null)"
    return repr(value)


def _message(err: Mapping[str, Any], path: Path_, model: type) -> str:
    kind, ctx, given = err["type"], err.get("ctx") or {}, err.get("input")
    annotation, bounds = _field_at(model, tuple(err["loc"]))
    if kind == "missing":
        return "required key is missing"
    if kind == "extra_forbidden":
        allowed = _allowed_keys(model, tuple(err["loc"])[:-1])
        key = path[-1] if path else "?"
        hint = suggest(key, allowed) or (f" (allowed: {', '.join(allowed)})" if allowed else "")
        return f"unknown key {key!r}{hint}"
    if kind in ("rule", "value_error", "assertion_error"):
        return str(err["msg"]).removeprefix("Value error, ").removeprefix("Assertion failed, ")
    if kind == "string_pattern_mismatch":
        what = PATTERN_WHAT.get(ctx.get("pattern", ""), "text matching " + str(ctx.get("pattern")))
        return f"expected {what}, got {_describe(given)}"
    if kind in ("string_type", "string_too_short"):
        quote = " (quote it)" if isinstance(given, (int, float, bool)) else ""
        shown = "an empty string" if given == "" else _describe(given)
        return f"expected text{quote}, got {shown}"
    if kind == "literal_error":
        expected = re.findall(r"'([^']*)'", str(ctx.get("expected", "")))
        return f"expected one of {', '.join(expected)}, got {_describe(given)}{suggest(str(given), expected)}"
    if kind in ("union_tag_invalid",):
        tags = re.findall(r"'([^']*)'", str(ctx.get("expected_tags", "")))
        return (f"expected a {ctx.get('discriminator', 'kind').strip(chr(39))} name (one of {', '.join(tags)}), "
                f"got {ctx.get('tag')!r}{suggest(str(ctx.get('tag')), tags)}")
    if kind == "union_tag_not_found":
        return f"expected a {str(ctx.get('discriminator', 'kind')).strip(chr(39))} name or mapping with it"
    if kind in ("int_type", "int_parsing", "int_from_float", "float_type", "float_parsing",
                "greater_than", "greater_than_equal", "less_than", "less_than_equal", "finite_number"):
        integer = annotation is int or kind.startswith("int")
        text = "an integer" if integer else "a number"
        words = [f"{op} {_num(v)}" for op, v in (bounds or [])]
        return f"expected {text}{' ' + ' and '.join(words) if words else ''}, got {_describe(given)}"
    if kind == "bool_type":
        return f"expected true or false, got {_describe(given)}"
    if kind in ("dict_type", "model_type", "model_attributes_type"):
        return f"expected a mapping, got {_describe(given)}"
    if kind in ("list_type", "tuple_type"):
        return f"expected a list, got {_describe(given)}"
    if kind == "too_short":
        return f"expected at least {ctx.get('min_length', 1)} entr{'y' if ctx.get('min_length', 1) == 1 else 'ies'}"
    return str(err["msg"])


def _num(value: Any) -> str:
    return str(int(value)) if float(value).is_integer() else str(value)


# -- following a loc through the model's types, for allowed keys and numeric bounds ----------
def _field_at(model: type, loc: tuple) -> tuple[Any, list[tuple[str, Any]]]:
    """The annotation at ``loc`` and its bounds ``[('>=', 0), ...]`` (best effort)."""
    tp: Any = model
    meta: list[tuple[str, Any]] = []
    for element in loc:
        tp, meta = _step(tp, element)
        if tp is None:
            return None, []
    for member in _members(tp):
        if member is not type(None):
            return member, _bounds(meta + _annotated_meta(tp))
    return None, []


def _annotated_meta(tp: Any) -> list:
    """Metadata of ``tp`` and of every Annotated member of a union inside it."""
    tp, meta = _unwrap(tp)
    if typing.get_origin(tp) in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        for arg in typing.get_args(tp):
            meta = meta + _annotated_meta(arg)
    return meta


def _allowed_keys(model: type, loc: tuple) -> list[str]:
    tp = model
    for element in loc:
        tp, _ = _step(tp, element)
        if tp is None:
            return []
    for candidate in _members(tp):
        if isinstance(candidate, type) and issubclass(candidate, BaseModel) \
                and not issubclass(candidate, RootModel):
            return [f.alias or name for name, f in candidate.model_fields.items()]
    return []


def _unwrap(tp: Any) -> tuple[Any, list]:
    meta: list = []
    while typing.get_origin(tp) is typing.Annotated:
        args = typing.get_args(tp)
        tp, meta = args[0], meta + list(args[1:])
    return tp, meta


def _members(tp: Any) -> list:
    tp, _ = _unwrap(tp)
    if typing.get_origin(tp) in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        out = []
        for arg in typing.get_args(tp):
            out += _members(arg)
        return out
    return [tp]


def _step(tp: Any, element: Any) -> tuple[Any, list]:
    for member in _members(tp):
        origin = typing.get_origin(member)
        if isinstance(member, type) and issubclass(member, BaseModel):
            fields = member.model_fields
            if issubclass(member, RootModel):
                return _step(fields["root"].annotation, element) if element != "root" else \
                    (fields["root"].annotation, list(fields["root"].metadata))
            by_alias = {f.alias or n: f for n, f in fields.items()}
            field = fields.get(element) or by_alias.get(element)
            if field is not None:
                return field.annotation, list(field.metadata)
            if isinstance(element, str) and _tag_member(tp, element) is not None:
                return _tag_member(tp, element), []
        elif origin is dict and isinstance(element, str):
            return typing.get_args(member)[1], []
        elif origin in (tuple, list) and isinstance(element, int):
            return typing.get_args(member)[0], []
    return None, []


def _tag_member(tp: Any, tag: str) -> Any:
    for member in _members(tp):
        if isinstance(member, type) and issubclass(member, BaseModel):
            for field in member.model_fields.values():
                if typing.get_origin(field.annotation) is typing.Literal and typing.get_args(field.annotation) == (tag,):
                    return member
    return None


def _bounds(meta: list) -> list[tuple[str, Any]]:
    out = []
    for m in meta:
        for attr, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            value = getattr(m, attr, None)
            if value is not None and not callable(value):
                out.append((op, value))
        for inner in getattr(m, "metadata", []) or []:
            out += _bounds([inner])
    return out

