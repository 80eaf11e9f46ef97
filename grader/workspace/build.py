"""`grader build`: colcon-build a submission in an isolated, content-addressed build area.

Never builds inside the student's folder. Results are cached by the hash of the staged sources
(plus the grader's ROS mode), so regrading an unchanged submission skips colcon entirely. One
broken package does not stop the others (``--continue-on-error``). Each package's status is
colcon's own result for it (``colcon_events``): built, failed, or skipped because a package it
depends on failed. A failed package carries the one line that explains it (``diagnose``) and
the path of its full log; a skipped one names the package that failed.

Below the workspace cache, packages are cached one by one (``package_cache``): a package whose
sources and workspace dependencies are identical to one the instructor supplies (the rubric's
``support:`` packages, e.g. the lab's interface package, untouched by most of a class) is taken
from that package's own build instead of built again for every submission.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Sequence

from grader.cache import default_cache_dir
from grader.cache.code import build_code
from grader.cache.environment import build_tools
from grader.cache.locks import Holds, build_lock, locked, use_lock
from grader.sandbox import allotment
from grader.errors import GraderError
from grader.rosenv import PY_SITE, child_env
from grader.sandbox.oneshot import run_jailed
from grader.workspace.colcon_events import JobOutcome, read_events
from grader.workspace.executables import (INDEX, command, executable_paths, find_executable,
                                          package_prefix, search_path)
from grader.workspace.diagnose import DETAIL_LINES, Availability, Diagnosis, diagnose
from grader.workspace.package_cache import (CachedPackage, PackageCache, copy_installs, package_keys,
                                            stage_support)
from grader.workspace.source import PackageSource, stage_sources, tree_digest
from grader.workspace.trusted_interfaces import TrustedInterfaces, build_trusted_interfaces

BUILD_TIMEOUT_S = 900
BUILD_MEMORY_MB = 6144     # colcon + compilers of one submission together (cgroup)
BUILD_PIDS = 2048
TIMED_OUT = -1
__all__ = ["BuildResult", "PackageBuild", "build_workspace", "default_cache_dir", "load_result"]


@dataclass
class PackageBuild:
    """One package's build, as colcon reported it."""

    name: str
    build_type: str
    status: str                        # built | failed | skipped
    reason: str = ""                   # one line: why it is not built ("srv/SetGoal.srv:1: ...")
    log_excerpt: str = ""              # indented block: reason, the log lines behind it, log path
    log: str = ""                      # the package's full colcon log (or build.log)
    blocked_by: list[str] = field(default_factory=list)       # skipped: the failed packages it needs
    missing_dependencies: list[str] = field(default_factory=list)  # neither installed nor submitted
    executables: dict[str, str] = field(default_factory=dict)   # ros2 pkg executables: name -> lib/<pkg>/...
    reused_from: str = ""              # build area whose install of it was copied (package cache)

    def problem(self) -> str:
        """One line for a student: which package, and why it cannot be run."""
        if self.status == "failed":
            return f"package '{self.name}' failed to build: {self.reason}"
        return f"package '{self.name}' was not built: {self.reason}"


