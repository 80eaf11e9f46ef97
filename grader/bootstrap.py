"""Idempotent set-up of the grader's ROS 2 environment.

Two entry points share every step (``prepare``):
* ``python -m grader.bootstrap`` (what `make demo` and `make test` run first, in a checkout):
  creates ``.venv``, then prepares it and makes the checkout importable in it. Runs with any
  Python >= 3.11 and only the standard library, because it is what creates the venv.
* ``grader setup`` (an installed grader, e.g. from ``pipx install``): prepares the environment
  grader itself runs in (``sys.prefix``), with the requirement pins the wheel carries.

Two modes:
* ``wheels`` (default): ROS 2 Jazzy comes from PyPI wheels into the environment; the wheels'
  exported CMake targets are repaired; our ``turtlesim`` interface package is built into its prefix.
* ``system``: ROS 2 Jazzy is sourced (``ROS_DISTRO=jazzy`` and the system ``rclpy`` imports): the
  environment sees system site packages, and a system ``turtlesim`` is used when installed.

A second run with nothing changed only compares stamps and finishes in well under a second.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from grader.rclpy_fix import RclpyFixError, ensure_fixed

ROOT = Path(__file__).resolve().parent.parent
VENV = Path(os.environ.get("GRADER_VENV", ROOT / ".venv"))
REQ_DIR = ROOT / "requirements"
INTERFACES = ROOT / "grader" / "interfaces"
#: where the wheels were built; their exported CMake files name these paths
FOREIGN_PREFIX = "/opt/python/cp311-cp311"


@dataclass(frozen=True)
class Target:
    """The environment being prepared: its prefix (a venv root), interpreter and pins."""

    prefix: Path
    python: Path
    requirements: Path              # folder with base.txt and ros-wheels.txt
    checkout: bool = False          # also make this checkout importable there (make bootstrap)

    @property
    def stamp(self) -> Path:
        return self.prefix / ".grader-bootstrap.json"


def repo_target() -> Target:
    """``.venv`` of this checkout (or $GRADER_VENV), as `make bootstrap` prepares it."""
    return Target(VENV, VENV / "bin" / "python", REQ_DIR, checkout=True)


class BootstrapError(SystemExit):
    """A set-up failure explained in one sentence (no traceback)."""

    def __init__(self, message: str) -> None:
        super().__init__(f"grader bootstrap: {message}")


def log(msg: str) -> None:
    print(f"[bootstrap] {msg}", flush=True)


def run(cmd: list[str], *, env: dict[str, str] | None = None, cwd: Path | None = None,
        quiet: bool = True, what: str = "") -> None:
    """Run a command; on failure show its output tail and stop with one sentence."""
    proc = subprocess.run(cmd, env=env, cwd=cwd, text=True,
                          stdout=subprocess.PIPE if quiet else None,
                          stderr=subprocess.STDOUT if quiet else None)
    if proc.returncode != 0:
        if quiet and proc.stdout:
            sys.stderr.write("\n".join(proc.stdout.splitlines()[-40:]) + "\n")
        raise BootstrapError(f"{what or cmd[0]} failed (exit {proc.returncode}): {' '.join(cmd)}")


def system_ros_available(exclude: Path | None = None) -> bool:
    """True when ROS 2 Jazzy is sourced and its rclpy imports with this interpreter; with
    ``exclude``, an rclpy found inside that prefix (wheels installed there) does not count."""
    if os.environ.get("ROS_DISTRO") != "jazzy" or os.environ.get("GRADER_FORCE_WHEELS"):
        return False
    probe = subprocess.run([sys.executable, "-c", "import rclpy; print(rclpy.__file__)"],
                           capture_output=True, text=True)
    if probe.returncode != 0:
        return False
    where = Path(probe.stdout.strip()).resolve()
    return exclude is None or not where.is_relative_to(Path(exclude).resolve())


def ensure_tools() -> None:
    """cmake, ninja and a C compiler build interface packages; install them via apt as root."""
    missing = {tool: pkg for tool, pkg in (("cmake", "cmake"), ("ninja", "ninja-build"),
                                           ("cc", "build-essential"), ("c++", "build-essential"))
               if shutil.which(tool) is None}
    if not missing:
        return
    pkgs = sorted(set(missing.values()))
    if os.geteuid() == 0 and shutil.which("apt-get"):
        log(f"installing {' '.join(pkgs)} with apt-get")
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        run(["apt-get", "update", "-qq"], env=env, what="apt-get update")
        run(["apt-get", "install", "-y", "-qq", *pkgs], env=env, what="apt-get install")
        return
    raise BootstrapError(f"missing {', '.join(missing)}: install the Debian/Ubuntu package(s) "
                         f"{' '.join(pkgs)} (e.g. `sudo apt-get install {' '.join(pkgs)}`) and rerun.")


def _apt_optional(packages: list[str], why: str) -> bool:
    """Install optional Debian packages with apt when root (retrying after ``apt-get update``);
    True when they are installed."""
    if os.geteuid() != 0 or not shutil.which("apt-get"):
        return False
    log(f"installing {' '.join(packages)} with apt-get ({why})")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    cmd = ["apt-get", "install", "-y", "-qq", *packages]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        subprocess.run(["apt-get", "update", "-qq"], env=env, capture_output=True)
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    return proc.returncode == 0


def ensure_browser() -> None:
    """Debian's chromium renders the HTML reports in the browser tests; optional elsewhere."""
    if shutil.which("chromium") or shutil.which("chromium-browser") or os.environ.get("GRADER_NO_BROWSER"):
        return
    if _apt_optional(["chromium"], "headless browser for the HTML report tests"):
        return
    log("note: chromium is not installed; HTML report browser tests will be skipped "
        "(install the Debian package `chromium` to run them)")


