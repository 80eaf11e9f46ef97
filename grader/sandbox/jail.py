"""One sandboxed command: what it sees (a bubblewrap view), who it runs as, its environment.

A :class:`Jail` describes the view; :func:`prepare` turns ``argv`` + environment into the
command to start (``bwrap ... -- setpriv ... -- env --default-signal=INT,TERM -- argv``), the
environment it gets, and what to do between fork and exec (join the cgroup; make the bwrap
wrappers ignore the SIGINT/SIGTERM the runner sends to the whole process group, so a student
node still gets Ctrl-C and shuts down cleanly instead of dying with its wrapper). Without
bubblewrap the same call gives today's isolation plus the minimal environment and a scratch
directory of its own.

Inside, the filesystem is an empty tmpfs root with read-only binds of the system (``/usr``,
``/etc``, the ``/bin``-style links), the Python interpreter and venv, and the paths the caller
names (a build's ``install``/``src``); one writable, size-capped scratch tmpfs at ``/sandbox``
(cwd, ``HOME``, ``TMPDIR``, ``ROS_LOG_DIR``; ``/tmp`` is a second one); a private ``/dev`` and
``/proc``. Nothing else of the host exists there: not the outputs, the bags, the rubric, the
fixtures, other submissions, the build cache or the grader's sources.
"""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

from grader.sandbox import cgroups

SCRATCH = "/sandbox"
GRADER_DIR = "/.grader"           # read-only files the grader hands in (entry runner, DDS profile)
SYSTEM_DIRS = ("/usr", "/etc")
SYSTEM_LINKS = ("/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32")
#: ``python -m MODULE`` of the grader that student code needs: the module file is bound alone
ENTRY_MODULES = {"grader.workspace.launch": Path(__file__).resolve().parents[1] / "workspace" / "launch.py"}
#: UDP-only Fast DDS profile: a sandbox cannot create the shared-memory segments in /dev/shm
SANDBOX_DDS_PROFILE = Path(__file__).resolve().parents[1] / "dds" / "fastdds_profile_sandbox.xml"
#: the grader package: hidden under an empty tmpfs when it sits inside a bound tree (a non-editable
#: install puts it in the venv's site-packages, which student code needs for rclpy)
PACKAGE_DIR = str(Path(__file__).resolve().parents[1])
#: variables a child keeps from the environment the grader computed (grader.rosenv.child_env)
KEEP_VARS = ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DISTRO", "ROS_VERSION",
             "ROS_PYTHON_VERSION", "RMW_IMPLEMENTATION", "PYTHONUNBUFFERED", "RCUTILS_COLORIZED_OUTPUT",
             "RCUTILS_LOGGING_BUFFERED_STREAM", "RCUTILS_CONSOLE_OUTPUT_FORMAT", "FASTRTPS_DEFAULT_PROFILES_FILE",
             "COLCON_HOME")
PATH_VARS = ("PATH", "AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH", "PYTHONPATH", "LD_LIBRARY_PATH")
SYSTEM_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"


@dataclass(frozen=True)
class Jail:
    """What a sandboxed command may see and do. Paths are host paths, bound at the same path."""

    bwrap: str | None = None              # None: no filesystem sandbox (fallback)
    ro: tuple[str, ...] = ()              # read-only
    rw: tuple[str, ...] = ()              # writable (a build area)
    scratch_mb: int = 256
    scratch_cap: bool = True              # bubblewrap has --size (>= 0.7): cap the scratch tmpfs
    own_network: bool = False             # True: a loopback of its own (builds, launch files)
    uid: int | None = None                # switch to this uid (when the grader is root)
    signal_reset: bool = True             # `env --default-signal` is available
    cgroup_procs: tuple[str, ...] = ()    # cgroup.procs files the process joins
    dds_profile: bool = True              # hand in the UDP-only Fast DDS profile
    python_path: tuple[str, ...] = ()     # put first on PYTHONPATH (their contents must be in ``ro``)

    def to_json(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}

    @classmethod
    def from_json(cls, data: Mapping) -> "Jail":
        return cls(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in data.items()})  # type: ignore[arg-type]


@dataclass
class Prepared:
    """What to start: argv, its environment and cwd, and the fork-to-exec steps."""

    argv: list[str]
    env: dict[str, str]
    cwd: str
    preexec: Callable[[], None]
    sandboxed: bool
    scratch: Path | None = None          # host scratch of the fallback; remove with cleanup()
    files: dict[str, str] = field(default_factory=dict)

    def exit_code(self, rc: int | None) -> int | None:
        """bwrap reports a payload killed by signal N as 128+N; give it back as -N (like Popen)."""
        if self.sandboxed and rc is not None and 128 < rc <= 128 + 64:
            return -(rc - 128)
        return rc

    def cleanup(self) -> None:
        if self.scratch is not None:
            shutil.rmtree(self.scratch, ignore_errors=True)
            self.scratch = None