@dataclass
class BuildResult:
    """What a build produced, and how to run its executables."""

    source: str
    digest: str
    root: Path                         # build area: src/, build/, install/, log/, build.log
    packages: dict[str, PackageBuild]
    cached: bool = False
    duration_s: float = 0.0
    warnings: list[str] = field(default_factory=list)   # what staging skipped (not cached: per submission)
    #: the grader's own builds of the interface packages, for grader processes (trusted_interfaces)
    interfaces: TrustedInterfaces = field(default_factory=TrustedInterfaces)

    @property
    def install(self) -> Path:
        return self.root / "install"

    @property
    def ok(self) -> bool:
        return all(p.status == "built" for p in self.packages.values())

    @property
    def failed(self) -> list[str]:
        """Packages that are not built: failed ones and the ones skipped because of them."""
        return [n for n, p in self.packages.items() if p.status != "built"]

    @property
    def build_log(self) -> Path:
        return self.root / "build.log"

    def prefixes(self) -> list[Path]:
        """Install prefixes of the built packages (what ``source install/setup.bash`` adds)."""
        return [self.install / n for n, p in self.packages.items() if p.status == "built"]

    def interface_prefixes(self) -> list[Path]:
        """Install prefixes of the trusted builds of its interface packages: what grader
        processes import the students' types from (never ``prefixes()``)."""
        return [Path(p) for _, p in sorted(self.interfaces.prefixes.items())]

    def env(self, **kwargs) -> dict[str, str]:
        return child_env(prefixes=self.prefixes(), **kwargs)

    # -- executables -------------------------------------------------------------------------
    def require_package(self, package: str) -> PackageBuild:
        pkg = self.packages.get(package)
        if pkg is None:
            raise GraderError(f"package '{package}' is not in the submission "
                              f"(packages found: {', '.join(sorted(self.packages)) or 'none'}).")
        if pkg.status != "built":
            details = pkg.log_excerpt.splitlines()[1:]      # its first line is the reason
            raise GraderError("\n".join([pkg.problem(), *details]))
        return pkg

    def executable(self, package: str, name: str, *, nested: bool = True) -> Path:
        """The file ``ros2 run package name`` runs with this build sourced (``grader.workspace.
        executables``); ``nested=False``: the one a launch file's ``Node`` runs."""
        if package in self.packages:
            self.require_package(package)
        prefixes = search_path(self.env())
        if package_prefix(package, prefixes) is None:
            if package in self.packages:
                raise GraderError(
                    f"package '{package}' is built but not in the ament index (its install has no "
                    f"{INDEX}/{package}), so `ros2 run` and `ros2 launch` cannot find it: install "
                    f"resource/{package} there (in setup.py: data_files=[('share/ament_index/resource_index/"
                    f"packages', ['resource/{package}'])])")
            raise GraderError(f"package '{package}' is not in the submission "
                              f"(packages found: {', '.join(sorted(self.packages)) or 'none'}).")
        return find_executable(package, name, prefixes, nested=nested)

    def argv(self, package: str, executable: str | None = None, module: str | None = None,
             args: list[str] | tuple[str, ...] = (), *, nested: bool = True) -> list[str]:
        """argv to run a package's executable as ``ros2 run`` would, or a ``module[:func]`` of it.

        ``executable``: found in the ament index and ``<prefix>/lib/<package>/`` like ``ros2 run``
        finds it (console scripts, CMake ``install(PROGRAMS)`` scripts and binaries alike) and
        started by its ``#!`` line, Python scripts with the ROS Python (``executables.command``).
        ``module`` (tried when the executable is missing: students name scripts freely) finds
        ``turtle_control.goal_publisher:main`` in the package's installed Python modules, whatever
        its script is called, and runs it as its console script would.
        """
        problem = None
        if executable:
            try:
                return command(self.executable(package, executable, nested=nested), args)
            except GraderError as exc:
                if not module:
                    raise
                problem = exc
        pkg = self.require_package(package)
        mod, _, func = (module or "").partition(":")
        site = self.install / package / PY_SITE / mod.replace(".", "/")
        if site.with_suffix(".py").is_file() or (site / "__init__.py").is_file():
            return [sys.executable, "-m", "grader.workspace.launch", f"{mod}:{func or 'main'}",
                    executable or mod.rsplit(".", 1)[-1], *args]
        if problem is not None:
            raise problem
        raise GraderError(f"package '{pkg.name}' has no Python module '{mod}' (looked for {PY_SITE}/"
                          f"{mod.replace('.', '/')}.py in its install)")


def _listing(prefix: Path, package: str) -> dict[str, str]:
    """``ros2 pkg executables`` of a built package: name -> path under its prefix."""
    found = package_prefix(package, [prefix])
    return {p.name: str(p.relative_to(prefix)) for p in executable_paths(package, found)} if found else {}


def _colcon_env() -> dict[str, str]:
    env = child_env()
    env.pop("ROS_DOMAIN_ID", None)
    env["COLCON_HOME"] = env.get("COLCON_HOME", str(Path(sys.prefix) / "colcon-home"))
    env.pop("PYTHONUNBUFFERED", None)
    return env


