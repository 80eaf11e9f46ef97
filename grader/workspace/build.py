"""`grader build`: colcon-build a submission in an isolated, content-addressed build area.

Never builds inside the student's folder. Results are cached by the hash of the staged sources
(plus the grader's ROS mode), so regrading an unchanged submission skips colcon entirely. One
broken package does not stop the others (``--continue-on-error``); the result says which package
failed and shows the relevant lines of its log.
"""

from __future__ import annotations

import configparser
import fcntl
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from grader.errors import GraderError
from grader.rosenv import PY_SITE, child_env, ros_mode
from grader.workspace.source import stage_sources, tree_digest

BUILD_TIMEOUT_S = 900
CACHE_FORMAT = 2


def default_cache_dir() -> Path:
    base = os.environ.get("GRADER_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "grader")
    return Path(base) / "builds"


@dataclass
class PackageBuild:
    name: str
    build_type: str
    status: str                        # built | failed | skipped
    log_excerpt: str = ""              # relevant lines of the package's build log when not built
    executables: dict[str, str] = field(default_factory=dict)   # console script -> module:func


@dataclass
class BuildResult:
    """What a build produced, and how to run its executables."""

    source: str
    digest: str
    root: Path                         # build area: src/, build/, install/, log/, build.log
    packages: dict[str, PackageBuild]
    cached: bool = False
    duration_s: float = 0.0

    @property
    def install(self) -> Path:
        return self.root / "install"

    @property
    def ok(self) -> bool:
        return all(p.status == "built" for p in self.packages.values())

    @property
    def failed(self) -> list[str]:
        return [n for n, p in self.packages.items() if p.status != "built"]

    @property
    def build_log(self) -> Path:
        return self.root / "build.log"

    def prefixes(self) -> list[Path]:
        """Install prefixes of the built packages (what ``source install/setup.bash`` adds)."""
        return [self.install / n for n, p in self.packages.items() if p.status == "built"]

    def env(self, **kwargs) -> dict[str, str]:
        return child_env(prefixes=self.prefixes(), **kwargs)

    # -- executables -------------------------------------------------------------------------
    def require_package(self, package: str) -> PackageBuild:
        pkg = self.packages.get(package)
        if pkg is None:
            raise GraderError(f"package '{package}' is not in the submission "
                              f"(packages found: {', '.join(sorted(self.packages)) or 'none'}).")
        if pkg.status != "built":
            raise GraderError(f"package '{package}' did not build ({pkg.status}); see its build log:\n"
                              + pkg.log_excerpt)
        return pkg

    def argv(self, package: str, executable: str | None = None, module: str | None = None,
             args: list[str] | tuple[str, ...] = ()) -> list[str]:
        """argv to run a package's executable, by console-script name or by ``module[:func]``.

        Students name console scripts freely; ``module`` finds ``turtle_control.goal_publisher:main``
        whatever its script is called. Both run through the grader's own interpreter, so a wrong
        shebang in an installed script never matters.
        """
        pkg = self.require_package(package)
        target = None
        if executable and executable in pkg.executables:
            target = pkg.executables[executable]
        elif module:
            mod, _, func = module.partition(":")
            func = func or "main"
            if (self.install / package / PY_SITE / (mod.replace(".", "/") + ".py")).exists() or \
                    (self.install / package / PY_SITE / mod.replace(".", "/") / "__init__.py").exists():
                target = f"{mod}:{func}"
            else:
                for script, entry in pkg.executables.items():
                    if entry.split(":")[0] == mod:
                        target = entry
                        break
        if target is None:
            wanted = executable or module
            listing = ", ".join(f"{k} ({v})" for k, v in sorted(pkg.executables.items())) or "none"
            raise GraderError(f"package '{package}' has no executable '{wanted}'; "
                              f"executables it does have: {listing}.")
        name = executable or target.split(":")[0].rsplit(".", 1)[-1]
        return [sys.executable, "-m", "grader.workspace.launch", target, name, *args]


def _console_scripts(prefix: Path, package: str) -> dict[str, str]:
    scripts: dict[str, str] = {}
    site = prefix / PY_SITE
    for ep in list(site.glob("*.egg-info/entry_points.txt")) + list(site.glob("*.dist-info/entry_points.txt")):
        cp = configparser.ConfigParser()
        try:
            cp.read(ep)
        except configparser.Error:
            continue
        if cp.has_section("console_scripts"):
            for name, value in cp.items("console_scripts"):
                scripts[name] = value.strip().replace(" ", "")
    return scripts


_ERROR_LINE = re.compile(r"(error|Error|ERROR|Traceback|SyntaxError|Exception|not found|No such file|"
                         r"undefined reference|CMake Error|failed)")


def relevant_lines(log: str, limit: int = 25) -> str:
    """The lines of a build log that explain a failure, with a little context."""
    lines = log.splitlines()
    keep: set[int] = set()
    for i, line in enumerate(lines):
        if _ERROR_LINE.search(line):
            keep.update(range(max(0, i - 2), min(len(lines), i + 4)))
    picked = [lines[i] for i in sorted(keep)] if keep else lines[-limit:]
    if len(picked) > limit:
        picked = picked[:limit // 2] + ["    ..."] + picked[-limit // 2:]
    return "\n".join("    " + ln.rstrip() for ln in picked)


def _colcon_env() -> dict[str, str]:
    env = child_env()
    env.pop("ROS_DOMAIN_ID", None)
    env["COLCON_HOME"] = env.get("COLCON_HOME", str(Path(sys.prefix) / "colcon-home"))
    env.pop("PYTHONUNBUFFERED", None)
    return env


def _run_colcon(root: Path, log_file: Path) -> int:
    cmake_args = [f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF",
                  "-DCMAKE_BUILD_TYPE=Release"]
    if shutil.which("ninja"):
        cmake_args += ["-G", "Ninja"]
    cmd = [sys.executable, "-m", "colcon", "--log-base", "log", "build",
           "--base-paths", "src", "--build-base", "build", "--install-base", "install",
           "--continue-on-error", "--parallel-workers", str(max(1, os.cpu_count() or 1)),
           "--event-handlers", "console_cohesion+", "console_direct-", "status-",
           "--cmake-args", *cmake_args]
    with open(log_file, "wb") as log:
        log.write(("$ " + " ".join(cmd) + "\n").encode())
        log.flush()
        try:
            proc = subprocess.run(cmd, cwd=root, env=_colcon_env(), stdout=log,
                                  stderr=subprocess.STDOUT, timeout=BUILD_TIMEOUT_S,
                                  start_new_session=True)
        except subprocess.TimeoutExpired:
            log.write(f"\ncolcon build timed out after {BUILD_TIMEOUT_S}s\n".encode())
            return -1
    return proc.returncode


def _package_log(root: Path, name: str) -> str:
    """The package's part of the build output, without colcon's own traceback frames.

    Errors raised while colcon reads a broken ``setup.py`` reach only the main log, between
    ``Starting >>> pkg`` and ``Failed <<< pkg``, so that section is read first.
    """
    text = ""
    build_log = root / "build.log"
    if build_log.exists():
        full = build_log.read_text(errors="replace")
        start = full.find(f"Starting >>> {name}\n")
        if start >= 0:
            end = re.compile(rf"^(Finished|Failed|Aborted)\s+<<< {re.escape(name)}\b", re.M).search(full, start)
            text = full[start:end.start()] if end else full[start:]
    if not text:
        for candidate in (root / "log" / "latest_build" / name / "stdout_stderr.log",):
            if candidate.exists():
                text = candidate.read_text(errors="replace")
    return _strip_colcon_frames(text)


def _strip_colcon_frames(text: str) -> str:
    out: list[str] = []
    skip_code_line = False
    for line in text.splitlines():
        if skip_code_line:
            skip_code_line = False
            if line.startswith("    "):
                continue
        if 'File "' in line and ("colcon_" in line or "/subprocess.py" in line or "asyncio" in line):
            skip_code_line = True
            continue
        if line.strip().startswith("^") or len(line) > 400 or line.startswith("Starting >>>"):
            continue
        out.append(line)
    # a "Traceback" header left with no frames after stripping says nothing
    kept = [ln for i, ln in enumerate(out)
            if not (ln.startswith("Traceback") and (i + 1 == len(out) or not out[i + 1].startswith("  ")))]
    return "\n".join(kept)


def _python_syntax_error(package_dir: Path) -> str:
    """A precise 'file:line: SyntaxError' for a package whose Python does not even compile."""
    for f in sorted(package_dir.rglob("*.py")):
        try:
            compile(f.read_bytes(), str(f), "exec")
        except SyntaxError as exc:
            rel = f.relative_to(package_dir.parent.parent)
            return f"    {rel}:{exc.lineno}: SyntaxError: {exc.msg}\n      {(exc.text or '').strip()}\n"
        except ValueError:
            continue
    return ""


def build_workspace(submission: Path, *, cache_dir: Path | None = None,
                    support: dict[str, Path] | None = None, force: bool = False) -> BuildResult:
    """Stage, hash and (unless cached) colcon-build ``submission``."""
    cache_dir = Path(cache_dir or default_cache_dir())
    cache_dir.mkdir(parents=True, exist_ok=True)
    staging = cache_dir / f".staging-{os.getpid()}-{time.monotonic_ns()}"
    try:
        staged = stage_sources(Path(submission), staging / "src", staging, support)
        digest = tree_digest(staging / "src", extra=f"{CACHE_FORMAT}:{ros_mode()}:{sys.version_info[:2]}")
        root = cache_dir / digest
        with open(cache_dir / f"{digest}.lock", "w") as lockf:
            fcntl.flock(lockf, fcntl.LOCK_EX)     # parallel graders build one digest once
            result_file = root / "result.json"
            if result_file.exists() and not force:
                result = load_result(result_file)
                result.source = str(submission)
                result.cached = True
                return result
            if root.exists():
                shutil.rmtree(root)
            root.mkdir(parents=True)
            shutil.move(str(staging / "src"), root / "src")
            t0 = time.monotonic()
            _run_colcon(root, root / "build.log")
            packages: dict[str, PackageBuild] = {}
            for pkg in staged:
                prefix = root / "install" / pkg.name
                built = (prefix / "share" / "colcon-core" / "packages" / pkg.name).exists()
                log = _package_log(root, pkg.name)
                status = "built" if built else ("failed" if log else "skipped")
                excerpt = "" if built else (relevant_lines(log) if log else
                                            "    not built because a package it depends on failed")
                if not built and pkg.build_type == "ament_python":
                    excerpt = _python_syntax_error(root / "src" / pkg.name) + excerpt
                packages[pkg.name] = PackageBuild(
                    pkg.name, pkg.build_type, status, excerpt,
                    _console_scripts(prefix, pkg.name) if built else {})
            result = BuildResult(str(submission), digest, root, packages,
                                 duration_s=round(time.monotonic() - t0, 2))
            result_file.write_text(json.dumps(_to_json(result), indent=1))
            return result
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _to_json(result: BuildResult) -> dict:
    return {"source": result.source, "digest": result.digest, "root": str(result.root),
            "duration_s": result.duration_s,
            "packages": {n: asdict(p) for n, p in result.packages.items()}}


def load_result(path: Path) -> BuildResult:
    data = json.loads(Path(path).read_text())
    return BuildResult(data["source"], data["digest"], Path(data["root"]),
                       {n: PackageBuild(**p) for n, p in data["packages"].items()},
                       duration_s=data.get("duration_s", 0.0))
