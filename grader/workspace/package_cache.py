"""Per-package build cache: a package built once is not built again for the next submission.

The workspace cache (``build.py``) is keyed by the whole ``src/`` tree, so two students who
differ in one Python file build everything, including the interface package the lab hands out
(rosidl generators, CMake and the C compiler). Measured on a 2-core machine for a Lab 3
submission: the whole colcon build costs ~18-21 s of CPU, of which ~15 s is the untouched
``turtle_control_interfaces``; with it reused, colcon builds the three Python packages in
~3.7 s of CPU (``benchmarks/bench_cpu.py``).

A package's key is the content of its own sources, its build type, the keys of the workspace
packages it depends on (``package.xml``), and the grader's ROS mode and Python, so a change
anywhere below a package rebuilds it. When every workspace dependency of a package is reused
too and its key names a package that built in an earlier build area, the new build area gets
``install/<pkg>`` as hard links to that install's files (see :func:`copy_installs`), and colcon
is told ``--packages-skip`` it (the documented way to build on top of packages already installed;
dependants resolve it in the install base as usual). Nothing else in an install names where it
was built: the libraries carry no RPATH and CMake's export files locate themselves, except for
two colcon shell scripts, which are rewritten. Only packages that built are reused: a failed one
is built again and gets its own diagnosis.

``<cache>/packages/<key>.json`` names the build area that holds the package. Per-key locks
(taken in sorted order, so two builds never wait on each other in a cycle) make a second build
of the same package wait for the first instead of compiling it twice on the same cores.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from grader.workspace.source import PackageSource, tree_digest

#: bump when what a cached package holds changes meaning
PACKAGE_CACHE_FORMAT = 1
INDEX_DIR = "packages"
_DEPEND = re.compile(r"<(?:depend|build_depend|build_export_depend|exec_depend|buildtool_depend|"
                     r"test_depend)[^>]*>\s*([A-Za-z0-9_]+)\s*<")


@dataclass(frozen=True)
class CachedPackage:
    """A package some earlier build area holds, built."""

    name: str
    key: str
    root: Path              # the build area it was built in
    build: dict             # its PackageBuild, as that build recorded it

    @property
    def install(self) -> Path:
        return self.root / "install" / self.name


def workspace_dependencies(staged: list[PackageSource]) -> dict[str, set[str]]:
    """``{package: the workspace packages its package.xml names}``."""
    names = {p.name for p in staged}
    deps: dict[str, set[str]] = {}
    for pkg in staged:
        manifest = pkg.path / "package.xml"
        text = manifest.read_text(errors="replace") if manifest.is_file() else ""
        deps[pkg.name] = {d for d in _DEPEND.findall(text) if d in names and d != pkg.name}
    return deps


def package_keys(staged: list[PackageSource], extra: str) -> dict[str, str]:
    """Each staged package's key: its sources, build type and its dependencies' keys."""
    deps = workspace_dependencies(staged)
    by_name = {p.name: p for p in staged}
    keys: dict[str, str] = {}

    def key(name: str, visiting: tuple[str, ...]) -> str:
        if name in keys:
            return keys[name]
        pkg = by_name[name]
        h = hashlib.sha256(f"{PACKAGE_CACHE_FORMAT}:{extra}:{pkg.name}:{pkg.build_type}:".encode())
        h.update(tree_digest(pkg.path).encode())
        for dep in sorted(deps[name]):
            # a dependency cycle cannot build; its members are keyed by name only there
            h.update(f"{dep}={'cycle' if dep in visiting else key(dep, (*visiting, name))};".encode())
        keys[name] = h.hexdigest()[:24]
        return keys[name]

    for pkg in staged:
        key(pkg.name, ())
    return keys


class PackageCache:
    """The index of built packages of one build cache folder."""

    def __init__(self, cache_dir: Path) -> None:
        self.dir = Path(cache_dir) / INDEX_DIR

    @contextlib.contextmanager
    def locked(self, keys: list[str]) -> Iterator[None]:
        """Hold every key's lock (sorted order: no cycles between concurrent builds)."""
        self.dir.mkdir(parents=True, exist_ok=True)
        with contextlib.ExitStack() as stack:
            for key in sorted(set(keys)):
                fh = stack.enter_context(open(self.dir / f"{key}.lock", "w"))
                fcntl.flock(fh, fcntl.LOCK_EX)
            yield

    def get(self, name: str, key: str) -> CachedPackage | None:
        entry = self.dir / f"{key}.json"
        try:
            data = json.loads(entry.read_text())
        except (OSError, ValueError):
            return None
        found = CachedPackage(name, key, Path(data["root"]), data["build"])
        ok = (data.get("name") == name and found.install.is_dir() and not found.install.is_symlink()
              and (found.root / "result.json").is_file())
        return found if ok else None

    def put(self, key: str, root: Path, build: dict) -> None:
        """Record that ``root`` holds the built package (atomically)."""
        self.dir.mkdir(parents=True, exist_ok=True)
        tmp = self.dir / f".{key}.{os.getpid()}.tmp"
        tmp.write_text(json.dumps({"name": build["name"], "root": str(root), "build": build}))
        os.replace(tmp, self.dir / f"{key}.json")

    def reusable(self, staged: list[PackageSource], keys: dict[str, str]) -> dict[str, CachedPackage]:
        """The packages that can be taken instead of built: cached, and so is every workspace
        package they depend on (a dependency rebuilt here could come out differently)."""
        found = {p.name: c for p in staged if (c := self.get(p.name, keys[p.name])) is not None}
        deps = workspace_dependencies(staged)
        changed = True
        while changed:
            changed = False
            for name in list(found):
                if not deps[name] <= set(found):
                    del found[name]
                    changed = True
        return found


def copy_installs(root: Path, reused: dict[str, CachedPackage]) -> None:
    """``root/install/<pkg>``: the install of each reused package, as hard links to its files.

    A real folder inside the build area (not a link out of it), so whatever sees the build area
    sees the package (a sandbox that binds only this area, a removed earlier area), at no extra
    disk. The few text files that name the install's own path (colcon's ``package.sh`` and
    ``local_setup.sh``) are rewritten, as new files, with the new path; ``__pycache__`` is left
    out so a traceback names this area's files.
    """
    install = root / "install"
    install.mkdir(parents=True, exist_ok=True)
    for name, cached in reused.items():
        src, dest = cached.install, install / name
        shutil.copytree(src, dest, symlinks=True, copy_function=_link_or_copy,
                        ignore=shutil.ignore_patterns("__pycache__"))
        old, new = str(src).encode(), str(dest).encode()
        for f in dest.rglob("*"):
            if f.is_file() and not f.is_symlink() and f.suffix not in _BINARY and f.stat().st_size < 1 << 20:
                data = f.read_bytes()
                if old in data and b"\0" not in data:
                    f.unlink()                  # a new file: the earlier area's copy stays as it was
                    f.write_bytes(data.replace(old, new))


_BINARY = {".so", ".a", ".pyc", ".o"}


def _link_or_copy(src: str, dest: str) -> None:
    try:
        os.link(src, dest)
    except OSError:                             # another file system, or links not allowed
        shutil.copy2(src, dest)
