"""Per-package build cache: the instructor's packages are built once, not once per submission.

The workspace cache (``build.py``) is keyed by the whole ``src/`` tree, so two students who
differ in one Python file build everything, including the interface package the lab hands out
(rosidl generators, CMake and the C compiler). Measured on a 2-core machine for a Lab 3
submission (``benchmarks/bench_cpu.py``): the whole colcon build costs ~18-21 s of CPU, of which
~15 s is the untouched ``turtle_control_interfaces``; with it taken from the cache, colcon builds
the three Python packages in ~4 s (~1.4 s for one).

Which packages are shared: the rubric's ``support:`` packages, built in a build area of their own
(:func:`stage_support`) where no student code runs. A package built inside a student's workspace
is never shared: the student's other packages' build code (``setup.py``, CMake) runs in the same
jail with write access to the whole ``install/``, so it could have altered it.

A package's key is the content of its own sources, its build type, the keys of the workspace
packages it depends on (``package.xml``), and what the workspace key has besides its sources (the
grader's build code, the ROS, Python and build tools' versions: ``build.py``), so a student's
copy of a support package gets the support build's key only when it and everything it depends on
in the workspace are byte-identical, and no package built by another grader or toolchain is
taken. Such a package is copied into the new build area's
``install/<pkg>`` (:func:`copy_installs`: real copies, ~2.4 MB and ~20 ms for the Lab 3 interface
package, so nothing a student's build does to its own ``install/`` reaches the shared one), and
colcon is told ``--packages-skip`` it (the documented way to build on top of packages already
installed; dependants resolve it in the install base as usual). Nothing in an install names
where it was built except two colcon shell scripts, which are rewritten: the libraries carry no
RPATH and CMake's export files locate themselves. ``<cache>/packages/<key>.json`` names the build
area that holds a shared package.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import threading
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Iterator

from grader.cache.locks import Holds, use_lock
from grader.workspace.source import SKIP_DIRS, PackageSource, find_packages, tree_digest

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
        h = hashlib.sha256(f"{extra}:{pkg.name}:{pkg.build_type}:".encode())
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

    def get(self, name: str, key: str) -> CachedPackage | None:
        entry = self.dir / f"{key}.json"
        try:
            data = json.loads(entry.read_text())
        except (OSError, ValueError):
            return None
        found = CachedPackage(name, key, Path(data["root"]), data["build"])
        ok = (data.get("trusted") is True and data.get("name") == name and found.install.is_dir()
              and not found.install.is_symlink() and (found.root / "result.json").is_file())
        return found if ok else None

    def put(self, key: str, root: Path, build: dict) -> None:
        """Record that ``root`` holds the built package (atomically); only for trusted builds."""
        self.dir.mkdir(parents=True, exist_ok=True)
        tmp = self.dir / f".{key}.{os.getpid()}.{threading.get_ident()}.tmp"
        tmp.write_text(json.dumps({"name": build["name"], "root": str(root), "build": build, "trusted": True}))
        os.replace(tmp, self.dir / f"{key}.json")

    def share(self, result, keys: dict[str, str]) -> None:
        """Offer every package a trusted build built (a ``BuildResult``) to later builds."""
        for name, pkg in result.packages.items():
            if pkg.status == "built" and not pkg.reused_from and name in keys:
                self.put(keys[name], Path(result.root), asdict(pkg))

    def reusable(self, staged: list[PackageSource], keys: dict[str, str],
                 holds: Holds | None = None) -> dict[str, CachedPackage]:
        """The packages that can be taken instead of built: cached, and so is every workspace
        package they depend on (a dependency rebuilt here could come out differently). With
        ``holds``, the build areas they are taken from are held (and looked up again once held:
        a prune may have removed one meanwhile)."""
        found = {p.name: c for p in staged if (c := self.get(p.name, keys[p.name])) is not None}
        if holds is not None:
            for name, cached in list(found.items()):
                holds.hold(use_lock(cached.root))
                if self.get(name, cached.key) is None:
                    del found[name]
        deps = workspace_dependencies(staged)
        changed = True
        while changed:
            changed = False
            for name in list(found):
                if not deps[name] <= set(found):
                    del found[name]
                    changed = True
        return found


@contextlib.contextmanager
def stage_support(support: dict[str, Path], cache_dir: Path) -> Iterator[Path | None]:
    """A workspace holding only the rubric's support packages (the instructor's files), to be
    built as a trusted build whose packages later builds may take; None when none is found."""
    ws = Path(cache_dir) / f".support-{os.getpid()}-{threading.get_ident()}"
    try:
        for name, path in sorted(support.items()):
            for pkg in (find_packages(Path(path)) if Path(path).is_dir() else []):
                if pkg.name == name:
                    shutil.copytree(pkg.path, ws / "src" / name, ignore=shutil.ignore_patterns(*SKIP_DIRS, "*.pyc"))
        yield ws if (ws / "src").is_dir() else None
    finally:
        shutil.rmtree(ws, ignore_errors=True)


def copy_installs(root: Path, reused: dict[str, CachedPackage]) -> None:
    """``root/install/<pkg>``: a copy of each reused package's install, with the few text files
    that name the install's own path (colcon's ``package.sh``, ``local_setup.sh``) rewritten;
    ``__pycache__`` is left out so a traceback names this area's files."""
    install = root / "install"
    install.mkdir(parents=True, exist_ok=True)
    for name, cached in reused.items():
        src, dest = cached.install, install / name
        shutil.copytree(src, dest, symlinks=True, ignore=shutil.ignore_patterns("__pycache__"))
        old, new = str(src).encode(), str(dest).encode()
        for f in dest.rglob("*"):
            if f.is_file() and not f.is_symlink() and f.suffix not in _BINARY and f.stat().st_size < 1 << 20:
                data = f.read_bytes()
                if old in data and b"\0" not in data:
                    f.write_bytes(data.replace(old, new))


_BINARY = {".so", ".a", ".pyc", ".o"}
