"""Why a package failed to build, as one line a student can act on (``file:line: message``).

colcon gives per package only a return code and a log. The line that explains a failure is
buried in CMake's output (re-wrapped at 80 columns), in tracebacks of the rosidl generators, in
compiler output or in a traceback printed by ``setup.py``. No library turns these logs into
diagnostics, so this module recognises the shapes ROS 2 builds produce, most precise first:

1. ``setup.py`` that does not run (a SyntaxError found by compiling it; anything else by running
   it again, since colcon prints that traceback to its own stderr, not to the package's log);
2. rosidl_adapter's ``Error processing 'float64 x, y' of 'pkg/SetGoal_Request'``: the interface
   file and line;
3. unknown interface types (rosidl_generator_type_description's missing ``.json`` / ``KeyError``):
   the line that uses the type;
4. ``find_package`` that found nothing: the dependency, named as one the grading machine lacks
   when it is neither installed nor in the submission;
5. the first other ``CMake Error`` block; 6. the first compiler or linker error;
7. the last exception of a Python traceback; 8. the first line that says ``error``.
"""

from __future__ import annotations

import importlib.util
import os
import re
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping

from grader.sandbox.oneshot import run_jailed_capture

DETAIL_LINES = 6
SETUP_PY_TIMEOUT_S = 60
ROS_NAME = re.compile(r"^[a-z][a-z0-9_]*$")       # REP 144; rosdep keys (python3-numpy) differ
DEP_TAGS = ("depend", "build_depend", "buildtool_depend", "build_export_depend", "exec_depend")
INTERFACE_SUFFIXES = (".msg", ".srv", ".action")
_SECTIONS = {"_Request": (".srv", 0), "_Response": (".srv", 1),
             "_Goal": (".action", 0), "_Result": (".action", 1), "_Feedback": (".action", 2)}
_TYPE_HINTS = {"float": "float32 or float64", "double": "float64", "int": "int32 or int64",
               "long": "int64", "unsigned": "uint32", "str": "string", "boolean": "bool"}


@dataclass
class Diagnosis:
    reason: str                                          # one line, e.g. "srv/SetGoal.srv:1: ..."
    detail: list[str] = field(default_factory=list)      # the few log lines that back it
    missing: list[str] = field(default_factory=list)     # dependencies the grading machine lacks


class Availability:
    """Which ROS packages a build can use: the submission's own, or ones installed here."""

    def __init__(self, workspace: Iterable[str], env: Mapping[str, str]) -> None:
        self.workspace = set(workspace)
        self.prefixes: list[Path] = []
        for var in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH"):
            for p in env.get(var, "").split(os.pathsep):
                if p and Path(p) not in self.prefixes:
                    self.prefixes.append(Path(p))

    def installed(self, name: str) -> bool:
        for p in self.prefixes:
            if (p / "share" / "ament_index" / "resource_index" / "packages" / name).is_file() or \
                    (p / "share" / name / "package.xml").is_file() or \
                    (p / "share" / name / "cmake").is_dir() or (p / "lib" / "cmake" / name).is_dir():
                return True
        try:
            return importlib.util.find_spec(name) is not None      # a pure-Python dependency
        except (ImportError, ValueError):
            return False

    def available(self, name: str) -> bool:
        return name in self.workspace or self.installed(name)

    def missing_from_manifest(self, package_xml: Path) -> list[str]:
        """Build and run dependencies in ``package.xml`` that nothing here provides."""
        try:
            root = ET.parse(package_xml).getroot()
        except (ET.ParseError, OSError):
            return []
        names = {(el.text or "").strip() for tag in DEP_TAGS for el in root.iter(tag)
                 if "condition" not in el.attrib}
        return sorted(n for n in names if ROS_NAME.match(n) and not self.available(n))


def lacks(name: str, where: str) -> str:
    return f"grading machine lacks {name} ({where}; not installed here, not in the submission)"


