"""Student launch files: what a rubric's ``launch:`` process starts.

``resolve_launch`` turns ``{package: turtle_goal, launch: goal.launch.py}`` into the OS processes
the scenario child starts (:class:`~grader.scenario.runspec.LaunchedProcess`), at resolution time,
in the parent, so ``run.json`` shows exactly what will run:

* Without a system ROS 2 (PyPI wheels have no ``launch``/``launch_ros``), the launch file is run
  in a subprocess against the grader's implementation of the commonly used API subset
  (``grader.launch.entities``); each declared node becomes a process of its own, started by the
  grader's runner like any student process. A ``turtlesim turtlesim_node`` node is the grader's
  reference simulator, under the node name the launch file gives it.
* With a sourced ROS 2 Jazzy that has ``ros2 launch``, the real ``ros2 launch`` runs the file as
  one process; an overlay package puts the reference simulator (or, when the scenario already
  runs it, a stand-in that waits) where ``turtlesim turtlesim_node`` is looked up.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

from grader.errors import GraderError
from grader.scenario.model import Process, param_text
from grader.scenario.runspec import LaunchedProcess

DESCRIBE_TIMEOUT_S = 30.0
SIM_PACKAGE, SIM_EXECUTABLE = "turtlesim", "turtlesim_node"


@dataclass
class LaunchResolution:
    processes: list[LaunchedProcess]
    sim_node: str | None = None          # the node name the launch file gives turtlesim
    notes: list[str] = field(default_factory=list)
    installed: bool = False              # found where `ros2 launch <package> <file>` looks
    file: str = ""                       # the launch file's name (``launch:`` may be a pattern)


#: what a launch file is called (``app.launch.py``, ``app_launch.py``, ``app.launch.xml`` ...)
LAUNCH_FILE = re.compile(r"(^|[._])launch\.(py|xml|ya?ml)$")


def launch_files(build: Any, package: str) -> list[str]:
    """Names of ``package``'s launch files: installed in its share folder or in its sources."""
    found: set[str] = set()
    share = build.install / package / "share" / package
    if share.is_dir():
        found |= {p.name for p in share.rglob("*") if p.is_file() and LAUNCH_FILE.search(p.name)}
    source = _package_source(build, package)
    if source is not None:
        found |= {p.name for p in source.rglob("*") if p.is_file() and LAUNCH_FILE.search(p.name)}
    return sorted(found)


def _package_source(build: Any, package: str) -> Path | None:
    for manifest in sorted((build.root / "src").rglob("package.xml")):
        text = manifest.read_text(errors="replace")
        if f"<name>{package}</name>" in text.replace(" ", ""):
            return manifest.parent
    return None


def _matches(folder: Path, name: str) -> list[Path]:
    """Files under ``folder`` called ``name``, or matching it when it is a pattern (``*launch.py``):
    one per file name (the first found)."""
    hits = sorted(p for p in folder.rglob(name) if p.is_file())
    if not any(c in name for c in "*?["):
        return hits
    first: dict[str, Path] = {}
    for hit in hits:
        if LAUNCH_FILE.search(hit.name):
            first.setdefault(hit.name, hit)
    return sorted(first.values(), key=lambda p: p.name)


def find_launch_file(build: Any, package: str, name: str) -> tuple[Path | None, str]:
    """The launch file as ``ros2 launch`` finds it (in the package's installed share folder),
    else in the package's sources (with a note: setup.py does not install it). ``name`` may be
    a pattern (``*launch.py``: the lab does not name the file): the one launch file matching it;
    several are an error naming them."""
    def one(hits: list[Path]) -> Path | None:
        if len(hits) > 1 and any(c in name for c in "*?["):
            raise GraderError(f"package '{package}' has {len(hits)} launch files ({', '.join(h.name for h in hits)}) "
                              "and the lab does not name the one that starts the application: keep only that one")
        return hits[0] if hits else None

    share = build.install / package / "share" / package
    hit = one(_matches(share, name)) if share.is_dir() else None
    if hit is not None:
        return hit, ""
    source = _package_source(build, package)
    if source is not None:
        found = one(_matches(source, name))
        if found is not None:
            rel = found.relative_to(build.root)
            shown = found.name
            pkg = build.packages.get(package)
            if pkg is not None and pkg.status != "built":
                return found, (f"package '{package}' was not built, so {shown} is not installed; "
                               f"the grader read {rel}.")
            if pkg is not None and pkg.build_type.startswith("ament_cmake"):
                how = (f"is not installed by {package}'s CMakeLists.txt (add install(DIRECTORY launch "
                       "DESTINATION share/${PROJECT_NAME}))")
            else:
                how = (f"is not installed by {package}'s setup.py (add it to data_files, "
                       f"e.g. share/{package}/launch)")
            return found, f"{shown} {how}; `ros2 launch` would not find it. The grader used {rel}."
    return None, ""


