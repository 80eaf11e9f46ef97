"""Decode CDR payloads into flat columns, using only the ``ros2msg`` text stored in the bag.

Two paths, chosen per type:

* fixed layout (no strings, no sequences — e.g. ``turtlesim/msg/Pose``, ``geometry_msgs/msg/Twist``):
  every message has the same byte layout, so all payloads of a topic are gathered into one
  ``(N, size)`` uint8 matrix and viewed through a numpy structured dtype. No per-message Python.
* everything else: a per-type decoder generated as Python source (``struct.unpack_from`` with
  CDR alignment) and compiled once, producing one flat dict per message.

Column names follow docs/ARCHITECTURE.md: nested fields joined with dots (``linear.x``), array
elements as ``data[0]`` with ``data.len``; arrays longer than :data:`MAX_EXPANDED` stay one
column of numpy arrays (``data``) so an image never becomes a million columns.

Why not rosbags' ``deserialize_cdr``, measured: a one-hour 225,000-message Pose bag loads into
a DataFrame in 0.057 s through the fixed-layout path, against 0.96 s for rosbags' AnyReader
deserialising the same messages into objects (17x, before any flattening into columns);
for variable types (50,000 ``rcl_interfaces/msg/Log``) the generated decoders take 0.29 s for
the finished DataFrame, rosbags 0.30 s for the objects alone. rosbags still decodes every bag in
the conformance check (:mod:`grader.bag.conformance`).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from grader.bag.msgdefs import PRIMITIVES, SEPARATOR, normalize_type, split_type

#: arrays up to this many elements are spread into ``name[i]`` columns
MAX_EXPANDED = 256

_SIZES = {"bool": 1, "byte": 1, "char": 1, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
          "int32": 4, "uint32": 4, "float32": 4, "int64": 8, "uint64": 8, "float64": 8}
_STRUCT = {"bool": "?", "byte": "B", "char": "B", "int8": "b", "uint8": "B", "int16": "h",
           "uint16": "H", "int32": "i", "uint32": "I", "float32": "f", "int64": "q",
           "uint64": "Q", "float64": "d"}
_NUMPY = {"bool": "?", "byte": "u1", "char": "u1", "int8": "i1", "uint8": "u1", "int16": "i2",
          "uint16": "u2", "int32": "i4", "uint32": "u4", "float32": "f4", "int64": "i8",
          "uint64": "u8", "float64": "f8"}
_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_TYPE_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*){0,2}$")


class DefinitionError(ValueError):
    """A stored message definition cannot be parsed or lacks a referenced type."""


@dataclass(frozen=True)
class Field:
    name: str
    type: str           # primitive name or normalised pkg/kind/Name
    array: str          # "" | "fixed" | "bounded" | "seq"
    count: int = 0      # fixed length or upper bound

    @property
    def primitive(self) -> bool:
        return self.type in PRIMITIVES


Types = dict[str, tuple[Field, ...]]


def parse_definition(text: str, type_name: str) -> Types:
    """Split a complete ros2msg definition into ``{type: fields}`` (constants dropped)."""
    root = normalize_type(type_name)
    out: Types = {}
    current = root
    chunk: list[str] = []

    def close() -> None:
        out[current] = _parse_fields("\n".join(chunk), split_type(current)[0], current)

    for line in text.splitlines():
        if line.strip() == SEPARATOR:
            close()
            chunk = []
            current = ""
            continue
        if not current and line.startswith("MSG:"):
            current = normalize_type(line[4:].strip())
            continue
        chunk.append(line)
    close()
    return out


def _parse_fields(text: str, package: str, owner: str) -> tuple[Field, ...]:
    fields: list[Field] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split(None, 2)
        if len(parts) < 2:
            raise DefinitionError(f"cannot parse line {raw!r} of {owner}")
        typ, name = parts[0], parts[1]
        rest = parts[2] if len(parts) > 2 else ""
        if "=" in name or rest.startswith("="):
            continue   # constant
        m = re.match(r"^([A-Za-z][A-Za-z0-9_/]*)(?:<=\d+)?(?:\[(<=)?(\d*)\])?$", typ)
        if not m or not _NAME_RE.match(name):
            raise DefinitionError(f"cannot parse field {raw.strip()!r} of {owner}")
        base = m.group(1)
        if base not in PRIMITIVES:
            base = normalize_type(base, package)
            if not _TYPE_RE.match(base):
                raise DefinitionError(f"bad type name {base!r} in {owner}")
        if m.group(0).endswith("]"):
            if m.group(2):
                array, count = "bounded", int(m.group(3))
            elif m.group(3):
                array, count = "fixed", int(m.group(3))
            else:
                array, count = "seq", 0
        else:
            array, count = "", 0
        fields.append(Field(name, base, array, count))
    if not fields:
        # rosidl gives empty structures one dummy byte so that CDR has something to send
        fields.append(Field("structure_needs_at_least_one_member", "uint8", ""))
    return tuple(fields)


def _fields(types: Types, t: str) -> tuple[Field, ...]:
    try:
        return types[t]
    except KeyError:
        raise DefinitionError(f"the stored definition lacks the type {t}") from None


# --------------------------------------------------------------------------------------------
# fixed layout

@dataclass(frozen=True)
class Leaf:
    column: str
    dtype: str      # numpy type code without byte order
    offset: int     # from the start of the CDR body (after the 4-byte encapsulation header)


def is_fixed(types: Types, t: str) -> bool:
    """True when every message of the type has the same layout (and no huge array to collapse)."""
    for f in _fields(types, t):
        if f.type in ("string", "wstring") or f.array in ("bounded", "seq"):
            return False
        if f.array == "fixed" and f.count > MAX_EXPANDED:
            return False
        if not f.primitive and not is_fixed(types, f.type):
            return False
    return True


def fixed_layout(types: Types, t: str) -> tuple[list[Leaf], int]:
    """Leaves with their byte offsets, and the body size, of a fixed-layout type."""
    leaves: list[Leaf] = []

    def walk(typ: str, pos: int, prefix: str) -> int:
        for f in _fields(types, typ):
            col = prefix + f.name
            n = f.count if f.array == "fixed" else 1
            for i in range(n):
                name = f"{col}[{i}]" if f.array else col
                if f.primitive:
                    size = _SIZES[f.type]
                    pos += -pos % size
                    leaves.append(Leaf(name, _NUMPY[f.type], pos))
                    pos += size
                else:
                    pos = walk(f.type, pos, name + ".")
        return pos

    size = walk(t, 0, "")
    return leaves, size


def decode_fixed(matrix: np.ndarray, leaves: list[Leaf], little: bool = True) -> dict[str, np.ndarray]:
    """Columns from an ``(N, body size)`` uint8 matrix of CDR bodies."""
    order = "<" if little else ">"
    names, formats, offsets = [], [], []
    for i, leaf in enumerate(leaves):
        names.append(f"f{i}")
        formats.append(order + leaf.dtype if leaf.dtype not in ("?", "u1", "i1") else leaf.dtype)
        offsets.append(leaf.offset)
    dt = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                   "itemsize": matrix.shape[1]})
    rec = np.ascontiguousarray(matrix).view(dt).reshape(-1)
    out = {}
    for i, leaf in enumerate(leaves):
        col = rec[f"f{i}"]
        # one dtype per kind, whichever path decoded it: float64, int64 (uint64 kept), bool
        kind = col.dtype.kind
        target = (np.float64 if kind == "f" else np.bool_ if kind == "b"
                  else np.uint64 if col.dtype == np.dtype(">u8") or col.dtype == np.dtype("<u8")
                  else np.int64)
        out[leaf.column] = col.astype(target)
    return out


def array_lengths(types: Types, t: str) -> dict[str, int]:
    """``name.len`` columns of the fixed arrays of a fixed-layout type (constant per type)."""
    out: dict[str, int] = {}

    def walk(typ: str, prefix: str) -> None:
        for f in _fields(types, typ):
            col = prefix + f.name
            if f.array == "fixed":
                out[col + ".len"] = f.count
            if not f.primitive:
                for i in range(f.count if f.array == "fixed" else 1):
                    walk(f.type, f"{col}[{i}]." if f.array else col + ".")

    walk(t, "")
    return out


# --------------------------------------------------------------------------------------------
# generated per-message decoders

def _gen(types: Types, root: str, little: bool) -> str:
    e = "<" if little else ">"
    lines = ["def _make(unpack_from, np, MAX):"]
    done: set[str] = set()
    order: list[str] = []

    def visit(t: str) -> None:
        if t in done:
            return
        done.add(t)
        for f in _fields(types, t):
            if not f.primitive:
                visit(f.type)
        order.append(t)

    visit(root)
    fn = {t: "d_" + re.sub(r"\W", "_", t) for t in order}
    for t in order:
        body = [f"  def {fn[t]}(b, p, row, pre):"]
        for f in _fields(types, t):
            key = repr(f.name)
            if f.array:
                if f.array == "fixed":
                    body.append(f"    n = {f.count}")
                else:
                    body.append("    p += -p & 3")
                    body.append(f"    n = unpack_from('{e}I', b, p)[0]; p += 4")
                body.append(f"    row[pre + {key} + '.len'] = n")
                if f.primitive and f.type not in ("string", "wstring"):
                    size = _SIZES[f.type]
                    if size > 1:
                        body.append(f"    if n: p += -p & {size - 1}")
                    body.append(f"    vals = unpack_from('{e}%d{_STRUCT[f.type]}' % n, b, p); p += n * {size}")
                    body.append("    if n <= MAX:")
                    body.append(f"      for i, v in enumerate(vals): row[f'{{pre}}{f.name}[{{i}}]'] = v")
                    body.append(f"    else: row[pre + {key}] = np.array(vals)")
                elif f.type == "string":
                    body.append("    vals = []")
                    body.append("    for i in range(n):")
                    body.append("      p += -p & 3")
                    body.append(f"      m = unpack_from('{e}I', b, p)[0]; p += 4")
                    body.append("      vals.append(bytes(b[p:p + m - 1]).decode('utf-8', 'replace')); p += m")
                    body.append("    if n <= MAX:")
                    body.append(f"      for i, v in enumerate(vals): row[f'{{pre}}{f.name}[{{i}}]'] = v")
                    body.append(f"    else: row[pre + {key}] = vals")
                elif f.type == "wstring":
                    body.append("    raise ValueError('wstring fields are not supported')")
                else:
                    body.append("    for i in range(n):")
                    body.append(f"      p = {fn[f.type]}(b, p, row, f'{{pre}}{f.name}[{{i}}].')")
            elif f.type == "string":
                body.append("    p += -p & 3")
                body.append(f"    m = unpack_from('{e}I', b, p)[0]; p += 4")
                body.append(f"    row[pre + {key}] = bytes(b[p:p + m - 1]).decode('utf-8', 'replace'); p += m")
            elif f.type == "wstring":
                body.append("    raise ValueError('wstring fields are not supported')")
            elif f.primitive:
                size = _SIZES[f.type]
                if size > 1:
                    body.append(f"    p += -p & {size - 1}")
                body.append(f"    row[pre + {key}] = unpack_from('{e}{_STRUCT[f.type]}', b, p)[0]; p += {size}")
            else:
                body.append(f"    p = {fn[f.type]}(b, p, row, pre + {key} + '.')")
        body.append("    return p")
        lines += body
    lines.append(f"  return {fn[root]}")
    return "\n".join(lines)


@lru_cache(maxsize=256)
def _compiled(text: str, type_name: str, little: bool):
    types = parse_definition(text, type_name)
    src = _gen(types, normalize_type(type_name), little)
    ns: dict = {}
    exec(compile(src, f"<cdr decoder {type_name}>", "exec"), ns)  # noqa: S102 - names validated
    return ns["_make"](struct.unpack_from, np, MAX_EXPANDED)


def message_decoder(text: str, type_name: str, little: bool = True):
    """``decode(body: memoryview) -> dict`` for one message body (after the 4-byte header)."""
    fn = _compiled(text, type_name, little)

    def decode(body) -> dict:
        row: dict = {}
        fn(body, 0, row, "")
        return row

    return decode


def scalar_columns(types: Types, t: str) -> list[str]:
    """Columns that every message of the type has (non-array leaves): for empty topics."""
    cols: list[str] = []

    def walk(typ: str, prefix: str) -> None:
        for f in _fields(types, typ):
            if f.array:
                cols.append(prefix + f.name + ".len")
            elif f.primitive:
                cols.append(prefix + f.name)
            else:
                walk(f.type, prefix + f.name + ".")

    walk(t, "")
    return cols