# -- CMake's re-wrapped messages ---------------------------------------------------------------
_CMAKE_HEAD = re.compile(r"^CMake Error(?: at (?P<file>\S+?):(?P<line>\d+)(?: \((?P<cmd>\w+)\))?)?"
                         r"(?: in (?P<in>\S+?))?:\s*(?P<rest>.*)$")
_STACK_FRAME = re.compile(r"^\s+(?P<file>\S+?):(?P<line>\d+) \((?P<cmd>\w+)\)")


@dataclass
class CMakeError:
    location: str                     # "CMakeLists.txt:4" (in the package) or ""
    command: str
    paragraphs: list[str]             # the message, one line per paragraph


def cmake_errors(lines: list[str]) -> list[CMakeError]:
    errors, i = [], 0
    while i < len(lines):
        m = _CMAKE_HEAD.match(lines[i])
        i += 1
        if not m:
            continue
        body = [m["rest"]] if m["rest"] else []
        while i < len(lines) and (not lines[i].strip() or lines[i].startswith(" ")):
            body.append(lines[i])
            i += 1
        paragraphs, cur = [], []
        for ln in body + [""]:
            if ln.strip():
                cur.append(ln.strip())
            elif cur:
                paragraphs.append(" ".join(cur))
                cur = []
        frames = []
        if i < len(lines) and lines[i].startswith("Call Stack"):
            i += 1
            while i < len(lines) and (fm := _STACK_FRAME.match(lines[i])):
                frames.append(fm)
                i += 1
        own = [f"{f['file']}:{f['line']}" for f in frames if not f["file"].startswith("/")]
        location = f"{m['file']}:{m['line']}" if m["file"] and not m["file"].startswith("/") else \
            (own[-1] if own else (m["in"] or ""))
        errors.append(CMakeError(location, m["cmd"] or "", paragraphs))
    return errors


# -- interface files --------------------------------------------------------------------------
def _interface_files(pkg_dir: Path) -> list[Path]:
    return sorted(p for p in pkg_dir.rglob("*") if p.suffix in INTERFACE_SUFFIXES and p.is_file())


def _definition_lines(path: Path):
    """(line number, section, text as rosidl sees it) of each line of an interface file."""
    section = 0
    for n, raw in enumerate(path.read_text(errors="replace").splitlines(), 1):
        text = raw.replace("\t", " ").split("#", 1)[0].rstrip()
        if text.strip() == "---":
            section += 1
            continue
        yield n, section, text


def _locate_definition(pkg_dir: Path, msg: str, line_text: str) -> tuple[str, int | None]:
    """File (relative to the package) and line of ``line_text`` in interface ``msg``."""
    stem, suffix, section = msg, ".msg", None
    for tail, (sfx, sec) in _SECTIONS.items():
        if msg.endswith(tail):
            stem, suffix, section = msg[:-len(tail)], sfx, sec
    files = [p for p in _interface_files(pkg_dir) if p.stem == stem and p.suffix == suffix]
    if not files:
        return f"{stem}{suffix}", None
    rel = str(files[0].relative_to(pkg_dir))
    hits = [(n, sec) for n, sec, text in _definition_lines(files[0])
            if text.strip() == line_text.strip()]
    for n, sec in hits:
        if section is None or sec == section:
            return rel, n
    return rel, hits[0][0] if hits else None


def _locate_type_use(pkg_dir: Path, own: str, type_pkg: str, type_name: str | None):
    """(file:line, text) of the first field whose type is ``type_pkg/type_name``."""
    for path in _interface_files(pkg_dir):
        for n, _sec, text in _definition_lines(path):
            if not text.strip():
                continue
            typ = re.sub(r"\[.*$", "", text.split()[0])
            pkg, _, name = typ.rpartition("/")
            pkg = pkg.split("/")[0] if pkg else own
            if pkg == type_pkg and (type_name is None or name == type_name) and name[:1].isupper():
                return f"{path.relative_to(pkg_dir)}:{n}", text.strip()
    return "", ""


