"""No circle between grader's modules, imports inside functions and under TYPE_CHECKING included.

A function-local import hides an arrow from a reader of the module's head, not from the code:
two modules that import each other anywhere are one unit that cannot be understood, tested or
moved apart. The scan is of the source (``ast``), so it sees every import whether it runs or not.
"""

from __future__ import annotations

import ast
from pathlib import Path

GRADER = Path(__file__).resolve().parents[2] / "grader"


def _module_name(path: Path) -> str:
    parts = path.relative_to(GRADER.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, known: set[str]) -> set[str]:
    """The grader modules ``path`` imports anywhere: ``from grader.x import y`` names grader.x.y
    when that is a module, else grader.x."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name in known}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and node.module.startswith("grader"):
            subs = {f"{node.module}.{a.name}" for a in node.names} & known
            out |= subs if subs else ({node.module} & known)
    return out


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected groups of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return groups


def test_no_module_of_grader_imports_one_that_imports_it_back() -> None:
    files = {_module_name(p): p for p in GRADER.rglob("*.py")}
    known = set(files)
    graph = {name: _imports(path, known) - {name} for name, path in files.items()}
    assert _cycles(graph) == []


def test_the_scan_finds_a_circle_made_by_a_function_local_import(tmp_path: Path) -> None:
    """The check can fail: two modules that import each other, one of them inside a function."""
    graph = {"grader.a": {"grader.b"}, "grader.b": {"grader.a"}, "grader.c": {"grader.a"}}
    assert _cycles(graph) == [["grader.a", "grader.b"]]
    (tmp_path / "x.py").write_text("def f():\n    from grader.grading.pipeline import grade_submission\n")
    assert _imports(tmp_path / "x.py", {"grader.grading.pipeline"}) == {"grader.grading.pipeline"}


def _load_time_imports(path: Path, known: set[str]) -> set[str]:
    """What importing ``path`` loads at once: its imports outside functions and ``TYPE_CHECKING``,
    each with the packages Python imports first (``grader.a.b`` loads ``grader.a``)."""
    out: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                out.update(_imports_of(child, known))
            visit(child)

    visit(ast.parse(path.read_text()))
    return {p for name in out for p in _packages(name) if p in known}


def _imports_of(node: ast.Import | ast.ImportFrom, known: set[str]) -> set[str]:
    if isinstance(node, ast.Import):
        return {a.name for a in node.names if a.name in known}
    if not (node.module and node.level == 0 and node.module.startswith("grader")):
        return set()
    subs = {f"{node.module}.{a.name}" for a in node.names} & known
    return subs | ({node.module} & known)


def _packages(name: str) -> list[str]:
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts) + 1)]


def test_no_circle_at_import_time_through_a_package() -> None:
    """Importing a module loads its packages first: ``grader/launch/__init__.py`` importing
    ``grader.scenario.model`` while ``grader/scenario/__init__.py`` imports ``grader.launch`` fails
    with "partially initialized module" although no two modules import each other. Moving an
    import out of a function (issue 38) must not close such a circle."""
    files = {_module_name(p): p for p in GRADER.rglob("*.py")}
    known = set(files)
    # a module's own packages are loaded before it: an import of one of them adds no arrow
    graph = {name: _load_time_imports(path, known) - set(_packages(name)) for name, path in files.items()}
    assert _cycles(graph) == []
    made_up = {"grader.launch": {"grader.scenario.model", "grader.scenario"},
               "grader.scenario": {"grader.launch"}, "grader.scenario.model": set()}
    assert _cycles(made_up) == [["grader.launch", "grader.scenario"]]
