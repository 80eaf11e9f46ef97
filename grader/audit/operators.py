"""The mutation operators of ``grader.audit.mutate``, one generator per operator.

Each maker walks a parsed file in source order and yields :class:`Edit`: the node whose source
span is replaced, the replacement text and a one-line description. Spans are computed from the
AST's UTF-8 byte columns (:class:`Source`), so a mutant changes exactly that span and keeps the
rest of the file (comments, formatting) as written. What each operator does, and what is never
mutated, is in ``grader.audit.mutate``'s docstring.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from typing import Callable, Iterator

_NAMED_CALLS = {"create_publisher": 1, "create_subscription": 1, "create_service": 1, "create_client": 1,
                "ActionServer": 2, "ActionClient": 2}
_NAME_KEYWORDS = {"topic", "srv_name", "action_name", "service_name", "name"}
_QOS_POSITION = {"create_publisher": 2, "create_subscription": 3}
_SKIP_KEYWORDS = {"qos_profile", "num_threads"}
_TIMER_CALLS = {"create_timer": "period", "create_rate": "frequency", "Rate": "frequency"}
_TIMER_KEYWORDS = {"timer_period_sec", "frequency", "hz"}
_LOG_METHODS = {"debug", "info", "warn", "warning", "error", "fatal"}
_ATOMS = (ast.Name, ast.Attribute, ast.Call, ast.Subscript, ast.List, ast.Tuple)


@dataclass
class Edit:
    """One change: replace ``node``'s span by ``text`` (a whole statement by ``pass``)."""

    operator: str
    node: ast.AST
    text: str                 # replacement source for the node's span
    description: str
    statement: bool = False   # replace a whole statement (keeps indentation)


class Source:
    """Byte-accurate spans of a file (ast offsets are UTF-8 byte columns)."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.lines = text.splitlines(keepends=True)
        self.starts = [0]
        for line in self.lines:
            self.starts.append(self.starts[-1] + len(line))

    def offset(self, line: int, col_bytes: int) -> int:
        raw = self.lines[line - 1].encode("utf-8")[:col_bytes]
        return self.starts[line - 1] + len(raw.decode("utf-8", errors="replace"))

    def span(self, node: ast.AST) -> tuple[int, int]:
        return (self.offset(node.lineno, node.col_offset), self.offset(node.end_lineno, node.end_col_offset))

    def segment(self, node: ast.AST) -> str:
        a, b = self.span(node)
        return self.text[a:b]


def parents_of(tree: ast.AST) -> dict[ast.AST, ast.AST]:
    """Each node's parent (ast nodes do not know it)."""
    out: dict[ast.AST, ast.AST] = {}
    for node in ast.walk(tree):
        for child in ast.iter_child_nodes(node):
            out[child] = node
    return out