def _first_sentence(text: str) -> str:
    return re.split(r"\.\s+(?=[A-Z])", text.strip(), maxsplit=1)[0].rstrip(".")


def _at(where: str, message: str) -> str:
    return f"{where}: {message}" if where else message


# -- the rules --------------------------------------------------------------------------------
_ROSIDL_FIELD = re.compile(r"Error processing '(?P<line>.*?)' of '(?P<pkg>\w+)/(?P<msg>\w+)': "
                           r"'(?P<err>.*)'\s*$")
_ROSIDL_WITH = re.compile(r"^Error with: (?P<pkg>\w+) (?P<msg>\w+) (?P<line>.*)$")
_ROSIDL_EXC = re.compile(r"rosidl_adapter\.parser\.(?P<exc>\w+): (?P<msg>.*)$")
_NO_JSON = re.compile(r"No such file or directory: '(?:[^']*/)?(?P<pkg>\w+)/(?P<kind>msg|srv|action)/"
                      r"(?P<name>\w+)\.json'")
_KEY_ERROR = re.compile(r"^KeyError: '(?P<pkg>\w+)'")
_NOT_FOUND = re.compile(r'provided by "(?P<a>[^"]+)"|Could NOT find (?P<b>\S+)|'
                        r'By not providing "Find(?P<c>\S+)\.cmake"')
_COMPILER = re.compile(r"^(?P<file>[^\s:][^:]*):(?P<line>\d+):(?:(?P<col>\d+):)? (?:fatal )?error: "
                       r"(?P<msg>.*)$")
_LINKER = re.compile(r"undefined reference to .*$")
#: ament_python_install_package(X) where rosidl_generate_interfaces() already installs Python package X
_PY_CLASH = re.compile(r'target "ament_cmake_python_(?:copy|symlink)_(?P<name>\w+)" because another target')
_EXC_LINE = re.compile(r"^(?P<exc>[A-Za-z_][\w.]*(?:Error|Exception|Exit|Interrupt|Warning))"
                       r"(?::\s*(?P<msg>.*))?$")
_FRAME = re.compile(r'^\s*File "(?P<file>[^"]+)", line (?P<line>\d+)')
_ERROR_WORD = re.compile(r"(^error\b|^ERROR\b|: error\b|\berror:)", re.I)


def _rosidl(pkg_dir: Path, texts: list[str]) -> Diagnosis | None:
    for t in texts:
        if m := _ROSIDL_FIELD.search(t):
            rel, n = _locate_definition(pkg_dir, m["msg"], m["line"])
            err = m["err"]
            message = _first_sentence(err)
            bad = re.match(r"'(\w+)' is an invalid message name", err)
            if bad and bad[1] in _TYPE_HINTS:
                message += f"; use {_TYPE_HINTS[bad[1]]}"
            if re.match(r"'[^']*,[^']*' is an invalid field name", err):
                message += "; declare one field per line"
            return Diagnosis(f"{rel}:{n or '?'}: {message}", [f"  {m['line'].strip()}", err])
        if m := _ROSIDL_WITH.search(t):
            rel, n = _locate_definition(pkg_dir, m["msg"], m["line"])
            return Diagnosis(f"{rel}:{n or '?'}: '{m['line'].strip()}' is not a field definition "
                             "(expected '<type> <name>')", [f"  {m['line'].strip()}"])
    for t in texts:
        if m := _ROSIDL_EXC.search(t):         # no line quoted: the file when it is the only one
            kind = next((k for k in ("msg", "srv", "action")
                         if any(f"convert_{k}_to_idl" in x for x in texts)), "")
            files = [p for p in _interface_files(pkg_dir) if kind and p.suffix == f".{kind}"]
            where = str(files[0].relative_to(pkg_dir)) if len(files) == 1 else ""
            quoted = re.findall(r"'([^']+)'", m["msg"])[:1]
            if where and quoted:
                where += next((f":{n}" for n, _s, text in _definition_lines(files[0])
                               if quoted[0] in text), "")
            return Diagnosis(_at(where, _first_sentence(m["msg"])))
    return None