def describe_launch(path: Path, arguments: dict[str, str], env: dict[str, str]) -> list[dict[str, Any]]:
    """Run ``grader.launch.describe`` on a launch file (student code: in a subprocess)."""
    argv = [sys.executable, "-m", "grader.launch.describe", str(path),
            *(f"{k}:={v}" for k, v in arguments.items())]
    # the launch file is student code: jailed (grader.sandbox), seeing only its builds and the
    # grader package (the launch/launch_ros stand-ins), with no network
    from grader.sandbox.oneshot import build_trees, run_jailed_capture  # noqa: PLC0415 - launch loads in every scenario child process; sandbox.oneshot only on this path

    package = Path(__file__).resolve().parents[1]
    run, stdout, stderr = run_jailed_capture(
        argv, env=env, cwd=path.parent, ro=[*build_trees(env), path.parent, package],
        python_path=[package.parent], timeout_s=DESCRIBE_TIMEOUT_S, memory_mb=2048, pids=256, name="launch")
    if run.timed_out:
        raise GraderError(f"{path.name}: loading the launch file took longer than "
                          f"{DESCRIBE_TIMEOUT_S:.0f} s")
    proc = subprocess.CompletedProcess(argv, cast(int, run.returncode), stdout, stderr)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    try:
        doc = json.loads(lines[-1])
    except (IndexError, json.JSONDecodeError):
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        raise GraderError(f"{path.name}: the launch file could not be loaded: {' / '.join(tail)}") from None
    if "error" in doc:
        raise GraderError(doc["error"])
    return doc["entities"]


def node_ros_args(entity: dict[str, Any]) -> list[str]:
    """``--ros-args`` for a launch ``Node``: name, namespace, parameters, remappings."""
    out: list[str] = []
    if entity.get("name"):
        out += ["-r", f"__node:={entity['name']}"]
    if entity.get("namespace"):
        ns = entity["namespace"]
        out += ["-r", f"__ns:={ns if ns.startswith('/') else '/' + ns}"]
    for params in entity.get("parameters", []):
        if isinstance(params, dict):
            for key, value in params.items():
                out += ["-p", f"{key}:={param_text(value)}"]
        else:
            out += ["--params-file", str(params)]
    for old, new in entity.get("remappings", []):
        out += ["-r", f"{old}:={new}"]
    out += list(entity.get("ros_arguments", []))
    return ["--ros-args", *out] if out else []


def resolve_launch(proc: Process, build: Any, *, sim_in_scenario: bool) -> LaunchResolution:
    """The processes ``proc``'s launch file starts (errors become a process with ``error``)."""
    assert proc.launch and proc.package
    try:
        path, note = find_launch_file(build, proc.package, proc.launch)
    except GraderError as exc:
        return LaunchResolution([LaunchedProcess(name=proc.name, process=proc.name, error=str(exc))])
    if path is None:
        what = (f"no launch file ({proc.launch})" if any(c in proc.launch for c in "*?[")
                else f"launch file {proc.launch} not found")
        return LaunchResolution([LaunchedProcess(name=proc.name, process=proc.name, error=(
            f"{what} in package '{proc.package}' (installed share/{proc.package} or its sources)"))])
    notes = [note] if note else []
    installed = not note
    try:
        entities = describe_launch(path, dict(proc.launch_arguments), build.env())
    except GraderError as exc:
        return LaunchResolution([LaunchedProcess(name=proc.name, process=proc.name, error=str(exc))],
                                notes=notes, installed=installed, file=path.name)
    if system_ros_launch_available():
        resolution = _real_ros2_launch(proc, build, path, entities, sim_in_scenario, notes)
        resolution.installed, resolution.file = installed, path.name
        return resolution
    out: list[LaunchedProcess] = []
    sim_node = None
    used: set[str] = set()
    for entity in entities:
        label = entity.get("name") or entity.get("executable") or (entity.get("cmd") or ["process"])[0]
        name = _unique(f"{proc.name}.{Path(str(label)).name}", used)
        if entity["kind"] == "node" and (entity.get("package"), entity["executable"]) == (SIM_PACKAGE, SIM_EXECUTABLE):
            sim_node = entity.get("name") or "turtlesim"
            declared: dict[str, Any] = dict(name=name, process=proc.name, node_name=sim_node, package=SIM_PACKAGE,
                            executable=SIM_EXECUTABLE)
            if sim_in_scenario:
                notes.append(f"{entity['at']}: turtlesim_node '{sim_node}' is the grader's reference "
                             "simulator (already running in this scenario)")
                out.append(LaunchedProcess(**declared, stand_in=True))
                continue
            from grader.sim import sim_argv  # noqa: PLC0415 - launch loads in every scenario child process; sim only on this path
            argv = sim_argv(ros_args=node_ros_args(entity)[1:])
            out.append(LaunchedProcess(**declared, argv=tuple(argv), start_delay=entity["delay"],
                                       env=entity.get("env", {})))
            continue
        if entity["kind"] == "process":
            out.append(LaunchedProcess(name=name, process=proc.name, argv=tuple(entity["cmd"]),
                                       start_delay=entity["delay"], env=entity.get("env", {})))
            continue
        try:
            if not entity.get("package"):
                raise GraderError(f"{entity['at']}: Node(executable={entity['executable']!r}) has no package")
            # found as launch_ros's Node finds it (lib/<package>/ of its prefix in the ament index)
            argv = build.argv(entity["package"], entity["executable"], None,
                              [*entity.get("arguments", []), *node_ros_args(entity)], nested=False)
            out.append(LaunchedProcess(name=name, process=proc.name, argv=tuple(argv),
                                       node_name=entity.get("name"), package=entity.get("package"),
                                       executable=entity["executable"], start_delay=entity["delay"],
                                       env=entity.get("env", {})))
        except GraderError as exc:
            out.append(LaunchedProcess(name=name, process=proc.name, node_name=entity.get("name"),
                                       package=entity.get("package"), executable=entity["executable"],
                                       error=f"{entity['at']}: {exc}"))
    if not any(not lp.stand_in for lp in out):
        out.append(LaunchedProcess(name=proc.name, process=proc.name,
                                   error=f"{path.name} starts no node besides turtlesim"))
    return LaunchResolution(out, sim_node, notes, installed, path.name)