def _under(path: str, roots: Sequence[str]) -> bool:
    p = Path(path)
    return any(p == Path(r) or Path(r) in p.parents for r in roots)


def ros_roots(env: Mapping[str, str]) -> list[str]:
    """The ROS installs ``env`` builds and runs against: every directory on its
    ``AMENT_PREFIX_PATH`` and ``CMAKE_PREFIX_PATH`` (a sourced ``/opt/ros/jazzy`` and its Python
    packages, an overlay, a build's ``install/<pkg>``), read-only in a jail. Never the grader's
    own package, even when a prefix contains it."""
    out: list[str] = []
    for var in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH"):
        for entry in env.get(var, "").split(os.pathsep):
            if entry and os.path.isdir(entry) and entry not in out and not _under(PACKAGE_DIR, [entry]):
                out.append(entry)
    return out


def visible_roots(jail: Jail) -> list[str]:
    """Host paths a jailed process can see (besides /proc, /dev and its scratch)."""
    from grader.sandbox.probe import python_roots  # noqa: PLC0415 - at the head it would close a circle: sandbox.jail -> sandbox -> sandbox.scenario -> sandbox.jail

    return [*SYSTEM_DIRS, *(str(p) for p in python_roots()), *jail.ro, *jail.rw]


def minimal_env(env: Mapping[str, str], extra: Mapping[str, str] | None, *, visible: Sequence[str],
                home: str, profile: str | None) -> dict[str, str]:
    """The ROS variables of ``env`` (path lists trimmed to what the jail shows), then ``extra``.

    Never the caller's other variables: no tokens, no ``SSH_AUTH_SOCK``, no grader paths.
    """
    out = {k: env[k] for k in KEEP_VARS if k in env}
    for var in PATH_VARS:
        parts = [p for p in env.get(var, "").split(os.pathsep) if p and _under(p, visible)]
        if var == "PATH":
            parts += [p for p in SYSTEM_PATH.split(":") if p not in parts]
        if parts:
            out[var] = os.pathsep.join(dict.fromkeys(parts))
    if profile:
        out["FASTRTPS_DEFAULT_PROFILES_FILE"] = profile
    out.update({"HOME": home, "TMPDIR": f"{home}/tmp", "ROS_LOG_DIR": f"{home}/ros_log",
                "LANG": "C.UTF-8", "PYTHONDONTWRITEBYTECODE": "1"})
    out.update(extra or {})
    return out


def _entry(argv: Sequence[str]) -> tuple[list[str], dict[str, str]]:
    """``python -m grader.workspace.launch ...`` -> ``python /.grader/launch.py ...`` (+ the file)."""
    argv = list(argv)
    if len(argv) >= 3 and argv[1] == "-m" and argv[2] in ENTRY_MODULES:
        src = ENTRY_MODULES[argv[2]]
        dest = f"{GRADER_DIR}/{src.name}"
        return [argv[0], dest, *argv[3:]], {dest: str(src)}
    return argv, {}


def _ancestors(paths: Sequence[str], bound: Sequence[str]) -> list[str]:
    """Directories to create (0755) so that ``paths`` can be reached: their parents, except
    those inside a bound tree. bwrap would make missing parents 0700, closed to the sandbox user."""
    seen: dict[str, None] = {}
    for p in paths:
        parts = Path(p).parts[1:-1]
        for i in range(1, len(parts) + 1):
            seen["/" + "/".join(parts[:i])] = None
    return [d for d in sorted(seen, key=lambda d: d.count("/")) if not _under(d, bound)]