def _unknown_type(pkg_dir: Path, own: str, lines: list[str], avail: Availability) -> Diagnosis | None:
    for ln in lines:
        if m := _NO_JSON.search(ln):
            where, text = _locate_type_use(pkg_dir, own, m["pkg"], m["name"])
            shown = m["name"] if m["pkg"] == own else f"{m['pkg']}/{m['name']}"
            why = (f"this package's rosidl_generate_interfaces() lists no {m['name']}.msg"
                   if m["pkg"] == own else f"{m['pkg']} has no message {m['name']}")
            return Diagnosis(_at(where, f"unknown type '{shown}'; {why}"), [f"  {text}"])
        if (m := _KEY_ERROR.match(ln.strip())) and any("rosidl_generator" in x for x in lines):
            pkg = m["pkg"]
            where, text = _locate_type_use(pkg_dir, own, pkg, None)
            typ = f"type '{text.split()[0]}'" if text else f"a type from {pkg}"
            if avail.available(pkg):
                fix = f"DEPENDENCIES {pkg} in rosidl_generate_interfaces() and find_package({pkg} REQUIRED)"
                return Diagnosis(_at(where, f"{typ} needs {fix}"), [f"  {text}", ln.strip()])
            return Diagnosis(lacks(pkg, _at(where, typ)), [f"  {text}", ln.strip()], [pkg])
    return None


def _cmake(errors: list[CMakeError], avail: Availability) -> Diagnosis | None:
    if not errors:
        return None
    for e in errors:
        m = _NOT_FOUND.search(" ".join(e.paragraphs))
        if not m:
            continue
        dep = m["a"] or m["b"] or m["c"]
        where = _at(e.location, f"find_package({dep})")
        if dep in avail.workspace:
            return Diagnosis(f"{where} ran before {dep} was built: declare <depend>{dep}</depend> "
                             "in package.xml", e.paragraphs[:2])
        if ROS_NAME.match(dep) and not avail.installed(dep):
            return Diagnosis(lacks(dep, where), e.paragraphs[:1], [dep])
    for e in errors:
        if m := _PY_CLASH.search(" ".join(e.paragraphs)):
            return Diagnosis(_at(e.location, f"ament_python_install_package({m['name']}) installs a Python "
                                 f"package named like the one rosidl_generate_interfaces() installs for this "
                                 f"package's interfaces, which ROS 2 Jazzy cannot build "
                                 f"(ros2/rosidl_python#141): give the module another name"), e.paragraphs[:1])
    e = errors[0]
    paras = [p for p in e.paragraphs if not p.startswith("execute_process(")]
    if len(paras) < len(e.paragraphs):  # a tool CMake ran failed: its exception says why
        paras = [p for p in paras if _EXC_LINE.match(p)][-1:] + paras
    first = paras[0] if paras else "CMake Error"
    return Diagnosis(_at(e.location, _clip(first)), [_clip(p) for p in paras[1:3]])


def _compiler(pkg_dir: Path, lines: list[str]) -> Diagnosis | None:
    for i, ln in enumerate(lines):
        if m := _COMPILER.match(ln):
            path = Path(m["file"])
            try:
                path = path.relative_to(pkg_dir)
            except ValueError:
                pass
            col = f":{m['col']}" if m["col"] else ""
            return Diagnosis(f"{path}:{m['line']}{col}: error: {m['msg']}",
                             [x.rstrip() for x in lines[i + 1:i + 3] if not _COMPILER.match(x)])
    for ln in lines:
        if m := _LINKER.search(ln):
            return Diagnosis(f"link error: {m[0]}", [ln.strip()])
    return None


