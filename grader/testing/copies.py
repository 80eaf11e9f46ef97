"""Disguised copies of a submission, as a student who copied would make them: every identifier the
code defines renamed, comments dropped, the layout changed (token spacing, indentation, blank
lines), behaviour unchanged. For the similarity tests and benchmark (grader.similarity), which must
find such copies by source and by behaviour.

``disguise_python(text, seed)`` rewrites one Python module; ``disguise_tree(src, dest, seed)``
copies a submission folder, disguising every ``.py`` file it holds (other files are copied as
they are). Names that other files may refer to stay: ``main`` (setup.py's entry points), dunder
names, imported names, attributes of objects other than ``self`` and keyword arguments.
"""

from __future__ import annotations

import ast
import builtins
import io
import random
import shutil
import tokenize
from pathlib import Path

KEEP = {"self", "cls", "main", "args", "kwargs"} | set(dir(builtins))


def _defined_names(tree: ast.AST) -> set[str]:
    """Names the module itself defines (functions, classes, parameters, variables, self.attrs)."""
    imported: set[str] = set()
    names: set[str] = set()
    keywords: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            imported |= {(a.asname or a.name).split(".")[0] for a in node.names}
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store)
              and isinstance(node.value, ast.Name) and node.value.id == "self"):
            names.add(node.attr)
        elif isinstance(node, ast.keyword) and node.arg:
            keywords.add(node.arg)
    return {n for n in names - imported - keywords - KEEP if not n.startswith("__")}


def _spans(tree: ast.AST, text: str, rename: dict[str, str]) -> list[tuple[int, int, int, str]]:
    """(line, start col, end col, new name) of every occurrence to rename."""
    lines = text.splitlines(keepends=True)
    out = []

    def add(line: int, start: int, name: str) -> None:
        if lines[line - 1][start:start + len(name)] == name:
            out.append((line, start, start + len(name), rename[name]))

    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id in rename:
            add(node.lineno, node.col_offset, node.id)
        elif isinstance(node, ast.arg) and node.arg in rename:
            add(node.lineno, node.col_offset, node.arg)
        elif (isinstance(node, ast.Attribute) and node.attr in rename and isinstance(node.value, ast.Name)
              and node.value.id == "self" and node.end_lineno is not None and node.end_col_offset is not None):
            add(node.end_lineno, node.end_col_offset - len(node.attr), node.attr)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.name in rename:
            line = lines[node.lineno - 1]
            keyword = "class " if isinstance(node, ast.ClassDef) else "def "
            at = line.find(keyword, node.col_offset)
            if at >= 0:
                add(node.lineno, at + len(keyword), node.name)
    return sorted(set(out), reverse=True)


NO_SPACE_BEFORE = {".", ",", ")", "]", "}", ":", "(", "["}
NO_SPACE_AFTER = {".", "(", "[", "{", "~"}
OPERATORS = {"=", "==", "!=", "<", ">", "<=", ">=", "+", "-", "*", "/", "//", "%", "**", "+=", "-=", "*=",
             "/=", "->", "|", "&"}


def _respace(text: str, rng: random.Random) -> str:
    """Comments dropped, each statement on one line with its tokens spaced anew (operators with or
    without spaces around them), indentation of 2 or 3 spaces, no blank lines."""
    width = rng.choice((2, 3))
    tight = rng.random() < 0.5            # "a=b+1" or "a = b + 1"
    lines: list[str] = []
    depth, line, prev = 0, "", None
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        kind, string = tok.type, tok.string
        if kind in (tokenize.COMMENT, tokenize.NL, tokenize.ENCODING, tokenize.ENDMARKER):
            continue
        if kind == tokenize.INDENT:
            depth += 1
            continue
        if kind == tokenize.DEDENT:
            depth -= 1
            continue
        if kind == tokenize.NEWLINE:
            lines.append(" " * (width * depth) + line)
            line, prev = "", None
            continue
        if prev is None:
            sep = ""
        elif string in NO_SPACE_BEFORE or prev.string in NO_SPACE_AFTER:
            sep = ""
        elif (string in OPERATORS or prev.string in OPERATORS) and tight and string != "->":
            sep = ""
        elif prev.string in (",", ":"):
            sep = " "
        else:
            sep = " "
        if string in ("(", "[") and prev is not None and prev.type == tokenize.NAME and prev.string in (
                "if", "in", "and", "or", "not", "return", "elif", "while", "for", "is", "else", "import", "yield",
                "assert", "except", "with", "as", "lambda", "del", "from", "print"):
            sep = " "
        line += sep + string
        prev = tok
    return "\n".join(lines) + "\n"


def disguise_python(text: str, seed: int = 0) -> str:
    """The module with its own identifiers renamed and its layout changed; same behaviour."""
    rng = random.Random(seed)
    tree = ast.parse(text)
    names = sorted(_defined_names(tree))
    words = ["val", "tmp", "data", "obj", "item", "thing", "res", "var", "q", "z"]
    rename = {n: f"{rng.choice(words)}_{i}{rng.randint(10, 99)}" for i, n in enumerate(names)}
    lines = text.splitlines(keepends=True)
    for line, start, end, new in _spans(tree, text, rename):
        row = lines[line - 1]
        lines[line - 1] = row[:start] + new + row[end:]
    renamed = "".join(lines)
    out = _respace(renamed, rng)
    ast.parse(out)                  # still Python
    return out


def disguise_tree(src: Path, dest: Path, seed: int = 0) -> Path:
    """Copy ``src`` to ``dest`` with every ``.py`` file disguised (the same seed per file name)."""
    shutil.copytree(src, dest)
    for i, path in enumerate(sorted(Path(dest).rglob("*.py"))):
        if path.name in ("setup.py", "__init__.py"):
            continue
        path.write_text(disguise_python(path.read_text(encoding="utf-8"), seed * 1000 + i), encoding="utf-8")
    return Path(dest)


__all__ = ["disguise_python", "disguise_tree"]