def _run_colcon(root: Path, log_file: Path, skip: Sequence[str] = ()) -> int:
    """colcon build in the build area; student code (setup.py, CMake) runs here, so in a jail
    that can write only build/, install/ and log/ and has no network (grader.sandbox)."""
    cmake_args = [f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF",
                  "-DCMAKE_BUILD_TYPE=Release"]
    if shutil.which("ninja"):
        cmake_args += ["-G", "Ninja"]
    cmd = [sys.executable, "-m", "colcon", "--log-base", "log", "build",
           "--base-paths", "src", "--build-base", "build", "--install-base", "install",
           "--continue-on-error", "--parallel-workers", str(allotment.current().slots),
           "--event-handlers", "console_cohesion+", "console_direct-", "status-",
           "event_log+", "log+",        # events.log and per-package logs: the status is read from them
           *(["--packages-skip", *skip] if skip else []),     # reused: in install/ already
           "--cmake-args", *cmake_args]
    log_file.write_bytes(("$ " + " ".join(cmd) + "\n").encode())
    run = run_jailed(cmd, env=_colcon_env(), cwd=root, stdout=log_file, ro=[root / "src"],
                     rw=[root / "build", root / "install", root / "log"], timeout_s=BUILD_TIMEOUT_S,
                     memory_mb=BUILD_MEMORY_MB, pids=BUILD_PIDS, name="build")
    with open(log_file, "ab") as log:
        for hit in run.limits_hit:
            log.write(f"\n[grader] build: {hit}\n".encode())
        if run.timed_out:
            log.write(f"\ncolcon build timed out after {BUILD_TIMEOUT_S}s\n".encode())
            return TIMED_OUT
    return run.returncode if run.returncode is not None else TIMED_OUT


def _package_log(root: Path, name: str) -> Path:
    log = root / "log" / "latest_build" / name / "stdout_stderr.log"
    return log if log.is_file() else root / "build.log"


def _not_built_by_colcon(root: Path, name: str) -> Diagnosis:
    """Why colcon never queued ``name``: usually a package.xml it could not read."""
    log_dir = root / "log" / "latest_build"
    all_log = log_dir / "logger_all.log"
    lines = all_log.read_text(errors="replace").splitlines() if all_log.is_file() else []
    for i, ln in enumerate(lines):
        if "Failed to parse potential ROS package manifest" in ln and f"src/{name}'" in ln:
            why = [x.strip() for x in lines[i + 1:i + 1 + DETAIL_LINES] if x.strip()]
            why = why[:next((k for k, x in enumerate(why) if x.startswith("[")), len(why))]
            return Diagnosis(f"package.xml: {why[0] if why else 'colcon could not read it'}", why[1:])
    build_log = root / "build.log"
    text = build_log.read_text(errors="replace") if build_log.exists() else ""
    if not (log_dir / "events.log").is_file():        # colcon stopped before building anything
        last = [ln.strip() for ln in text.splitlines() if ln.strip()][-1:] or ["no output"]
        return Diagnosis(f"colcon did not run: {last[0][:200]}")
    said = [ln.strip() for ln in text.splitlines() if name in ln and ("WARNING" in ln or "ERROR" in ln)]
    return Diagnosis("colcon did not build it (see build.log)", said[:DETAIL_LINES])


def _excerpt(first: str, detail: list[str], log: Path | None) -> str:
    lines = ["    " + first] + ["      " + d for d in detail[:DETAIL_LINES] if d.strip()]
    if log is not None:
        lines.append(f"    log: {log}")
    return "\n".join(lines)


def _failure(root: Path, pkg: PackageSource, job: JobOutcome, timed_out: bool,
             avail: Availability, env: dict[str, str]) -> tuple[Diagnosis, Path]:
    """Why ``pkg`` failed, and the log that shows it."""
    log = _package_log(root, pkg.name)
    if job.rc is not None:
        text = log.read_text(errors="replace") if log.name != "build.log" else ""
        if "CalledProcessError" in text and "run_setup" in text:
            log = root / "build.log"    # colcon printed setup.py's own traceback only there
        return diagnose(pkg.name, pkg.build_type, root / "src" / pkg.name, text, avail, env), log
    if timed_out:
        return Diagnosis(f"colcon build timed out after {BUILD_TIMEOUT_S}s while building it"), log
    if not job.queued:
        return _not_built_by_colcon(root, pkg.name), log
    return Diagnosis("colcon stopped before it finished (see build.log)"), log


