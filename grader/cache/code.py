"""Which grader files make a cache entry, and their digest: the part of a key a person never bumps.

A recording (a scenario's bag, logs, canvas) is made by the scenario child and the processes it
starts, and shaped by the parent code that prepares the run; a build area by the colcon call,
the sandbox it runs in and the code that reads colcon's results. Any change to that code may
change what a cache entry holds, so the entry's key carries a digest of those files as installed
(``code_digest``), never a constant someone has to remember to bump.

Which files: the *import closure* of a few entry points, read from the code itself
(``closure``), not a hand-kept list of modules:

* every ``import``/``from ... import`` of a ``grader`` module anywhere in a module (lazy imports
  inside functions included), with the packages above it (their ``__init__`` runs too);
* every ``grader`` module started as a process (``"-m", "grader.x"`` or ``python_argv("grader.x")``):
  ``"grader.sim"`` runs ``grader/sim/__main__.py``, ``"grader.launch.describe"`` the launch
  loader, ``"grader.workspace.launch"`` the ``module:`` entry runner of a jailed process;
* every file or folder a module names from its own location, ``Path(__file__)...parent / "x"``:
  the sandbox's PID 1 (``sandbox/enter.py``, run as a script), the Fast DDS profiles
  (``dds/*.xml``), the ``launch``/``launch_ros`` stand-ins (``launch/api/``, put on the launch
  loader's ``sys.path``, not imported as ``grader`` modules).

The entry points (``RECORDING_ROOTS``, ``BUILD_ROOTS``) are the only hand-kept part: the scenario
child ``grader.scenario.run`` (recorder thread, simulator, driver, steps, runner, sandbox of the
students), its parent side ``grader.scenario`` (``resolve``, ``run_scenario``: the child's
sandbox and environment), ``grader.grading.timescale`` (at which speed a scenario records and when
it falls back to 1x), ``grader.grading.reuse`` (what an entry holds), ``grader.launch`` (a launch
file resolved into processes) and ``grader.workspace.build`` (how an executable is found and
started, and the installs a scenario runs). Besides code, ``EXTRA_DATA`` holds the one input no
module names by path: the turtlesim interface definitions (``interfaces/``), built into the venv
by ``grader setup`` and loaded by every node of a scenario. ``tests/cache/test_cache_reuse.py``
runs a real scenario with ``PYTHONPROFILEIMPORTTIME`` and checks that every ``grader`` module the
scenario child and its grader processes import is in the recording set. One package a root
imports is left out on purpose (``NOT_MAKING``): the analyzers, which the parent reads only for the
rates a faster run's watchdog expects (the rates are in the key themselves).

The files are read from where Python imports ``grader`` (a checkout or an installed wheel alike),
keyed by their path inside the package, so the same sources give the same digest anywhere.
``__pycache__`` and compiled files are left out. Computed once per process (``lru_cache``).

Cost, measured on the 2-core development machine (``python -m grader.cache.code --time``): the
recording set is ~90 files; reading them for the closure and hashing them (with the ~25 of the
build set) takes 62-68 ms of CPU (5 runs), once per grading process (scenario children never
compute it); the environment's part (``grader.cache.environment``) ~5 ms more, plus ~40-130 ms of
wall for the build tools' ``--version`` calls.
"""

from __future__ import annotations

import functools
import hashlib
import re
import sys
import time
from pathlib import Path

import grader

#: where making a recording starts (see the module docstring); the rest is derived from imports
RECORDING_ROOTS = ("grader.scenario.run", "grader.scenario", "grader.grading.timescale",
                   "grader.grading.reuse", "grader.launch", "grader.workspace.build")