def scope_of(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> str:
    """``Class.method`` enclosing ``node`` (part of a mutant's id, so ids survive moved lines)."""
    names = []
    cur = parents.get(node)
    while cur is not None:
        if isinstance(cur, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.append(cur.name)
        cur = parents.get(cur)
    return ".".join(reversed(names)) or "<module>"


def _walk(tree: ast.AST) -> Iterator[ast.AST]:
    """Nodes in source order (depth first), so mutants come out in reading order."""
    yield tree
    for child in ast.iter_child_nodes(tree):
        yield from _walk(child)


def _call_name(call: ast.Call) -> str:
    f = call.func
    return f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""


def unmutable(tree: ast.Module, parents: dict[ast.AST, ast.AST]) -> set[ast.AST]:
    """Nodes whose change cannot matter or cannot be read (see the module docstring)."""
    out: set[ast.AST] = set()

    def drop(node: ast.AST | None) -> None:
        if node is not None:
            out.update(ast.walk(node))

    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            drop(node)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Module)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                drop(body[0])
            if not isinstance(node, (ast.ClassDef, ast.Module)):
                for arg in node.args.args + node.args.kwonlyargs + node.args.posonlyargs:
                    drop(arg.annotation)
                drop(node.returns)
        elif isinstance(node, ast.AnnAssign):
            drop(node.annotation)
        elif isinstance(node, ast.ExceptHandler):
            drop(node.type)
        elif isinstance(node, ast.If) and _main_guard(node):
            for stmt in node.body:
                drop(stmt)
        elif isinstance(node, ast.Subscript):
            drop(node.slice)
        elif isinstance(node, ast.Call):
            name = _call_name(node)
            for kw in node.keywords:
                if kw.arg in _SKIP_KEYWORDS:
                    drop(kw.value)
            qos = _QOS_POSITION.get(name)
            if qos is not None and len(node.args) > qos:
                drop(node.args[qos])
    return out


def _main_guard(node: ast.If) -> bool:
    """``if __name__ == "__main__":``: dead code under ``ros2 run`` (console scripts call main)."""
    test = node.test
    return isinstance(test, ast.Compare) and isinstance(test.left, ast.Name) and test.left.id == "__name__"


def _number(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and type(node.value) in (int, float)


def _paren(node: ast.AST) -> str:
    text = ast.unparse(node)
    atom = isinstance(node, _ATOMS) or (_number(node) and node.value >= 0)
    return text if atom else f"({text})"


def _fmt(value: float | int) -> str:
    return repr(value)


def _in_timer_arg(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> bool:
    """Part of a timer period or rate argument (``change_timer_period`` owns those)."""
    child, cur = node, parents.get(node)
    while cur is not None and not isinstance(cur, ast.stmt):
        if isinstance(cur, ast.Call) and _call_name(cur) in _TIMER_CALLS:
            return (bool(cur.args) and child is cur.args[0]) or any(
                kw.value is child and kw.arg in _TIMER_KEYWORDS for kw in cur.keywords)
        if isinstance(cur, ast.keyword):
            call = parents.get(cur)
            if isinstance(call, ast.Call) and _call_name(call) in _TIMER_CALLS and cur.arg in _TIMER_KEYWORDS:
                return True
        child, cur = cur, parents.get(cur)
    return False


# ------------------------------------------------------------------------------ operators
Maker = Callable[[ast.Module, dict, set, Source], Iterator[Edit]]


def _flip_sign(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    for node in _walk(tree):
        if node in skip:
            continue
        if _in_timer_arg(node, parents):
            continue
        if _number(node) and node.value != 0:
            parent = parents.get(node)
            if isinstance(parent, ast.UnaryOp) and isinstance(parent.op, (ast.USub, ast.UAdd)):
                continue        # -c: dropping the minus is the same mutant
            yield Edit("flip_sign", node, _fmt(-node.value),
                        f"{src.segment(node)} -> {_fmt(-node.value)}{_context(node, parents, src)}")
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            yield Edit("flip_sign", node, _paren(node.operand), f"drop the minus of {src.segment(node)}")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub)) and _numeric(node):
            text = f"{src.segment(node.left)} {'-' if isinstance(node.op, ast.Add) else '+'} {_right(node, src)}"
            yield Edit("flip_sign", node, text, f"{'+ -> -' if isinstance(node.op, ast.Add) else '- -> +'} in "
                        f"{_short(src.segment(node))}")
        elif isinstance(node, ast.AugAssign) and isinstance(node.op, (ast.Add, ast.Sub)) \
                and not _stringy(node.value):
            op = "-=" if isinstance(node.op, ast.Add) else "+="
            text = f"{src.segment(node.target)} {op} {src.segment(node.value)}"
            yield Edit("flip_sign", node, text, f"{'+=' if op == '-=' else '-='} -> {op} "
                        f"in {_short(src.segment(node))}")


def _context(node: ast.AST, parents: dict, src: Source) -> str:
    """`` in `<the expression around node>` `` (which of several equal constants changed)."""
    cur = parents.get(node)
    while isinstance(cur, ast.UnaryOp):
        cur = parents.get(cur)
    if cur is None or isinstance(cur, (ast.stmt, ast.keyword)) or not hasattr(cur, "lineno"):
        return ""
    return f" in `{_short(src.segment(cur))}`"


def _right(node: ast.BinOp, src: Source) -> str:
    """The right operand, parenthesised when the new operator would bind it differently."""
    text = src.segment(node.right)
    if isinstance(node.right, ast.BinOp) and isinstance(node.right.op, (ast.Add, ast.Sub)):
        return f"({text})"
    return text


def _stringy(node: ast.AST) -> bool:
    return isinstance(node, ast.JoinedStr) or (isinstance(node, ast.Constant) and isinstance(node.value, (str, bytes)))


def _numeric(node: ast.BinOp) -> bool:
    """An addition that is (as far as the source shows) arithmetic, not string or list joining."""
    for side in (node.left, node.right):
        if _stringy(side) or isinstance(side, (ast.List, ast.Tuple, ast.ListComp, ast.Dict)):
            return False
        if isinstance(side, ast.BinOp) and isinstance(side.op, ast.Add) and not _numeric(side):
            return False
    return True


def _scale_constant(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    for node in _walk(tree):
        if node in skip or not _number(node) or node.value == 0 or _in_timer_arg(node, parents):
            continue
        new = node.value * 2
        yield Edit("scale_constant", node, _fmt(new),
                    f"{src.segment(node)} -> {_fmt(new)}{_context(node, parents, src)}")


def _kind(node: ast.AST, keyword: bool = False) -> str | None:
    """What a swapped value is, or None for values whose swap only breaks start-up (names of
    things, classes, ``self``, callbacks given by keyword, constructors in a list)."""
    if _number(node) or (isinstance(node, ast.UnaryOp) and _number(node.operand)):
        return "number"
    if isinstance(node, ast.Constant):
        return None
    if isinstance(node, ast.Name):
        return None if node.id == "self" or node.id[:1].isupper() else "name"
    if isinstance(node, ast.Attribute):
        return None if keyword else "attribute"
    if isinstance(node, ast.Call):
        name = _call_name(node)
        return None if name[:1].isupper() else "call"
    if isinstance(node, (ast.Subscript, ast.BinOp, ast.UnaryOp)):
        return type(node).__name__
    return None


def _swap_args(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    for node in _walk(tree):
        if node in skip:
            continue
        groups: list[tuple[list[ast.AST], str, bool]] = []
        if isinstance(node, ast.Call):
            groups.append(([a for a in node.args], "arguments", False))
            groups.append(([k.value for k in node.keywords if k.arg is not None], "keyword values", True))
        elif isinstance(node, (ast.List, ast.Tuple)) and isinstance(node.ctx, ast.Load):
            groups.append((list(node.elts), "elements", False))
        for values, what, keyword in groups:
            for a, b in zip(values, values[1:]):
                if a in skip or b in skip:
                    continue
                kind = _kind(a, keyword)
                if kind is None or kind != _kind(b, keyword) or src.segment(a) == src.segment(b):
                    continue
                yield Edit("swap_args", _Pair(a, b), f"{src.segment(b)}{_between(src, a, b)}{src.segment(a)}",
                            f"swap the {what} {_short(src.segment(a))} and {_short(src.segment(b))}")


class _Pair(ast.AST):
    """Span covering two sibling nodes (from the first's start to the second's end)."""

    def __init__(self, a: ast.AST, b: ast.AST) -> None:
        super().__init__()
        self.lineno, self.col_offset = a.lineno, a.col_offset
        self.end_lineno, self.end_col_offset = b.end_lineno, b.end_col_offset
        self.first = a


def _between(src: Source, a: ast.AST, b: ast.AST) -> str:
    return src.text[src.span(a)[1]:src.span(b)[0]]


def _ros_name(text: str) -> bool:
    return bool(re.fullmatch(r"~?/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*", text))


def _rename_topic(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    names: list[ast.Constant] = []
    for node in _walk(tree):
        if isinstance(node, ast.Call) and _call_name(node) in _NAMED_CALLS:
            pos = _NAMED_CALLS[_call_name(node)]
            cands = node.args[pos:pos + 1] + [k.value for k in node.keywords if k.arg in _NAME_KEYWORDS]
            names += [c for c in cands if isinstance(c, ast.Constant) and isinstance(c.value, str)
                      and _ros_name(c.value)]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.startswith("/") \
                and _ros_name(node.value) and node not in skip:
            names.append(node)
    seen: set[int] = set()
    for node in sorted(names, key=lambda n: (n.lineno, n.col_offset)):
        if id(node) in seen or node in skip:
            continue
        seen.add(id(node))
        new = node.value + "_renamed"
        yield Edit("rename_topic", node, repr(new), f"rename {node.value!r} to {new!r}")


def _in_handler(node: ast.AST, parents: dict) -> bool:
    child, cur = node, parents.get(node)
    while cur is not None:
        if isinstance(cur, ast.ExceptHandler):
            return True
        if isinstance(cur, ast.Try) and child in cur.finalbody:
            return True
        if isinstance(cur, (ast.FunctionDef, ast.AsyncFunctionDef)):
            return False
        child, cur = cur, parents.get(cur)
    return False


def _drop_call(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    for node in _walk(tree):
        if not (isinstance(node, ast.Expr) and isinstance(node.value, ast.Call)) or node in skip \
                or _in_handler(node, parents):
            continue
        call = node.value
        func = call.func
        if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Call) \
                and _call_name(func.value) == "super" and func.attr == "__init__":
            continue
        name = _call_name(call)
        kind = "publish" if name == "publish" else "log" if (
            name in _LOG_METHODS and isinstance(func, ast.Attribute) and isinstance(func.value, ast.Call)
            and _call_name(func.value) == "get_logger") else "print" if name == "print" else "call"
        yield Edit("drop_call", node, "pass", f"drop the {kind} {_short(src.segment(node))}", statement=True)


def _is_pi(node: ast.AST) -> bool:
    return (isinstance(node, ast.Name) and node.id == "pi") or (
        isinstance(node, ast.Attribute) and node.attr == "pi")


def _is_two_pi(node: ast.AST) -> bool:
    if isinstance(node, ast.Name) and node.id == "tau" or isinstance(node, ast.Attribute) and node.attr == "tau":
        return True
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
        sides = (node.left, node.right)
        return any(_number(s) and s.value == 2 for s in sides) and any(_is_pi(s) for s in sides)
    return _number(node) and abs(float(node.value) - 6.283185307179586) < 1e-3


def _mentions_pi(node: ast.AST) -> bool:
    return any(_is_pi(n) or _is_two_pi(n) or (_number(n) and abs(abs(float(n.value)) - 3.14159) < 1e-2)
               for n in ast.walk(node))


def _remove_angle_wrap(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    for node in _walk(tree):
        if node in skip:
            continue
        if isinstance(node, ast.Call) and _call_name(node) in ("atan2", "arctan2") and len(node.args) == 2:
            s, c = node.args
            if isinstance(s, ast.Call) and isinstance(c, ast.Call) and _call_name(s) == "sin" \
                    and _call_name(c) == "cos" and len(s.args) == 1 and len(c.args) == 1 \
                    and ast.dump(s.args[0]) == ast.dump(c.args[0]):
                yield Edit("remove_angle_wrap", node, _paren(s.args[0]),
                            f"unwrap: {_short(src.segment(node))} -> {_short(src.segment(s.args[0]))}")
        elif isinstance(node, ast.Call) and _call_name(node) == "remainder" and len(node.args) == 2 \
                and _is_two_pi(node.args[1]):
            yield Edit("remove_angle_wrap", node, _paren(node.args[0]),
                        f"unwrap: {_short(src.segment(node))} -> {_short(src.segment(node.args[0]))}")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mod) and _is_two_pi(node.right):
            yield Edit("remove_angle_wrap", node, _paren(node.left),
                        f"unwrap: {_short(src.segment(node))} -> {_short(src.segment(node.left))}")
        elif isinstance(node, (ast.While, ast.If)) and isinstance(node.test, (ast.Compare, ast.BoolOp)) \
                and _mentions_pi(node.test) and any(
                    isinstance(s, (ast.AugAssign, ast.Assign)) and _mentions_pi(s.value) for s in node.body):
            yield Edit("remove_angle_wrap", node, "pass",
                        f"unwrap: drop `{_short(src.segment(node).splitlines()[0])}`", statement=True)


def _change_timer_period(tree: ast.Module, parents: dict, skip: set, src: Source) -> Iterator[Edit]:
    for node in _walk(tree):
        if not isinstance(node, ast.Call) or _call_name(node) not in _TIMER_CALLS:
            continue
        kind = _TIMER_CALLS[_call_name(node)]
        arg = node.args[0] if node.args else next(
            (k.value for k in node.keywords if k.arg in _TIMER_KEYWORDS), None)
        if arg is None or arg in skip:
            continue
        text = src.segment(arg)
        for factor, effect in ((2, "slower"), (0.5, "faster")):
            scale = factor if kind == "period" else 1 / factor
            if _number(arg):
                new = _fmt(arg.value * scale)
            else:
                new = f"({text}) * {_fmt(scale)}"
            yield Edit("change_timer_period", arg, new,
                        f"{'period' if kind == 'period' else 'rate'} {text} -> {new} (twice as {effect[:-2]})")


MAKERS: dict[str, Maker] = {
    "flip_sign": _flip_sign, "scale_constant": _scale_constant, "swap_args": _swap_args,
    "rename_topic": _rename_topic, "drop_call": _drop_call, "remove_angle_wrap": _remove_angle_wrap,
    "change_timer_period": _change_timer_period,
}


def _short(text: str, limit: int = 60) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit - 3] + "..."