def _package_results(root: Path, staged: list[PackageSource], *, timed_out: bool,
                     reused: dict[str, CachedPackage] | None = None) -> dict[str, PackageBuild]:
    """Each package's result from colcon's events: built, failed (with why) or skipped (by what);
    ``reused`` packages were taken from an earlier build (colcon skipped them)."""
    reused = reused or {}
    env = _colcon_env()
    avail = Availability([p.name for p in staged], env)
    jobs = read_events(root / "log" / "latest_build" / "events.log", [p.name for p in staged])
    out: dict[str, PackageBuild] = {}
    for pkg in staged:                 # built and failed first: skipped ones name the failed ones
        job = jobs[pkg.name]
        missing = avail.missing_from_manifest(root / "src" / pkg.name / "package.xml")
        if pkg.name in reused:
            out[pkg.name] = PackageBuild(pkg.name, pkg.build_type, "built", missing_dependencies=missing,
                                         executables=_listing(root / "install" / pkg.name, pkg.name),
                                         reused_from=str(reused[pkg.name].root))
        elif job.succeeded:
            prefix = root / "install" / pkg.name
            out[pkg.name] = PackageBuild(pkg.name, pkg.build_type, "built", missing_dependencies=missing,
                                         executables=_listing(prefix, pkg.name))
        elif not job.skipped and (job.rc is not None or job.started or not job.queued):
            d, log = _failure(root, pkg, job, timed_out, avail, env)
            out[pkg.name] = PackageBuild(pkg.name, pkg.build_type, "failed", d.reason,
                                         _excerpt(d.reason, d.detail, log), str(log),
                                         missing_dependencies=sorted(set(missing) | set(d.missing)))
    for pkg in staged:
        if pkg.name in out:
            continue
        job = jobs[pkg.name]
        blocked = [d for d in job.dependencies if d in out and out[d].status == "failed"]
        if blocked:
            first = out[blocked[0]].reason
            why = first if len(blocked) == 1 else f"'{blocked[0]}': {first}"
            reason = f"it depends on {', '.join(repr(b) for b in blocked)}, which failed ({why})"
        elif timed_out:
            reason = f"colcon build timed out after {BUILD_TIMEOUT_S}s before it started"
        else:
            reason = "a package it depends on was not built"
        out[pkg.name] = PackageBuild(pkg.name, pkg.build_type, "skipped", reason,
                                     _excerpt("not built: " + reason, [], None),
                                     blocked_by=blocked,
                                     missing_dependencies=avail.missing_from_manifest(
                                         root / "src" / pkg.name / "package.xml"))
    return {p.name: out[p.name] for p in staged}


def build_support(support: dict[str, Path], cache_dir: Path | None = None,
                  holds: Holds | None = None) -> BuildResult | None:
    """Build a rubric's ``support`` packages on their own, as a trusted build whose packages
    every later submission identical in them takes instead of compiling them again (a cache hit
    when already built). ``grader gradescope-setup`` calls it when the image is made, so no
    submission pays for it; ``build_workspace`` calls it first thing (``holds``: the submission's
    holds, so its support build stays while it runs). None: nothing to build."""
    cache_dir = Path(cache_dir or default_cache_dir())
    cache_dir.mkdir(parents=True, exist_ok=True)
    with stage_support(support, cache_dir) as support_ws:
        if support_ws is None:
            return None
        return build_workspace(support_ws, cache_dir=cache_dir, trusted=True, holds=holds)