def _traceback(pkg_dir: Path, lines: list[str]) -> Diagnosis | None:
    for i in range(len(lines) - 1, -1, -1):
        m = _EXC_LINE.match(lines[i])
        if not m or m["exc"].endswith("Warning"):
            continue
        where = ""
        for ln in reversed(lines[:i]):
            f = _FRAME.match(ln)
            if f and (Path(f["file"]).name == "setup.py" or _inside(Path(f["file"]), pkg_dir)):
                where = f"{_rel(Path(f['file']), pkg_dir)}:{f['line']}"
                break
            if ln.startswith("Traceback"):
                break
        return Diagnosis(_at(where, lines[i].strip()), [x.rstrip() for x in lines[max(0, i - 2):i]])
    return None


def _inside(path: Path, pkg_dir: Path) -> bool:
    return path.is_absolute() and path.resolve().is_relative_to(pkg_dir.resolve())


def _rel(path: Path, pkg_dir: Path) -> str:
    return str(path.resolve().relative_to(pkg_dir.resolve())) if _inside(path, pkg_dir) else path.name


def _clip(text: str, limit: int = 200) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _setup_py(pkg_dir: Path, log: str, env: Mapping[str, str]) -> Diagnosis | None:
    setup = pkg_dir / "setup.py"
    if not setup.is_file():
        return Diagnosis("no setup.py in the package (ament_python packages need one)")
    try:
        compile(setup.read_bytes(), str(setup), "exec")
    except SyntaxError as exc:
        return Diagnosis(f"setup.py:{exc.lineno}: SyntaxError: {exc.msg}", [f"  {(exc.text or '').strip()}"])
    except ValueError:
        pass
    if log.strip() and not ("CalledProcessError" in log and "run_setup" in log):
        return None                   # setup.py ran; the build step's own log says what failed
    stderr = _run_setup_py(pkg_dir, env)
    return _traceback(pkg_dir, stderr.splitlines()) if stderr else None


def _run_setup_py(pkg_dir: Path, env: Mapping[str, str]) -> str:
    """stderr of ``setup.py --name``: colcon ran it the same way but kept no per-package copy.
    Student code: run in a jail that sees the package read-only (grader.sandbox)."""
    run, _out, err = run_jailed_capture([sys.executable, "setup.py", "--name"], env=env, cwd=pkg_dir,
                                        ro=[pkg_dir], timeout_s=SETUP_PY_TIMEOUT_S, memory_mb=1024,
                                        pids=256, name="setup-py")
    if run.timed_out:
        return f"TimeoutError: setup.py did not finish within {SETUP_PY_TIMEOUT_S}s"
    return err if run.returncode else ""


def diagnose(name: str, build_type: str, pkg_dir: Path, log: str, avail: Availability,
             env: Mapping[str, str]) -> Diagnosis:
    """The reason ``name`` (sources in ``pkg_dir``, colcon log text ``log``) failed."""
    d = _diagnose(name, build_type, pkg_dir, log, avail, env)
    d.reason = _clip(d.reason, 300)
    d.detail = [_clip(x, 300) for x in d.detail]
    return d


def _diagnose(name: str, build_type: str, pkg_dir: Path, log: str, avail: Availability,
              env: Mapping[str, str]) -> Diagnosis:
    lines = log.splitlines()
    if build_type in ("ament_python", "python") and (d := _setup_py(pkg_dir, log, env)):
        return d
    errors = cmake_errors(lines)
    texts = [p for e in errors for p in e.paragraphs] + lines
    for rule in (lambda: _rosidl(pkg_dir, texts), lambda: _unknown_type(pkg_dir, name, lines, avail),
                 lambda: _cmake(errors, avail), lambda: _compiler(pkg_dir, lines),
                 lambda: _traceback(pkg_dir, lines)):
        if d := rule():
            return d
    for ln in lines:
        if _ERROR_WORD.search(ln) and not ln.startswith("ninja: build stopped"):
            return Diagnosis(_at("setup.py" if build_type == "ament_python" else "", ln.strip()))
    tail = [ln.rstrip() for ln in lines if ln.strip()][-DETAIL_LINES:]
    return Diagnosis("the build step failed without an error message; see the log", tail)