#: where making a build area starts: staging, colcon in its jail, per-package results, listings
BUILD_ROOTS = ("grader.workspace.build",)
#: inputs of a recording that no module names by path (relative to the package)
EXTRA_DATA = ("interfaces",)
#: packages a root imports that make no recording: ``grader.analyze`` is imported by
#: ``grader.grading.timescale.expected_rates`` in the parent only, to read the rates the rubric's
#: ``publish_rate`` items expect, and those rates enter the key themselves (``recording_settings``);
#: an analyzer's change regrades from the same bags and must not record every scenario again
NOT_MAKING = ("grader.analyze",)

PACKAGE = Path(grader.__file__).resolve().parent
_SKIP = {"__pycache__"}


def module_file(name: str, package: Path = PACKAGE) -> Path | None:
    """The file of a ``grader`` module (``grader.x.y``), or None when there is none."""
    parts = name.split(".")
    if parts[0] != "grader":
        return None
    base = package.joinpath(*parts[1:])
    if (base / "__init__.py").is_file():
        return base / "__init__.py"
    if len(parts) > 1 and base.with_suffix(".py").is_file():
        return base.with_suffix(".py")
    return None


def _with_parents(name: str, package: Path) -> set[str]:
    parts = name.split(".")
    return {m for i in range(1, len(parts) + 1) if module_file(m := ".".join(parts[:i]), package)}


#: ``from grader.x import a, b`` (also in parentheses over lines) and ``import grader.x``
_IMPORT = re.compile(rb"^[ \t]*(?:from[ \t]+(grader(?:\.\w+)*)[ \t]+import[ \t]+(\([^)]*\)|[^\n#]*)"
                     rb"|import[ \t]+(grader(?:\.\w+)+))", re.M)
#: a grader module started as a process: ``"-m", "grader.<module>"`` or ``python_argv("grader.<module>")``
_MODULE_RUN = re.compile(rb"(?:[\"']-m[\"'],\s*|python_argv\(\s*)[\"'](grader(?:\.\w+)+)[\"']")
#: ``Path(__file__)[.resolve()][.parent...|.parents[N]] / "a" / "b"``
_FILE_PATH = re.compile(rb"Path\(__file__\)(?:\.resolve\(\))?((?:\.parent\b)*)(?:\.parents\[(\d+)\])?"
                        rb"((?:[ \t]*/[ \t]*[\"'][^\"'\n]+[\"'])+)")
_PART = re.compile(rb"[\"']([^\"'\n]+)[\"']")


def _named_files(text: bytes, here: Path) -> set[Path]:
    """Files and folders a module names from its own location (an expression that ends in
    ``/ "name"``; ``Path(__file__).parent`` alone names no input)."""
    found = set()
    for m in _FILE_PATH.finditer(text):
        path = here
        for _ in range(m.group(1).count(b".parent")):
            path = path.parent
        if m.group(2) is not None:
            path = path.parents[int(m.group(2))]
        path = path.joinpath(*(part.decode() for part in _PART.findall(m.group(3))))
        if path.exists():
            found.add(path)
    return found


def _edges(name: str, package: Path) -> tuple[set[str], set[Path]]:
    """The ``grader`` modules ``name`` imports or names, and the files it names by path.

    Read with regular expressions, not ``ast``: parsing the ~85 files of the recording set costs
    ~250 ms of CPU, the expressions ~15 ms (measured on the development machine), and
    ``tests/cache/test_cache_code.py`` checks that they find every import ``ast`` finds."""
    file = module_file(name, package)
    assert file is not None
    text = file.read_bytes()
    named: set[str] = set()
    for base, names, plain in _IMPORT.findall(text):
        if plain:
            named.add(plain.decode())
            continue
        named.add(base.decode())
        for part in re.sub(rb"#[^\n]*", b"", names).strip(b"() \t\r\n").split(b","):
            words = part.split()
            if words:                                       # `a` of `a as b`
                named.add(f"{base.decode()}.{words[0].decode()}")
    for found in _MODULE_RUN.findall(text):
        named.add(found.decode())
        if (package.joinpath(*found.decode().split(".")[1:]) / "__main__.py").is_file():
            named.add(found.decode() + ".__main__")         # `python -m grader.sim`
    modules: set[str] = set()
    for n in named:
        modules |= _with_parents(n, package)
    return modules, _named_files(text, file)