def build_workspace(submission: Path, *, cache_dir: Path | None = None,
                    support: dict[str, Path] | None = None, force: bool = False,
                    trusted: bool = False, holds: Holds | None = None) -> BuildResult:
    """Stage, hash and (unless cached) colcon-build ``submission``.

    Packages identical to a ``support`` package are taken from the support packages' own build
    (made once, the first time; see ``package_cache``), not with ``force``. ``trusted``: the
    sources are the instructor's (no student code runs in this build), so its packages may be
    shared with later builds. ``holds``: the build area, and the areas packages were copied
    from, stay held there (safe from ``grader cache prune``) until the caller closes it; without
    it, until this returns.

    The key (the area's folder name) is the staged sources' digest with the grader's build code
    (``grader.cache.code.build_code``) and the ROS, Python and build tools' versions
    (``grader.cache.environment.build_tools``): an upgrade of any of them builds again.
    """
    cache_dir = Path(cache_dir or default_cache_dir())
    cache_dir.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as own:
        holds = holds or own.enter_context(Holds())
        return _build(Path(submission), cache_dir, support, force, trusted, holds)


def _build(submission: Path, cache_dir: Path, support: dict[str, Path] | None, force: bool,
           trusted: bool, holds: Holds) -> BuildResult:
    if support and not force:
        try:
            build_support(support, cache_dir, holds=holds)
        except GraderError:
            pass                  # a support package that cannot be staged is built (and reported) below
    staging = cache_dir / f".staging-{os.getpid()}-{time.monotonic_ns()}"
    try:
        staging_result = stage_sources(submission, staging / "src", staging, support)
        staged = staging_result.packages
        extra = f"{build_code()}:{build_tools()['digest']}"
        digest = tree_digest(staging / "src", extra=extra)
        keys = package_keys(staged, extra)
        root = cache_dir / digest
        packages_cache = PackageCache(cache_dir)
        holds.hold(use_lock(root))               # before the lookup: a prune waits, or went first
        with locked(build_lock(root)):           # parallel graders build one digest once
            result_file = root / "result.json"
            if result_file.exists() and not force:
                result = load_result(result_file)
                result.source = str(submission)
                result.cached = True
                result.warnings = staging_result.warnings
                if trusted:
                    packages_cache.share(result, keys)      # e.g. after the index was cleared
                elif not all(Path(p).is_dir() for p in result.interfaces.prefixes.values()):
                    result.interfaces = build_trusted_interfaces(result, cache_dir, build_workspace)    # cleared meanwhile
                    result_file.write_text(json.dumps(_to_json(result), indent=1))
                return _with_interface_problems(result)
            if root.exists():
                shutil.rmtree(root)
            root.mkdir(parents=True)
            shutil.move(str(staging / "src"), root / "src")
            reused = {} if force else packages_cache.reusable(staged, keys, holds)
            copy_installs(root, reused)
            t0 = time.monotonic()
            if len(reused) < len(staged):
                rc = _run_colcon(root, root / "build.log", skip=sorted(reused))
            else:
                rc = 0
                (root / "build.log").write_text("every package is reused from an earlier build:\n" + "".join(
                    f"  {n}: {c.install}\n" for n, c in sorted(reused.items())))
            packages = _package_results(root, staged, timed_out=rc == TIMED_OUT, reused=reused)
            result = BuildResult(str(submission), digest, root, packages,
                                 duration_s=round(time.monotonic() - t0, 2), warnings=staging_result.warnings)
            if not trusted:      # grader processes import the students' types from their own build
                result.interfaces = build_trusted_interfaces(result, cache_dir, build_workspace)
            result_file.write_text(json.dumps(_to_json(result), indent=1))
            if trusted:
                packages_cache.share(result, keys)
            return _with_interface_problems(result)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _with_interface_problems(result: BuildResult) -> BuildResult:
    """The student reads why the grader could not use one of their interface packages."""
    result.warnings = [*result.warnings, *(f"interface package '{n}': {why}"
                                           for n, why in sorted(result.interfaces.problems.items()))]
    return result


def _to_json(result: BuildResult) -> dict:
    return {"source": result.source, "digest": result.digest, "root": str(result.root),
            "duration_s": result.duration_s,
            "packages": {n: asdict(p) for n, p in result.packages.items()},
            "trusted_interfaces": result.interfaces.to_json()}


def load_result(path: Path) -> BuildResult:
    data = json.loads(Path(path).read_text())
    return BuildResult(data["source"], data["digest"], Path(data["root"]),
                       {n: PackageBuild(**p) for n, p in data["packages"].items()},
                       duration_s=data.get("duration_s", 0.0),
                       interfaces=TrustedInterfaces.from_json(data.get("trusted_interfaces")))
