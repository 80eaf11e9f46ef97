"""Turn whatever a student handed in into a clean ``src/`` tree of ROS packages.

Accepted: a colcon workspace (with ``src/``), a folder of packages, a single package, or a
``.zip`` / ``.tar.gz`` / ``.tgz`` / ``.tar`` of any of these. Build products that students often
zip along (``build/``, ``install/``, ``log/``) are dropped. A submission is untrusted input, so
nothing in it can reach outside the staged tree: archive members with absolute paths or ``..``,
symbolic and hard links (in archives and in folders: a ``leak -> /etc/passwd`` link is never
followed), device files and files over ``MAX_FILE_BYTES`` are skipped, and each skip is a
warning that reaches the result (``Staged.warnings``); more than ``MAX_UNPACKED_BYTES`` in all
refuses the submission.
"""

from __future__ import annotations

import hashlib
import os
import re
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
MAX_FILE_BYTES = 20 * 2**20          # no source file of a ROS package comes near this
ARCHIVE_SUFFIXES = (".zip", ".tar.gz", ".tgz", ".tar", ".tar.xz", ".tar.bz2")


@dataclass(frozen=True)
class PackageSource:
    name: str
    path: Path          # folder holding package.xml
    build_type: str     # ament_python | ament_cmake | cmake | ...


def is_archive(path: Path) -> bool:
    return path.is_file() and path.name.lower().endswith(ARCHIVE_SUFFIXES)


def _outside(name: str) -> bool:
    p = PurePosixPath(name)
    return p.is_absolute() or ".." in p.parts


def _too_big(limit: int, archive: Path) -> GraderError:
    return GraderError(f"{archive.name} unpacks to more than {limit >> 20} MiB; "
                       "submit sources only.")


def extract_archive(archive: Path, dest: Path, warnings: list[str] | None = None, *,
                    max_file: int = MAX_FILE_BYTES, max_total: int = MAX_UNPACKED_BYTES) -> Path:
    """Extract ``archive`` into ``dest`` safely; returns ``dest``. Members that would land
    outside it, links, devices and files over ``max_file`` are skipped, each with a warning;
    over ``max_total`` in all refuses it. (An LMS download holding a class's archives takes
    larger limits than one submission: grader.intake.)"""
    warnings = warnings if warnings is not None else []
    dest.mkdir(parents=True, exist_ok=True)
    total = 0
    try:
        if archive.name.lower().endswith(".zip"):
            with zipfile.ZipFile(archive) as zf:
                members: list = []
                for info in zf.infolist():
                    mode = info.external_attr >> 16
                    if _outside(info.filename):
                        warnings.append(f"{archive.name}: skipped {info.filename!r}: its path points "
                                        "outside the archive")
                    elif (mode & 0o170000) == 0o120000:
                        warnings.append(f"{archive.name}: skipped the symbolic link {info.filename!r}")
                    elif info.file_size > max_file:
                        warnings.append(f"{archive.name}: skipped {info.filename!r} "
                                        f"({info.file_size >> 20} MiB, over {max_file >> 20} MiB)")
                    else:
                        total += info.file_size
                        if total > max_total:
                            raise _too_big(max_total, archive)
                        members.append(info)
                zf.extractall(dest, members=members)
        else:
            with tarfile.open(archive) as tf:
                members = []
                for m in tf.getmembers():
                    if _outside(m.name):
                        warnings.append(f"{archive.name}: skipped {m.name!r}: its path points outside "
                                        "the archive")
                    elif m.issym() or m.islnk():
                        warnings.append(f"{archive.name}: skipped the link {m.name!r} -> {m.linkname!r}")
                    elif not (m.isfile() or m.isdir()):
                        warnings.append(f"{archive.name}: skipped the special file {m.name!r}")
                    elif m.size > max_file:
                        warnings.append(f"{archive.name}: skipped {m.name!r} ({m.size >> 20} MiB, over "
                                        f"{max_file >> 20} MiB)")
                    else:
                        total += m.size
                        if total > max_total:
                            raise _too_big(max_total, archive)
                        members.append(m)
                tf.extractall(dest, members=members, filter="data")
    except (zipfile.BadZipFile, tarfile.TarError, EOFError) as exc:
        raise GraderError(f"{archive} is not a readable archive ({exc}); "
                          "re-create it with `zip -r` or `tar czf`.") from exc
    return dest


