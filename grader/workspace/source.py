"""Turn whatever a student handed in into a clean ``src/`` tree of ROS packages.

Accepted: a colcon workspace (with ``src/``), a folder of packages, a single package, or a
``.zip`` / ``.tar.gz`` / ``.tgz`` / ``.tar`` of any of these. Archives are extracted safely (no
absolute paths, no ``..``, no links out of the tree, bounded size), and build products that
students often zip along (``build/``, ``install/``, ``log/``) are dropped.
"""

from __future__ import annotations

import hashlib
import shutil
import tarfile
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from grader.errors import GraderError

#: directories never copied: colcon outputs, VCS data, caches
SKIP_DIRS = {"build", "install", "log", ".git", "__pycache__", ".pytest_cache", ".mypy_cache",
             ".venv", "venv", "node_modules", ".idea", ".vscode"}
MAX_UNPACKED_BYTES = 200 * 2**20
ARCHIVE_SUFFIXES = (".zip", ".tar.gz", ".tgz", ".tar", ".tar.xz", ".tar.bz2")


@dataclass(frozen=True)
class PackageSource:
    name: str
    path: Path          # folder holding package.xml
    build_type: str     # ament_python | ament_cmake | cmake | ...


def is_archive(path: Path) -> bool:
    return path.is_file() and path.name.lower().endswith(ARCHIVE_SUFFIXES)


def _check_member(name: str) -> None:
    p = PurePosixPath(name)
    if p.is_absolute() or ".." in p.parts:
        raise GraderError(f"archive member {name!r} points outside the archive; "
                          "re-create the archive from inside your workspace folder.")


def extract_archive(archive: Path, dest: Path) -> Path:
    """Extract ``archive`` into ``dest`` safely; returns ``dest``."""
    dest.mkdir(parents=True, exist_ok=True)
    total = 0
    try:
        if archive.name.lower().endswith(".zip"):
            with zipfile.ZipFile(archive) as zf:
                for info in zf.infolist():
                    _check_member(info.filename)
                    total += info.file_size
                    if total > MAX_UNPACKED_BYTES:
                        raise GraderError(f"{archive.name} unpacks to more than "
                                          f"{MAX_UNPACKED_BYTES >> 20} MiB; submit sources only.")
                zf.extractall(dest)
        else:
            with tarfile.open(archive) as tf:
                members = []
                for m in tf.getmembers():
                    _check_member(m.name)
                    if m.issym() or m.islnk() or m.isdev():
                        continue  # links and devices are never needed to build a ROS package
                    total += m.size
                    if total > MAX_UNPACKED_BYTES:
                        raise GraderError(f"{archive.name} unpacks to more than "
                                          f"{MAX_UNPACKED_BYTES >> 20} MiB; submit sources only.")
                    members.append(m)
                tf.extractall(dest, members=members, filter="data")
    except (zipfile.BadZipFile, tarfile.TarError, EOFError) as exc:
        raise GraderError(f"{archive} is not a readable archive ({exc}); "
                          "re-create it with `zip -r` or `tar czf`.") from exc
    return dest


def _build_type(package_xml: Path) -> str:
    text = package_xml.read_text(errors="replace")
    for kind in ("ament_python", "ament_cmake", "cmake"):
        if f"<build_type>{kind}</build_type>" in text.replace(" ", ""):
            return kind
    return "ament_cmake" if (package_xml.parent / "CMakeLists.txt").exists() else "ament_python"


def _package_name(package_xml: Path) -> str:
    import re

    m = re.search(r"<name>\s*([^<\s]+)\s*</name>", package_xml.read_text(errors="replace"))
    if not m:
        raise GraderError(f"{package_xml} has no <name> element; every ROS package needs one.")
    return m.group(1)


def find_packages(root: Path) -> list[PackageSource]:
    """All packages below ``root`` (a package's own subfolders are not searched further)."""
    found: list[PackageSource] = []

    def walk(d: Path) -> None:
        if (d / "COLCON_IGNORE").exists() or (d / "AMENT_IGNORE").exists():
            return
        if (d / "package.xml").is_file():
            found.append(PackageSource(_package_name(d / "package.xml"), d, _build_type(d / "package.xml")))
            return
        for child in sorted(d.iterdir()):
            if child.is_dir() and child.name not in SKIP_DIRS and not child.name.startswith(".") \
                    and not child.is_symlink():
                walk(child)

    walk(root)
    names = [p.name for p in found]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        where = "; ".join(f"{p.name}: {p.path.relative_to(root)}" for p in found if p.name in dupes)
        raise GraderError(f"package name(s) {', '.join(dupes)} appear more than once ({where}); "
                          "keep one copy of each package.")
    return found


def stage_sources(submission: Path, dest_src: Path, scratch: Path,
                  support: dict[str, Path] | None = None) -> list[PackageSource]:
    """Copy the submission's packages (plus missing ``support`` packages) into ``dest_src``."""
    submission = Path(submission)
    if not submission.exists():
        raise GraderError(f"{submission} does not exist.")
    root = submission
    if is_archive(submission):
        root = extract_archive(submission, scratch / "unpacked")
    elif not submission.is_dir():
        raise GraderError(f"{submission} is neither a folder nor a .zip/.tar.gz archive.")
    packages = find_packages(root)
    have = {p.name for p in packages}
    for name, path in (support or {}).items():
        if name not in have:
            packages += find_packages(Path(path))
    if not packages:
        raise GraderError(f"no ROS package (package.xml) found in {submission}; submit your "
                          "workspace folder (with src/) or the package folders themselves.")
    if dest_src.exists():
        shutil.rmtree(dest_src)
    dest_src.mkdir(parents=True)
    staged = []
    for pkg in packages:
        target = dest_src / pkg.name
        shutil.copytree(pkg.path, target, symlinks=False,
                        ignore=shutil.ignore_patterns(*SKIP_DIRS, "*.pyc"))
        staged.append(PackageSource(pkg.name, target, pkg.build_type))
    return staged


def tree_digest(src: Path, extra: str = "") -> str:
    """Content hash of a staged ``src/`` tree: same sources, same hash, whatever their mtimes."""
    h = hashlib.sha256(extra.encode())
    for f in sorted(p for p in src.rglob("*") if p.is_file()):
        h.update(str(f.relative_to(src)).encode() + b"\0")
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()[:20]
