"""Submissions of bare source files: a student who uploads ``my_first_node.py`` and
``turtle_controller.py`` instead of a workspace.

Such a submission (no ``package.xml`` anywhere, at least one ``.py`` file) is wrapped into the
ament_python package the rubric names (``loose_files:``): its ``.py`` files go into the
package's module folder, the rubric's ``executables`` become console scripts, and the package
is built and graded like any other. Without ``loose_files`` in the rubric it is refused with
the reason, never skipped. Only ``.py`` files are taken (links, huge files and everything else
are left out, each with a note); two files of the same name in different folders are refused,
since nobody can tell which one the student meant.
"""

from __future__ import annotations

import re
import shutil
import tarfile
import zipfile
from pathlib import Path, PurePosixPath

from grader.errors import GraderError
from grader.intake.model import Arrival
from grader.workspace.source import MAX_FILE_BYTES, SKIP_DIRS, extract_archive, is_archive

#: Canvas names a re-uploaded file ``node-1.py``: the plain name is what the student meant
_RESUBMITTED = re.compile(r"^(?P<stem>.+)-\d+(?P<ext>\.[A-Za-z0-9]+)$")
MAX_SHOWN = 6


def scan(path: Path) -> tuple[bool, list[str]]:
    """(has a package.xml, the .py files as relative paths) of a folder or an archive."""
    names: list[str] = []
    if is_archive(path):
        try:
            if path.name.lower().endswith(".zip"):
                with zipfile.ZipFile(path) as zf:
                    names = [i.filename for i in zf.infolist() if not i.is_dir()]
            else:
                with tarfile.open(path) as tf:
                    names = [m.name for m in tf.getmembers() if m.isfile()]
        except (OSError, zipfile.BadZipFile, tarfile.TarError, EOFError):
            return True, []              # unreadable: the build says so, with the archive's name
    else:
        for file in _walk(path):
            names.append(file.relative_to(path).as_posix())
    parts = [PurePosixPath(n) for n in names if not any(p in SKIP_DIRS or p.startswith(".")
                                                        for p in PurePosixPath(n).parts[:-1])]
    has_package = any(p.name == "package.xml" for p in parts)
    return has_package, sorted(str(p) for p in parts if p.suffix == ".py")


def _walk(folder: Path):
    for entry in sorted(folder.iterdir()):
        if entry.is_symlink():
            continue
        if entry.is_dir():
            if entry.name not in SKIP_DIRS and not entry.name.startswith("."):
                yield from _walk(entry)
        elif entry.is_file():
            yield entry


def _shown(names: list[str]) -> str:
    shown = ", ".join(names[:MAX_SHOWN])
    return shown + (f" and {len(names) - MAX_SHOWN} more" if len(names) > MAX_SHOWN else "")


def check_loose(arrival: Arrival, rubric, work: Path) -> None:
    """Wrap ``arrival`` into the rubric's package when it is only loose files, or refuse it."""
    if not arrival.gradable:
        return
    has_package, py_files = scan(arrival.path)       # type: ignore[arg-type]
    if has_package or not py_files:
        return                   # a workspace; or nothing to wrap (the build names what is missing)
    spec = getattr(rubric, "loose_files", None)
    if spec is None:
        arrival.refused = (f"only loose files ({_shown(py_files)}) and no ROS package (package.xml): this "
                           "rubric does not say which package they belong in (loose_files:); ask for the "
                           "workspace's src/ folder or the package folders")
        return
    try:
        wrap(arrival, spec, work / "loose" / (arrival.id or arrival.key))
    except GraderError as exc:             # an archive that cannot be unpacked
        arrival.refused = str(exc)


def wrap(arrival: Arrival, spec, dest: Path) -> None:
    """Build the package folder ``dest/src/<package>`` from the arrival's .py files."""
    if dest.exists():
        shutil.rmtree(dest)
    source = arrival.path
    assert source is not None
    warnings: list[str] = []
    if is_archive(source):
        source = extract_archive(source, dest / "unpacked", warnings)
    files: dict[str, Path] = {}
    for file in _walk(source):
        if file.suffix != ".py":
            continue
        if file.stat().st_size > MAX_FILE_BYTES:
            warnings.append(f"left out {file.name} ({file.stat().st_size >> 20} MiB)")
            continue
        name = file.name
        if name in files:
            arrival.refused = (f"two files named {name} ({files[name].relative_to(source)}, "
                               f"{file.relative_to(source)}): submit one copy of each file")
            return
        files[name] = file
    wanted = set(spec.files.values())
    for name in list(files):
        m = _RESUBMITTED.match(name)
        plain = f"{m['stem']}{m['ext']}" if m else None
        if plain and plain in wanted and plain not in files:
            files[plain] = files.pop(name)
    pkg_dir = dest / "ws" / "src" / spec.package
    module_dir = pkg_dir / spec.package
    module_dir.mkdir(parents=True)
    for name, file in sorted(files.items()):
        shutil.copyfile(file, module_dir / name)
    (module_dir / "__init__.py").touch(exist_ok=True)
    _package_files(pkg_dir, spec)
    if source != arrival.path:
        shutil.rmtree(dest / "unpacked", ignore_errors=True)
    arrival.path = dest / "ws"
    arrival.notes.append(f"loose files ({_shown(sorted(files))}) wrapped into package {spec.package} "
                         "(the rubric's loose_files)")
    missing = sorted(f"{script} needs {file}" for script, file in spec.files.items() if file not in files)
    if missing:
        arrival.notes.append(f"not among the files: {'; '.join(missing)} (those programs cannot run)")
    arrival.notes += warnings


def _package_files(pkg_dir: Path, spec) -> None:
    """package.xml, setup.py, setup.cfg and the ament resource marker of the wrapper package."""
    name = spec.package
    depends = "\n".join(f"  <exec_depend>{d}</exec_depend>" for d in spec.depends)
    (pkg_dir / "package.xml").write_text(f"""<?xml version="1.0"?>
<package format="3">
  <name>{name}</name>
  <version>0.0.0</version>
  <description>A student's loose files, wrapped by grader (rubric loose_files).</description>
  <maintainer email="grader@localhost">grader</maintainer>
  <license>unknown</license>
{depends}
  <export>
    <build_type>ament_python</build_type>
  </export>
</package>
""")
    scripts = ",\n".join(f"            '{script} = {spec.entry_point(script)}'" for script in spec.executables)
    (pkg_dir / "setup.py").write_text(f"""from setuptools import setup

package_name = '{name}'

setup(
    name=package_name,
    version='0.0.0',
    packages=[package_name],
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='grader',
    maintainer_email='grader@localhost',
    description="A student's loose files, wrapped by grader.",
    license='unknown',
    entry_points={{
        'console_scripts': [
{scripts},
        ],
    }},
)
""")
    (pkg_dir / "setup.cfg").write_text(f"[develop]\nscript_dir=$base/lib/{name}\n"
                                       f"[install]\ninstall_scripts=$base/lib/{name}\n")
    (pkg_dir / "resource").mkdir()
    (pkg_dir / "resource" / name).touch()