def copy_tree(src: Path, dest: Path, warnings: list[str], root: Path) -> None:
    """Copy a package folder without following links: a symbolic link (to a file or a folder,
    inside or outside the submission) is skipped with a warning, as are special and huge files."""
    dest.mkdir(parents=True, exist_ok=True)
    for entry in sorted(src.iterdir()):
        rel = entry.relative_to(root)
        if entry.name in SKIP_DIRS or entry.name.endswith(".pyc"):
            continue
        if entry.is_symlink():
            warnings.append(f"skipped the symbolic link {rel} -> {os.readlink(entry)}")
        elif entry.is_dir():
            copy_tree(entry, dest / entry.name, warnings, root)
        elif not entry.is_file():
            warnings.append(f"skipped the special file {rel}")
        elif entry.stat().st_size > MAX_FILE_BYTES:
            warnings.append(f"skipped {rel} ({entry.stat().st_size >> 20} MiB, over {MAX_FILE_BYTES >> 20} MiB)")
        else:
            shutil.copy2(entry, dest / entry.name, follow_symlinks=False)


def _build_type(package_xml: Path) -> str:
    text = package_xml.read_text(errors="replace")
    for kind in ("ament_python", "ament_cmake", "cmake"):
        if f"<build_type>{kind}</build_type>" in text.replace(" ", ""):
            return kind
    return "ament_cmake" if (package_xml.parent / "CMakeLists.txt").exists() else "ament_python"


def _package_name(package_xml: Path) -> str:
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


@dataclass
class Staged:
    packages: list[PackageSource]
    warnings: list[str]          # what was skipped, for the result


def stage_sources(submission: Path, dest_src: Path, scratch: Path,
                  support: dict[str, Path] | None = None) -> Staged:
    """Copy the submission's packages (plus missing ``support`` packages) into ``dest_src``."""
    submission = Path(submission)
    if not submission.exists():
        raise GraderError(f"{submission} does not exist.")
    warnings: list[str] = []
    root = submission
    if is_archive(submission):
        root = extract_archive(submission, scratch / "unpacked", warnings)
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
        copy_tree(pkg.path, target, warnings, pkg.path.parent)
        staged.append(PackageSource(pkg.name, target, pkg.build_type))
    return Staged(staged, warnings)


def tree_digest(src: Path, extra: str = "") -> str:
    """Content hash of a staged ``src/`` tree: same sources, same hash, whatever their mtimes."""
    h = hashlib.sha256(extra.encode())
    for f in sorted(p for p in src.rglob("*") if p.is_file()):
        h.update(str(f.relative_to(src)).encode() + b"\0")
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()[:20]


# ------------------------------------------------------------------ a folder of submissions
def submission_id(path: Path) -> str:
    """Folder name or archive stem, made safe for a folder and a CSV cell."""
    name = path.name
    for suffix in (".tar.gz", ".tgz", ".tar.xz", ".tar.bz2", ".tar", ".zip"):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
            break
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "submission"


def discover_submissions(root: Path) -> list[Path]:
    """A folder of submissions (one folder or archive each), or a single submission."""
    root = Path(root)
    if not root.exists():
        raise GraderError(f"{root} does not exist.")
    if is_archive(root) or (root / "src").is_dir() or (root / "package.xml").exists():
        return [root]
    subs = sorted(p for p in root.iterdir()
                  if (p.is_dir() and not p.name.startswith(".")) or is_archive(p))
    if not subs:
        raise GraderError(f"{root} holds no submissions (expected one folder or archive per student).")
    return subs
