"""Where analyzers (and the report figures drawn for them) come from: the plug-in point.

Three sources, registered the same way (``@register`` from ``grader.analyze``, ``@figure`` from
``grader.report.figures``) and validated the same way (a rubric's parameters are checked against
the accepted ones with ``file:line`` errors, whichever source defined the analyzer):

1. **This package's own modules**: every public module of ``grader.analyze`` is imported on first
   use (discovered with ``pkgutil``; no list to edit).
2. **An installed distribution**: each entry point of the group ``grader.analyzers`` names a
   module whose import registers analyzers and figures, e.g. in its ``pyproject.toml``::

       [project.entry-points."grader.analyzers"]
       my_lab = "my_lab_checks"

   So an instructor who installed the grader with pipx can ``pipx inject grader my-lab-checks``
   without forking the grader.
3. **A Python file next to a rubric**: ``analyzers: [my_lab_checks.py]`` (paths relative to the
   rubric). ``grader.rubric.load.load_rubric`` imports it before it checks the items' analyzer
   names and parameters; problems are the rubric's ``file:line: analyzers[i]: ...`` errors (file
   missing, import error, an analyzer name already defined elsewhere, a file that registers
   nothing). The file travels with the rubric into the wheel and Gradescope bundles
   (``grader.rubric.stage.referenced_paths``). It is one module: it may import the grader, the
   field's libraries and the standard library, not a sibling file.

Every process that analyzes gets the same analyzers: built-ins and entry points are loaded by the
first ``grader.analyze.get``/``names``; a rubric's files by ``load_rubric`` (grade, regrade, check,
gradescope-run all load their rubric with it) and again, idempotently, by
``grader.grading.analysis.analyze_bags`` for a Rubric built another way. The scenario child
analyzes nothing (it records), so it loads none.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import pkgutil
import sys
import threading
import traceback
from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path
from typing import Any, Iterable

from grader.analyze import registry
from grader.errors import GraderError

ENTRY_POINT_GROUP = "grader.analyzers"

#: modules of grader.analyze that register nothing (helpers, pure checks used by the pipeline)
_HELPERS = frozenset({"plugins", "evidence", "registry"})

_state = {"loaded": ""}            # "" (not yet), "loading" (in this or another thread), "done"
#: a batch analyzes in threads: one imports, the others wait for it (reentrant: the modules being
#: imported call back into the registry)
_LOCK = threading.RLock()


class PluginError(GraderError):
    """A plug-in that cannot be used (missing, not importable, defining a name twice)."""


@dataclass(frozen=True)
class LoadedFile:
    """A rubric's analyzer file as imported: its content digest, module name and what it defined."""

    digest: str
    module: str
    analyzers: tuple[str, ...]
    stamp: tuple[int, int]        # (mtime_ns, size): unchanged files are not read again


_FILES: dict[Path, LoadedFile] = {}


def builtin_modules() -> list[str]:
    """The public modules of ``grader.analyze`` (imported in name order)."""
    return sorted(f"grader.analyze.{m.name}" for m in pkgutil.iter_modules([str(Path(__file__).parent)])
                  if not m.name.startswith("_") and m.name not in _HELPERS)


def installed_entry_points() -> list[EntryPoint]:
    """The ``grader.analyzers`` entry points of the installed distributions, by name."""
    return sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: (ep.name, ep.value))


def load_builtin_and_installed() -> None:
    """Import the built-in analyzer modules, then every installed plug-in (once per process)."""
    if _state["loaded"] == "done":
        return
    with _LOCK:
        if _state["loaded"]:          # done by another thread, or this thread is importing them
            return
        _state["loaded"] = "loading"
        try:
            for module in builtin_modules():
                importlib.import_module(module)
            for ep in installed_entry_points():
                _load_entry_point(ep)
        except BaseException:
            _state["loaded"] = ""
            raise
        _state["loaded"] = "done"


def _load_entry_point(ep: EntryPoint) -> None:
    dist = getattr(ep, "dist", None)
    where = f"entry point {ep.name} = {ep.value}" + (f" of {dist.name}" if dist is not None else "")
    registry._defining.append(where)
    try:
        ep.load()
    except GraderError:
        raise
    except Exception as exc:  # noqa: BLE001 - any import failure of someone else's code
        raise PluginError(f"analyzer plug-in ({where}, group {ENTRY_POINT_GROUP}) cannot be imported: "
                          f"{type(exc).__name__}: {exc}; fix or uninstall that distribution") from None
    finally:
        registry._defining.pop()


def _stamp(path: Path) -> tuple[int, int]:
    st = path.stat()
    return (st.st_mtime_ns, st.st_size)


def load_file(path: str | Path) -> tuple[str, ...]:
    """Import a rubric's analyzer file; the names of the analyzers it defines.

    Idempotent: the same unchanged file is imported once per process, and a byte-identical copy
    of it (a staged rubric's) is the same plug-in; a changed file replaces its previous
    definitions. Raises :class:`PluginError` (one sentence, with the file's line when the error is
    in it) when the file is missing or cannot be imported, when it defines an analyzer name that
    another module, plug-in or file already defines, or when it defines nothing.
    """
    with _LOCK:
        return _load_file(path)


