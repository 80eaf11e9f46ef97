"""Which files of a submission count for source similarity, and the snapshot of them that
``grader grade`` keeps in ``OUT/<id>/source/`` (so ``grader similarity OUT`` needs only OUT).

Counted: Python (nodes, ``setup.py``, launch files ``*.launch.py``), XML and YAML launch files,
``CMakeLists.txt`` and interface definitions (``.msg``, ``.srv``, ``.action``). Not counted:
``package.xml`` and ``setup.cfg`` (generated and near-identical in every package), build output,
hidden folders, anything larger than ``MAX_FILE_BYTES`` (not hand-written).
"""

from __future__ import annotations

import shutil
from pathlib import Path

SOURCE_DIR = "source"
MAX_FILE_BYTES = 200_000
SKIP_DIRS = {"build", "install", "log", "__pycache__", ".git", ".grader-check", "test"}
INTERFACE_SUFFIXES = (".msg", ".srv", ".action")


def counted(path: Path) -> bool:
    """True for a file whose text is compared."""
    name = path.name
    if name == "CMakeLists.txt":
        return True
    if name.endswith((".py", *INTERFACE_SUFFIXES)):
        return True
    return name.endswith((".launch.xml", ".launch.yaml", ".launch.yml")) or (
        path.parent.name == "launch" and name.endswith((".xml", ".yaml", ".yml")))


def source_files(root: Path) -> list[Path]:
    """The counted files under ``root``, sorted, as paths relative to it."""
    root = Path(root)
    out: list[Path] = []
    if not root.is_dir():
        return out
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root)
        if any(part in SKIP_DIRS or part.startswith(".") for part in rel.parts[:-1]):
            continue
        if path.is_symlink() or not path.is_file() or not counted(path):
            continue
        if path.stat().st_size > MAX_FILE_BYTES or path.name == "__init__.py" and path.stat().st_size == 0:
            continue
        out.append(rel)
    return out


def snapshot(src_root: Path, sub_out: Path) -> int:
    """Copy the counted files of a staged source tree into ``sub_out/source/``; how many."""
    dest = Path(sub_out) / SOURCE_DIR
    if dest.exists():
        shutil.rmtree(dest)
    files = source_files(src_root)
    for rel in files:
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(Path(src_root) / rel, target)
    return len(files)


def read_text(path: Path) -> str:
    """A file's text; undecodable bytes replaced (student files come in any encoding)."""
    return Path(path).read_bytes().decode("utf-8", errors="replace")


__all__ = ["SOURCE_DIR", "counted", "read_text", "snapshot", "source_files"]