def bwrap_argv(jail: Jail, argv: Sequence[str], *, cwd: str, files: Mapping[str, str]) -> list[str]:
    """The bubblewrap command line for ``argv`` in ``jail``."""
    assert jail.bwrap
    out = [jail.bwrap, "--die-with-parent", "--unshare-pid", "--unshare-ipc", "--unshare-uts",
           "--hostname", "sandbox", "--unshare-cgroup-try"]
    if jail.own_network:
        out.append("--unshare-net")
    for d in SYSTEM_DIRS:
        out += ["--ro-bind", d, d]
    for link in SYSTEM_LINKS:
        if os.path.islink(link):
            out += ["--symlink", os.readlink(link), link]
        elif os.path.isdir(link):
            out += ["--ro-bind", link, link]
    size = ["--size", str(jail.scratch_mb * 2**20)] if jail.scratch_cap else []
    out += ["--proc", "/proc", "--dev", "/dev",
            "--perms", "01777", *size, "--tmpfs", SCRATCH,
            "--perms", "01777", "--dir", f"{SCRATCH}/tmp", "--perms", "01777", "--dir", f"{SCRATCH}/ros_log",
            # /tmp: a tmpfs of its own (not a link into the scratch), so host paths under /tmp can
            # still be bound (a build area in a temporary cache)
            "--perms", "01777", *size, "--tmpfs", "/tmp"]
    ro = [p for p in _dedupe(visible_roots(jail)) if p not in SYSTEM_DIRS and p not in jail.rw
          and not _under(p, SYSTEM_DIRS) and os.path.exists(p)]
    rw = [p for p in _dedupe(jail.rw) if os.path.exists(p)]
    bound = [*SYSTEM_DIRS, *ro, *rw, *files]
    for d in _ancestors([*ro, *rw, *files, cwd + "/."], bound):
        if d not in ("/tmp", SCRATCH):           # the tmpfs mounts above
            out += ["--perms", "0755", "--dir", d]
    for p in ro:
        out += ["--ro-bind", p, p]
    for p in rw:
        out += ["--bind", p, p]
    for dest, src in files.items():
        out += ["--ro-bind", src, dest]
    if PACKAGE_DIR not in jail.ro and _under(PACKAGE_DIR, [*SYSTEM_DIRS, *ro, *rw]):
        out += ["--perms", "0755", *(["--size", "4096"] if jail.scratch_cap else []), "--tmpfs", PACKAGE_DIR]
    out += ["--chdir", cwd]
    if jail.uid is not None:
        out += ["--cap-add", "CAP_SETUID", "--cap-add", "CAP_SETGID", "--",
                shutil.which("setpriv") or "setpriv", f"--reuid={jail.uid}", f"--regid={jail.uid}",
                "--clear-groups"]
    out.append("--")
    if jail.signal_reset:
        out += ["env", "--default-signal=INT,TERM", "--"]
    return out + list(argv)


def _dedupe(paths: Sequence[str]) -> list[str]:
    """Unique paths, dropping those inside another one of the list."""
    uniq = sorted(dict.fromkeys(str(Path(p)) for p in paths))
    return [p for p in uniq if not any(q != p and _under(p, [q]) for q in uniq)]


def prepare(jail: Jail | None, argv: Sequence[str], env: Mapping[str, str], *,
            extra_env: Mapping[str, str] | None = None, cwd: str | None = None) -> Prepared:
    """The command, environment and fork-to-exec steps that run ``argv`` in ``jail``.

    ``env`` is the grader's environment for ROS children (trimmed to its ROS variables);
    ``extra_env`` is passed as it is (the rubric's ``env:``). ``jail=None``: the command as it
    is, with ``env`` + ``extra_env`` (``GRADER_SANDBOX=off``). A jail without bubblewrap: the
    command as it is, but with the minimal environment and a scratch directory of its own.
    """
    if jail is None:
        return Prepared(list(argv), {**env, **(extra_env or {})}, cwd or os.getcwd(), lambda: None, False)
    procs = list(jail.cgroup_procs)
    if jail.bwrap:
        argv, files = _entry(argv)
        if len(argv) >= 3 and argv[1] == "-m" and argv[2].startswith("grader."):
            # the grader's own program run as student code (the simulator a launch file starts
            # when the scenario has none): it needs the grader package, read-only, still jailed
            jail = replace(jail, ro=(*jail.ro, PACKAGE_DIR), python_path=(str(Path(PACKAGE_DIR).parent), *jail.python_path))
        if jail.dds_profile and SANDBOX_DDS_PROFILE.exists():
            files[f"{GRADER_DIR}/fastdds_profile.xml"] = str(SANDBOX_DDS_PROFILE)
        run_cwd = cwd or SCRATCH
        child_env = minimal_env(env, extra_env, visible=visible_roots(jail), home=SCRATCH,
                                profile=files.get(f"{GRADER_DIR}/fastdds_profile.xml") and
                                f"{GRADER_DIR}/fastdds_profile.xml")
        if jail.python_path:
            child_env["PYTHONPATH"] = os.pathsep.join(
                [*jail.python_path, *filter(None, child_env.get("PYTHONPATH", "").split(os.pathsep))])
        command = bwrap_argv(jail, argv, cwd=run_cwd, files=files)
        ignore = jail.signal_reset

        def preexec() -> None:
            if procs:
                cgroups.join(procs)
            if ignore:     # the wrappers ignore Ctrl-C; `env --default-signal` restores it inside
                signal.signal(signal.SIGINT, signal.SIG_IGN)
                signal.signal(signal.SIGTERM, signal.SIG_IGN)

        return Prepared(command, child_env, "/", preexec, True, files=files)
    # fallback: today's isolation, but a scratch directory of its own and the minimal environment
    scratch = Path(tempfile.mkdtemp(prefix="grader-scratch-"))
    (scratch / "tmp").mkdir()
    (scratch / "ros_log").mkdir()
    child_env = minimal_env(env, extra_env, visible=["/"], home=str(scratch), profile=None)

    def preexec_fallback() -> None:
        if procs:
            cgroups.join(procs)

    return Prepared(list(argv), child_env, cwd or str(scratch), preexec_fallback, False, scratch=scratch)