def ensure_sandbox() -> None:
    """bubblewrap (Debian's ``bubblewrap``, the sandbox behind Flatpak) jails student code; without
    it grading still works, with reduced isolation and a warning in every result."""
    if shutil.which("bwrap") or os.environ.get("GRADER_NO_SANDBOX_INSTALL"):
        return
    if _apt_optional(["bubblewrap"], "sandbox for student code"):
        return
    log("note: bubblewrap is not installed; student code will run with reduced isolation "
        "(install the Debian package `bubblewrap`; `grader doctor` lists the active protections)")


def ensure_slurm() -> None:
    """Debian's Slurm (``slurmctld``, ``slurmd``, ``slurm-client``): the test of the Slurm example
    (tests/scale/test_slurm.py) starts a single-node cluster of its own with them. Only for a
    checkout's tests; the daemons are not started here (the package scripts find no init system
    to start them with, or the test's own configuration is used)."""
    if shutil.which("slurmctld") and shutil.which("slurmd") and shutil.which("sbatch") \
            or os.environ.get("GRADER_NO_SLURM_INSTALL"):
        return
    if _apt_optional(["slurmctld", "slurmd", "slurm-client"], "a single-node Slurm for the Slurm example's test"):
        return
    log("note: Slurm is not installed; the Slurm example's test will be skipped (install the Debian "
        "packages slurmctld, slurmd and slurm-client to run it)")