def _unique(name: str, used: set[str]) -> str:
    candidate, n = name, 2
    while candidate in used:
        candidate, n = f"{name}-{n}", n + 1
    used.add(candidate)
    return candidate


# ----------------------------------------------------------------------- system ROS 2 launch
def system_ros_launch_available() -> bool:
    """A sourced ROS 2 with ``ros2 launch`` (the real thing is used then)."""
    from grader.rosenv import ros_mode  # noqa: PLC0415 - launch loads in every scenario child process; rosenv only on this path

    if os.environ.get("GRADER_OWN_LAUNCH") or ros_mode() != "system" or not shutil.which("ros2"):
        return False
    try:
        import launch  # noqa: F401, PLC0415 - only asks whether a real ROS launch is installed
    except ImportError:
        return False
    return True


def _real_ros2_launch(proc: Process, build: Any, path: Path, entities: list[dict[str, Any]],
                      sim_in_scenario: bool, notes: list[str]) -> LaunchResolution:
    overlay = sim_overlay(build.root / "grader-sim-overlay")
    sim_node = next((e.get("name") or "turtlesim" for e in entities if e["kind"] == "node"
                     and (e.get("package"), e["executable"]) == (SIM_PACKAGE, SIM_EXECUTABLE)), None)
    env = {"AMENT_PREFIX_PATH": os.pathsep.join([str(overlay), *build.env().get("AMENT_PREFIX_PATH", "").split(os.pathsep)])}
    if sim_in_scenario:
        env["GRADER_SIM_PROVIDED"] = "1"
    argv = [shutil.which("ros2") or "ros2", "launch", str(path),
            *(f"{k}:={v}" for k, v in proc.launch_arguments.items())]
    notes = notes + ["run with the system's ros2 launch; turtlesim_node is the grader's reference simulator"]
    return LaunchResolution([LaunchedProcess(name=proc.name, process=proc.name, argv=tuple(argv), env=env)],
                            sim_node, notes)


def sim_overlay(root: Path) -> Path:
    """An install prefix whose ``turtlesim turtlesim_node`` is the reference simulator."""
    exe = root / "lib" / SIM_PACKAGE / SIM_EXECUTABLE
    if not exe.exists():
        (root / "share" / "ament_index" / "resource_index" / "packages").mkdir(parents=True, exist_ok=True)
        (root / "share" / "ament_index" / "resource_index" / "packages" / SIM_PACKAGE).write_text("")
        (root / "share" / SIM_PACKAGE).mkdir(parents=True, exist_ok=True)
        exe.parent.mkdir(parents=True, exist_ok=True)
        exe.write_text(f'#!/bin/sh\nif [ -n "$GRADER_SIM_PROVIDED" ]; then exec sleep infinity; fi\n'
                       f'exec "{sys.executable}" -m grader.sim "$@"\n')
        exe.chmod(0o755)
    return root