def _left_out(name: str, skip: tuple[str, ...]) -> bool:
    return any(name == s or name.startswith(s + ".") for s in skip)


def closure(roots: tuple[str, ...], package: Path = PACKAGE,
            skip: tuple[str, ...] = NOT_MAKING) -> tuple[set[str], set[Path]]:
    """Every ``grader`` module reachable from ``roots`` and every file they name by path, not
    following the packages of ``skip`` (see ``NOT_MAKING``)."""
    modules: set[str] = set()
    files: set[Path] = set()
    todo = [m for r in roots for m in sorted(_with_parents(r, package))]
    while todo:
        name = todo.pop()
        if name in modules or _left_out(name, skip):
            continue
        modules.add(name)
        found, named = _edges(name, package)
        todo += sorted(found - modules)
        for path in named:
            if path.suffix == ".py" and path.is_file() and path.is_relative_to(package):
                rel = path.relative_to(package).with_suffix("")
                script = ".".join(("grader", *rel.parts))
                if module_file(script, package) == path:
                    todo.append(script)                    # a module run as a script (enter.py)
                    continue
            files.add(path)
    return modules, files


def _expand(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    return sorted(p for p in path.rglob("*") if p.is_file() and not _SKIP & set(p.parts)
                  and p.suffix not in (".pyc", ".pyo"))


def code_files(roots: tuple[str, ...], extra: tuple[str, ...] = (), package: Path = PACKAGE) -> list[Path]:
    """The files of the closure of ``roots`` plus ``extra`` (paths inside the package), sorted."""
    modules, named = closure(roots, package)
    files = {f for m in modules if (f := module_file(m, package)) is not None}
    for path in [*named, *(package / e for e in extra)]:
        files.update(_expand(path))
    return sorted(files, key=lambda p: p.relative_to(package).as_posix())


def files_digest(files: list[Path], package: Path = PACKAGE) -> str:
    """SHA-256 over ``files``: each one's path inside ``package``, then its bytes."""
    h = hashlib.sha256()
    for f in files:
        h.update(f.relative_to(package).as_posix().encode() + b"\0")
        h.update(f.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


@functools.lru_cache(maxsize=None)
def code_digest(roots: tuple[str, ...], extra: tuple[str, ...] = ()) -> str:
    """The digest of the closure of ``roots`` (and ``extra``) in the installed package."""
    return files_digest(code_files(roots, extra))


def recording_code() -> str:
    """Digest of the grader code and data that take part in making a recording."""
    return code_digest(RECORDING_ROOTS, EXTRA_DATA)


def build_code() -> str:
    """Digest of the grader code that takes part in making a build area."""
    return code_digest(BUILD_ROOTS)


def main(argv: list[str] | None = None) -> int:
    """``python -m grader.cache.code [--files] [--time]``: the digests, their files, their cost."""
    argv = sys.argv[1:] if argv is None else argv
    t0, c0 = time.perf_counter(), time.process_time()
    rec, build = recording_code(), build_code()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"recording code {rec[:16]}  ({len(code_files(RECORDING_ROOTS, EXTRA_DATA))} files)")
    print(f"build code     {build[:16]}  ({len(code_files(BUILD_ROOTS))} files)")
    if "--time" in argv:
        print(f"computed in {wall * 1000:.0f} ms wall, {cpu * 1000:.0f} ms CPU")
    if "--files" in argv:
        for f in code_files(RECORDING_ROOTS, EXTRA_DATA):
            print(("B " if f in set(code_files(BUILD_ROOTS)) else "  ") + f.relative_to(PACKAGE).as_posix())
    return 0


if __name__ == "__main__":
    sys.exit(main())