def digest(*paths: Path, extra: str = "") -> str:
    h = hashlib.sha256(extra.encode())
    for base in paths:
        files = sorted(p for p in base.rglob("*") if p.is_file()) if base.is_dir() else [base]
        for f in files:
            h.update(str(f.relative_to(ROOT)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def ensure_venv(mode: str) -> None:
    want_system = mode == "system"
    cfg = VENV / "pyvenv.cfg"
    python = repo_target().python
    if cfg.exists():
        has_system = "include-system-site-packages = true" in cfg.read_text()
        if has_system == want_system and python.exists():
            return
        log(f"recreating {VENV} (mode changed to {mode})")
        shutil.rmtree(VENV)
    if mode == "wheels" and sys.version_info[:2] != (3, 11):
        alt = shutil.which("python3.11")
        if alt and Path(alt).resolve() != Path(sys.executable).resolve():
            log(f"re-running with {alt}: the ROS 2 wheels are built for CPython 3.11")
            os.execv(alt, [alt, "-m", "grader.bootstrap", *sys.argv[1:]])
        raise BootstrapError("the ROS 2 Jazzy wheels need CPython 3.11 (python3.11 was not found): "
                             "install python3.11, or source a ROS 2 Jazzy install first.")
    log(f"creating {VENV} ({mode})")
    args = [sys.executable, "-m", "venv", str(VENV)]
    if want_system:
        args.append("--system-site-packages")
    run(args, what="python -m venv")


def pip_install(t: Target, mode: str, state: dict) -> None:
    reqs = [t.requirements / "base.txt"] + ([t.requirements / "ros-wheels.txt"] if mode == "wheels" else [])
    key = digest(*reqs, extra=mode)   # the grader itself is a .pth, so pyproject.toml is not an input
    if state.get("pip") == key:
        return
    log("installing Python packages (" + ", ".join(r.name for r in reqs) + ")")
    cmd = [str(t.python), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    for r in reqs:
        cmd += ["-r", str(r)]
    run(cmd, what="pip install")
    if t.checkout:
        install_grader_itself(t)
    state["pip"] = key
    state.pop("cmake_repair", None)


def install_grader_itself(t: Target) -> None:
    """Make this checkout importable and put a `grader` command in the venv.

    A .pth file plus a two-line launcher does what an editable install does, without needing a
    build backend in the venv (system Pythons often lack `wheel`).
    """
    site = subprocess.run([str(t.python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (Path(site) / "grader-checkout.pth").write_text(str(ROOT) + "\n")
    launcher = t.prefix / "bin" / "grader"
    launcher.write_text(f"#!{t.python}\nimport sys\nfrom grader.cli import main\nsys.exit(main())\n")
    launcher.chmod(0o755)


def compile_own_code(t: Target) -> None:
    """Write the byte code of the checkout's own modules, as pip does for what it installs.

    A shell with ``PYTHONDONTWRITEBYTECODE=1`` (this project's development machines have it) never
    writes ``__pycache__`` for the checkout, so every grader process compiled the ~180 modules it
    imports again: 0.29 s CPU to import the scenario child's modules without byte code, 0.23 s with
    it; every scenario starts two or three such processes. Incremental (an unchanged module is
    skipped), so a second bootstrap pays ~0.3 s.
    """
    sources = [str(d) for d in (ROOT / "grader", ROOT / "rubrics") if d.is_dir()]
    if not sources:
        return
    done = subprocess.run([str(t.python), "-m", "compileall", "-q", "-j", "0", *sources],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:     # e.g. an installed grader in a folder we may not write: only slower
        log("could not write the byte code of every grader module (start-up is slower, nothing else): "
            + (done.stdout.strip().splitlines() or ["no output"])[-1])


def repair_cmake_exports(t: Target, state: dict) -> None:
    """The wheels' exported targets name include dirs of the machine that built them."""
    if state.get("cmake_repair") == "done":
        return
    out = subprocess.run([str(t.python), "-c", "import sys, sysconfig, numpy; "
                          "print(sysconfig.get_paths()['include']); print(numpy.get_include()); "
                          "print(f'python{sys.version_info.major}.{sys.version_info.minor}')"],
                         capture_output=True, text=True, check=True).stdout.split()
    py_inc, np_inc, ver = out[0], out[1], out[2]
    replacements = [
        (f"{FOREIGN_PREFIX}/lib/{ver}/site-packages/numpy/_core/include", np_inc),
        (f"{FOREIGN_PREFIX}/include/{ver}", py_inc),
    ]
    fixed = 0
    for f in (t.prefix / "share").rglob("*.cmake"):
        text = f.read_text(errors="surrogateescape")
        if FOREIGN_PREFIX not in text:
            continue
        for old, new in replacements:
            text = text.replace(old, new)
        f.write_text(text, errors="surrogateescape")
        fixed += 1
    if fixed:
        log(f"repaired foreign include paths in {fixed} exported CMake file(s)")
    state["cmake_repair"] = "done"


def fix_executor(t: Target, state: dict) -> None:
    """The wheel's MultiThreadedExecutor busy loop (ros2/rclpy#1452), fixed in this venv only
    (grader.rclpy_fix); a system ROS install is never edited. Probed again after every pip
    install, which may have brought back the original file."""
    if state.get("executor_fix") == state.get("pip"):
        return
    try:
        done = ensure_fixed(str(t.python), env=ros_build_env(t))
    except RclpyFixError as exc:
        raise BootstrapError(f"rclpy's MultiThreadedExecutor: {exc}") from None
    if done == "applied":
        log("fixed rclpy's MultiThreadedExecutor busy loop (ros2/rclpy#1452) in this environment")
    state["executor_fix"] = state.get("pip")


def ros_build_env(t: Target) -> dict[str, str]:
    env = dict(os.environ)
    prefix = str(t.prefix)
    for var in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH"):
        parts = [p for p in env.get(var, "").split(os.pathsep) if p]
        env[var] = os.pathsep.join([prefix] + [p for p in parts if p != prefix])
    env["PATH"] = os.pathsep.join([str(t.prefix / "bin"), env.get("PATH", "")])
    env["VIRTUAL_ENV"] = prefix
    return env


def system_turtlesim_installed(t: Target, mode: str) -> bool:
    if mode != "system":
        return False
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix and prefix != str(t.prefix) and \
                (Path(prefix) / "share/ament_index/resource_index/packages/turtlesim").exists():
            return True
    return False


def build_interfaces(t: Target, mode: str, state: dict) -> None:
    """Build grader/interfaces/* (our turtlesim) into the environment's prefix with CMake + Ninja."""
    if system_turtlesim_installed(t, mode):
        log("using the system turtlesim interfaces")
        state["interfaces"] = "system"
        return
    key = digest(INTERFACES, extra=mode + state.get("pip", ""))
    if state.get("interfaces") == key:
        return
    env = ros_build_env(t)
    build_root = t.prefix / "build-interfaces"
    for pkg in sorted(p for p in INTERFACES.iterdir() if (p / "package.xml").exists()):
        log(f"building interface package {pkg.name}")
        bdir = build_root / pkg.name
        shutil.rmtree(bdir, ignore_errors=True)
        gen = ["-G", "Ninja"] if shutil.which("ninja") else []
        run(["cmake", "-S", str(pkg), "-B", str(bdir), *gen, f"-DCMAKE_INSTALL_PREFIX={t.prefix}",
             f"-DPython3_EXECUTABLE={t.python}", "-DBUILD_TESTING=OFF"],
            env=env, what=f"configure {pkg.name}")
        run(["cmake", "--build", str(bdir), "--parallel", str(os.cpu_count() or 2)],
            env=env, what=f"build {pkg.name}")
        run(["cmake", "--install", str(bdir)], env=env, what=f"install {pkg.name}")
    check = subprocess.run([str(t.python), "-c", "from turtlesim.msg import Pose"],
                           env=env, capture_output=True, text=True)
    if check.returncode != 0:
        raise BootstrapError("turtlesim interfaces were built but do not import: "
                             + check.stderr.strip().splitlines()[-1])
    state["interfaces"] = key


def prepare(t: Target, mode: str) -> None:
    """Every step after the environment exists: pip pins, CMake repair, interfaces; each one
    skipped when its stamp says its inputs did not change."""
    state: dict = {}
    if t.stamp.exists():
        try:
            state = json.loads(t.stamp.read_text())
        except json.JSONDecodeError:
            state = {}
    if state.get("mode") not in (None, mode):
        state = {}
    pip_install(t, mode, state)
    if mode == "wheels":
        repair_cmake_exports(t, state)
        fix_executor(t, state)
    build_interfaces(t, mode, state)
    compile_own_code(t)
    state["mode"] = mode
    t.stamp.write_text(json.dumps(state, indent=1))
    log(f"ready ({mode} ROS 2; python {t.python})")


def main(argv: list[str] | None = None) -> int:
    """`make bootstrap`: create ``.venv`` in this checkout and prepare it."""
    mode = "system" if system_ros_available() else "wheels"
    ensure_tools()
    ensure_browser()
    ensure_sandbox()
    ensure_slurm()
    ensure_venv(mode)
    prepare(repo_target(), mode)
    return 0


# ----------------------------------------------------------------------------------------------
# `grader setup`: the same preparation for an installed grader, in the environment it runs in

def installed_target() -> Target:
    from grader.labs import requirements_dir  # noqa: PLC0415 - bootstrap runs on a bare python before the dependencies it installs exist

    return Target(Path(sys.prefix), Path(sys.executable), requirements_dir())


def setup_here(*, force_wheels: bool = False) -> str:
    """Prepare ``sys.prefix`` (the venv grader is installed in); returns the mode used."""
    t = installed_target()
    mode = "wheels" if force_wheels else ("system" if system_ros_available(exclude=t.prefix) else "wheels")
    if sys.prefix == sys.base_prefix:
        raise BootstrapError(f"grader runs in {sys.prefix}, which is not a virtual environment; install "
                             "it with pipx or into a venv (see the README) so that `grader setup` never "
                             "changes the system Python.")
    if mode == "wheels" and sys.version_info[:2] != (3, 11):
        raise BootstrapError(
            f"the ROS 2 Jazzy wheels need CPython 3.11, but grader runs on Python "
            f"{sys.version_info.major}.{sys.version_info.minor}: reinstall it with "
            "`pipx install --python python3.11 ...` (or a python3.11 venv), or source ROS 2 Jazzy "
            "(`source /opt/ros/jazzy/setup.bash`) and rerun `grader setup`.")
    cfg = t.prefix / "pyvenv.cfg"
    if mode == "system" and "include-system-site-packages = true" not in \
            (cfg.read_text(errors="replace") if cfg.exists() else ""):
        raise BootstrapError(
            "ROS 2 Jazzy is sourced, but this environment cannot see the system's Python packages "
            "that ROS's rclpy and interface generators import: reinstall with "
            "`pipx install --system-site-packages ...` (or `python3 -m venv --system-site-packages`), "
            "or set GRADER_FORCE_WHEELS=1 to use the PyPI wheels instead (Python 3.11).")
    ensure_tools()
    prepare(t, mode)
    return mode


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("setup", help="install ROS 2 Jazzy and build the interfaces for an installed grader",
                       description="Prepares the environment grader is installed in: ROS 2 Jazzy from the "
                                   "PyPI wheels (or a sourced system ROS 2 Jazzy), the CMake path repair, "
                                   "and our turtlesim interfaces. Idempotent; run it again after upgrading "
                                   "grader. In a source checkout, use `make bootstrap` instead.")
    p.add_argument("--wheels", action="store_true",
                   help="use the PyPI wheels even when a system ROS 2 is sourced (same as GRADER_FORCE_WHEELS=1)")
    p.set_defaults(func=run_setup)


def run_setup(args: argparse.Namespace) -> int:
    from grader.errors import GraderError  # noqa: PLC0415 - bootstrap runs on a bare python before the dependencies it installs exist
    from grader.labs import in_checkout  # noqa: PLC0415 - bootstrap runs on a bare python before the dependencies it installs exist

    if in_checkout():
        raise GraderError("this grader runs from a source checkout: set it up with `make bootstrap` "
                          "(`grader setup` is for an installed grader).")
    try:
        setup_here(force_wheels=args.wheels)
    except BootstrapError as exc:
        raise GraderError(str(exc.code).removeprefix("grader bootstrap: ")) from None
    print("grader setup: done; check it with `grader doctor`, list the labs with `grader labs`")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