def _load_file(path: str | Path) -> tuple[str, ...]:
    """:func:`load_file`, under the lock."""
    path = Path(path).resolve()
    if not path.is_file():
        raise PluginError(f"analyzer file not found (looked for {path})")
    stamp = _stamp(path)
    known = _FILES.get(path)
    if known is not None and known.stamp == stamp:
        return known.analyzers
    data = path.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    if known is not None and known.digest == digest:
        _FILES[path] = LoadedFile(digest, known.module, known.analyzers, stamp)
        return known.analyzers
    if known is not None:
        unload_file(path)
    same = next((f for f in _FILES.values() if f.digest == digest), None)
    if same is not None:      # a byte-identical copy (a staged rubric next to its source): one plug-in
        _FILES[path] = LoadedFile(digest, same.module, same.analyzers, stamp)
        return same.analyzers
    load_builtin_and_installed()        # so a name it repeats is found now, whoever came first
    module_name = f"grader_rubric_plugin_{_identifier(path.stem)}_{hashlib.sha256(str(path).encode()).hexdigest()[:10]}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise PluginError(f"{path.name} is not a Python module (name it *.py)")
    module = importlib.util.module_from_spec(spec)
    before = set(registry._REGISTRY)
    sys.modules[module_name] = module          # dataclasses and pickling look modules up here
    registry._defining.append(str(path))
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - an instructor's file: any error becomes a rubric problem
        registry.forget(set(registry._REGISTRY) - before)
        _forget_figures(module_name)
        sys.modules.pop(module_name, None)
        if isinstance(exc, registry.DuplicateAnalyzer):
            raise PluginError(f"{path.name}{_line_in(exc, path)}: {exc}") from None
        raise PluginError(f"cannot import {path.name}{_line_in(exc, path)}: {type(exc).__name__}: {exc}") from None
    finally:
        registry._defining.pop()
    defined = tuple(sorted(set(registry._REGISTRY) - before))
    if not defined and not _defines_figures(module_name):
        sys.modules.pop(module_name, None)
        raise PluginError(f"{path.name} defines no analyzer and no figure (decorate a function with "
                          "@register(\"name\", params=MyParams) from grader.analyze)")
    _FILES[path] = LoadedFile(digest, module_name, defined, stamp)
    return defined


def load_files(paths: Iterable[str | Path]) -> dict[str, tuple[str, ...]]:
    """:func:`load_file` for each path; ``{path: analyzer names}``."""
    return {str(p): load_file(p) for p in paths}


def load_rubric_files(rubric: Any) -> None:
    """Import the analyzer files a Rubric names (``rubric.analyzers``; idempotent)."""
    load_files(getattr(rubric, "analyzers", ()) or ())


def load_recorded_files(paths: Iterable[str]) -> None:
    """Import the analyzer files a result.json names (``analyzer_files``) before its page is drawn
    again without the rubric (``grader scores merge``), so the page keeps those analyzers'
    figures and evidence labels; a file since moved or broken is skipped (the page then shows
    the evidence without them, as for an analyzer this grader does not know)."""
    for path in paths:
        try:
            load_file(path)
        except GraderError:
            continue


def unload_file(path: str | Path) -> None:
    """Forget a file's analyzers and figures (it changed, or a test is done with it)."""
    with _LOCK:
        _unload(path)


def _unload(path: str | Path) -> None:
    known = _FILES.pop(Path(path).resolve(), None)
    if known is None or any(f.module == known.module for f in _FILES.values()):
        return                  # unknown, or an identical copy elsewhere still uses the module
    registry.forget(known.analyzers)
    _forget_figures(known.module)
    sys.modules.pop(known.module, None)


def loaded_files() -> dict[Path, tuple[str, ...]]:
    """The rubric analyzer files imported in this process and the analyzers each defined."""
    return {p: f.analyzers for p, f in _FILES.items()}


def _identifier(stem: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in stem) or "file"


def _line_in(exc: BaseException, path: Path) -> str:
    """`` (line N)``: where in ``path`` the error happened, when it happened there."""
    if isinstance(exc, SyntaxError) and exc.filename and Path(exc.filename).resolve() == path and exc.lineno:
        return f" (line {exc.lineno})"
    lines = [f.lineno for f in traceback.extract_tb(exc.__traceback__)
             if f.filename and Path(f.filename).resolve() == path]
    return f" (line {lines[-1]})" if lines else ""


def _figures_module() -> Any:
    return sys.modules.get("grader.report.figures")


def _defines_figures(module_name: str) -> bool:
    figures = _figures_module()
    return figures is not None and figures.defined_by(module_name)


def _forget_figures(module_name: str) -> None:
    figures = _figures_module()
    if figures is not None:
        figures.forget_module(module_name)
