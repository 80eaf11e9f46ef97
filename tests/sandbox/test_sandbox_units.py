"""The sandbox's parts on their own (real processes, no ROS): capped logs, the minimal
environment, the bubblewrap view, the DDS profile, the modes and the probe."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from grader.errors import GraderError
from grader.rosenv import FASTDDS_PROFILE, SIMULATOR_DDS_PROFILE, child_env, simulator_env
from grader.sandbox import probe, protections
from grader.sandbox.capture import CappedLog
from grader.sandbox.jail import SANDBOX_DDS_PROFILE, Jail, minimal_env, prepare
from grader.sandbox.scenario import ScenarioSandbox, summary
from sandboxhelpers import require_protections

REPO = Path(__file__).resolve().parents[2]
NS = {"d": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


def test_only_the_simulators_readers_repair_a_lost_request_at_once() -> None:
    """The simulator's profile sets the default reader's first ACKNACK and heartbeat answer to
    zero: on Fast DDS's 70 ms default a request from a just-made client reached the lockstep
    simulator 1-6 ticks late, by the machine's speed (benchmarks/README.md). The recorder's and
    driver's profile and the students' keep the defaults; the simulator gets its own profile only
    where the graph uses the grader's (a lab machine's own profile is left alone)."""
    def reader_times(path: Path) -> dict[str, tuple[str, str]]:
        reader = ET.parse(path).getroot().find(".//d:data_reader", NS)
        if reader is None:
            return {}
        assert reader.get("is_default_profile") == "true"
        times = reader.find("d:times", NS)
        return {child.tag.split("}")[1]: (child.find("d:sec", NS).text, child.find("d:nanosec", NS).text)
                for child in (times if times is not None else [])}

    assert reader_times(SIMULATOR_DDS_PROFILE) == {"initialAcknackDelay": ("0", "0"),
                                                   "heartbeatResponseDelay": ("0", "0")}
    assert reader_times(FASTDDS_PROFILE) == {} and reader_times(SANDBOX_DDS_PROFILE) == {}
    graph = child_env(base={})
    assert graph["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(FASTDDS_PROFILE)
    assert simulator_env(graph) == {"FASTRTPS_DEFAULT_PROFILES_FILE": str(SIMULATOR_DDS_PROFILE)}
    assert simulator_env(child_env(base={"FASTRTPS_DEFAULT_PROFILES_FILE": "/lab/profile.xml"})) == {}
    assert simulator_env(child_env(base={"FASTDDS_DEFAULT_PROFILES_FILE": "/lab/profile.xml"})) == {}


@pytest.mark.parametrize("profile", [SANDBOX_DDS_PROFILE, SIMULATOR_DDS_PROFILE], ids=["sandbox", "simulator"])
def test_dds_profiles_keep_the_discovery_and_writer_settings_of_the_main_one(profile: Path) -> None:
    """Discovery, and the 20 ms heartbeat of service clients' request writers (a request from a
    just-made client, dropped by a reader that has not matched it yet, is sent again on it:
    tests/sim/test_sim_fresh_clients.py); no default writer profile and none for services' reply
    writers (every writer on 20 ms took wall_pen's lockstep ticks from 31.5 to 50.4 s)."""
    def block(path: Path, xpath: str) -> str:
        node = ET.parse(path).getroot().find(xpath, NS)
        assert node is not None, f"{path.name}: no {xpath}"
        return ET.tostring(node).decode().replace(" ", "").replace("\n", "")

    assert block(profile, ".//d:discovery_config") == block(FASTDDS_PROFILE, ".//d:discovery_config")
    writer = ".//d:data_writer[@profile_name='client']"
    assert block(profile, writer) == block(FASTDDS_PROFILE, writer)
    period = ET.parse(FASTDDS_PROFILE).getroot().find(writer + "/d:times/d:heartbeatPeriod", NS)
    assert (period.find("d:sec", NS).text, period.find("d:nanosec", NS).text) == ("0", "20000000")
    for path in (profile, FASTDDS_PROFILE):
        assert [w.get("profile_name") for w in ET.parse(path).getroot().iter(f"{{{NS['d']}}}data_writer")] == ["client"]


def test_sandbox_dds_profile_uses_udp_only() -> None:
    root = ET.parse(SANDBOX_DDS_PROFILE).getroot()
    assert root.find(".//d:useBuiltinTransports", NS).text == "false"
    assert root.find(".//d:transport_descriptor/d:type", NS).text == "UDPv4"


def test_capped_log_keeps_the_cap_notes_the_cut_and_never_blocks_the_writer(tmp_path: Path) -> None:
    r, w = os.pipe()
    proc = subprocess.Popen([sys.executable, "-c", "import sys\nfor _ in range(6 * 1024): sys.stdout.write('y' * 1023 + '\\n')\n"
                             "sys.stderr.write('done')"], stdout=w, stderr=subprocess.PIPE)
    os.close(w)
    cuts = []
    capped = CappedLog(r, tmp_path / "out.log", 2**20, stream="stdout", on_cut=lambda s, c: cuts.append((s, c)))
    assert proc.wait(30) == 0 and proc.stderr.read() == b"done"
    capped.join(10)
    text = (tmp_path / "out.log").read_text()
    assert text.count("y" * 1023) == 1024 and len(text) < 2**20 + 300
    assert "[grader] stdout cut: the log reached its limit of 1 MiB" in text
    assert f"[grader] {5 * 2**20} bytes of stdout discarded" in text
    assert cuts == [("stdout", 2**20)] and capped.dropped == 5 * 2**20


def test_minimal_env_keeps_ros_variables_and_drops_the_callers(tmp_path: Path) -> None:
    caller = {"ROS_DOMAIN_ID": "7", "AWS_SECRET_ACCESS_KEY": "x", "SSH_AUTH_SOCK": "/run/agent",
              "PYTHONPATH": os.pathsep.join([str(REPO), f"{sys.prefix}/lib/site"]),
              "AMENT_PREFIX_PATH": os.pathsep.join([str(tmp_path / "install" / "pkg"), sys.prefix]),
              "PATH": f"{REPO}/bin:{sys.prefix}/bin:/usr/bin"}
    env = minimal_env(caller, {"TURTLE_SPEED": "2"}, visible=[sys.prefix, str(tmp_path / "install")],
                      home="/sandbox", profile="/.grader/fastdds_profile.xml")
    assert env["ROS_DOMAIN_ID"] == "7" and env["TURTLE_SPEED"] == "2"
    assert "AWS_SECRET_ACCESS_KEY" not in env and "SSH_AUTH_SOCK" not in env
    assert str(REPO) not in env["PYTHONPATH"].split(os.pathsep)
    assert f"{REPO}/bin" not in env["PATH"].split(os.pathsep)
    assert env["AMENT_PREFIX_PATH"].split(os.pathsep)[0] == str(tmp_path / "install" / "pkg")
    assert env["HOME"] == "/sandbox" and env["ROS_LOG_DIR"].startswith("/sandbox")
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == "/.grader/fastdds_profile.xml"


def test_jailed_command_sees_only_what_it_is_given(tmp_path: Path) -> None:
    require_protections("filesystem")
    given, hidden = tmp_path / "given", tmp_path / "hidden"
    given.mkdir()
    hidden.mkdir()
    (given / "a.txt").write_text("ok")
    jail = Jail(bwrap=probe().bwrap, ro=(str(given),), uid=65534 if probe().uid_drop else None)
    code = ("import os, sys; print(open(sys.argv[1]).read(), os.path.exists(sys.argv[2]), "
            "os.path.exists(sys.argv[3]), os.getcwd())")
    p = prepare(jail, [sys.executable, "-c", code, str(given / "a.txt"), str(hidden), str(REPO / "grader")],
                {"ROS_DOMAIN_ID": "3"})
    done = subprocess.run(p.argv, env=p.env, cwd=p.cwd, preexec_fn=p.preexec, capture_output=True, text=True)
    assert done.stdout.split() == ["ok", "False", "False", "/sandbox"], done.stderr
    # the student entry runner is handed in as one file, not the grader package
    p = prepare(jail, [sys.executable, "-m", "grader.workspace.launch", "json:dumps", "x"], {})
    assert "/.grader/launch.py" in p.argv and "-m" not in p.argv[p.argv.index("/.grader/launch.py") - 2:]


def test_an_installed_grader_package_inside_a_bound_tree_is_covered(tmp_path: Path) -> None:
    """A non-editable install puts the grader in the venv's site-packages, which student code
    needs (rclpy): the package directory is covered by an empty tmpfs, its siblings stay."""
    require_protections("filesystem")
    # the checkout stands in for the venv here, bound with its own mode: in a clone made in a
    # `mktemp -d` folder (0700) the sandbox's uid cannot reach the interpreter through it (the
    # grader binds the venv itself, whose parents bubblewrap makes), so drop the uid only where
    # the checkout lets it through
    drop = probe().uid_drop and bool(REPO.stat().st_mode & 0o001)
    jail = Jail(bwrap=probe().bwrap, ro=(str(REPO),), uid=65534 if drop else None)
    code = "import os, sys; print(len(os.listdir(sys.argv[1])), os.path.exists(sys.argv[2]))"
    p = prepare(jail, [sys.executable, "-c", code, str(REPO / "grader"), str(REPO / "pyproject.toml")], {})
    done = subprocess.run(p.argv, env=p.env, cwd=p.cwd, preexec_fn=p.preexec, capture_output=True, text=True)
    assert done.stdout.split() == ["0", "True"], done.stderr
    # when the grader program itself runs jailed (a launch file's simulator), it stays visible
    p = prepare(jail, [sys.executable, "-m", "grader.sandbox.enter", "--", sys.executable, "-c", code,
                       str(REPO / "grader"), str(REPO / "pyproject.toml")], {})
    done = subprocess.run(p.argv, env=p.env, cwd=p.cwd, preexec_fn=p.preexec, capture_output=True, text=True)
    assert int(done.stdout.split()[0]) > 5, done.stderr


def test_off_mode_warns_and_require_mode_refuses_a_missing_protection(monkeypatch) -> None:
    monkeypatch.setenv("GRADER_SANDBOX", "off")
    off = summary()
    assert off["active"] == [] and "reduced isolation" in off["warning"]
    assert ScenarioSandbox().argv(["x"]) == ["x"]
    monkeypatch.setenv("GRADER_SANDBOX", "sometimes")
    with pytest.raises(GraderError, match="use auto, off or require"):
        summary()
    monkeypatch.setenv("GRADER_SANDBOX", "require")
    monkeypatch.setenv("GRADER_BWRAP", str(REPO / "no-such-bwrap"))
    probe.cache_clear()
    try:
        with pytest.raises(GraderError, match="filesystem.*bubblewrap is not installed"):
            ScenarioSandbox()
    finally:
        monkeypatch.delenv("GRADER_BWRAP")
        probe.cache_clear()


def test_grader_program_started_as_student_code_stays_jailed_with_the_package_read_only(tmp_path: Path) -> None:
    """A launch file's turtlesim_node is the grader's simulator started like a student node: it
    sees the grader package read-only, and still nothing else."""
    require_protections("filesystem")
    jail = Jail(bwrap=probe().bwrap, uid=65534 if probe().uid_drop else None)
    code = "import grader.sandbox.enter as e, os, sys; print(os.path.exists(sys.argv[1])); open(e.__file__, 'a')"
    p = prepare(jail, [sys.executable, "-c", code, str(tmp_path)], {})
    assert "-m" not in p.argv                                         # plain student code: no package
    p = prepare(jail, [sys.executable, "-m", "grader.sandbox.enter", "--", sys.executable, "-c", code,
                       str(tmp_path)], {})
    done = subprocess.run(p.argv, env=p.env, cwd=p.cwd, preexec_fn=p.preexec, capture_output=True, text=True)
    assert done.stdout.split() == ["False"], done.stderr
    assert "Read-only file system" in done.stderr or "Permission denied" in done.stderr, done.stderr


def test_executables_start_in_the_jail_as_ros2_run_starts_them(tmp_path: Path) -> None:
    """A package's installed executables, found by the ament index and started by their '#!'
    line: `#!/usr/bin/env python3` gets the ROS Python (rclpy imports), a shell script and a
    binary run directly; each in the jail, which shows the install prefix read-only."""
    require_protections("filesystem")
    from grader.rosenv import child_env
    from grader.workspace.executables import INDEX, command, find_executable

    prefix = tmp_path / "install" / "pkg"
    (prefix / INDEX).mkdir(parents=True)
    (prefix / INDEX / "pkg").write_text("")
    lib = prefix / "lib" / "pkg"
    lib.mkdir(parents=True)
    (lib / "py_node").write_text("#!/usr/bin/env python3\nimport sys, rclpy\nprint('py', sys.argv[0], *sys.argv[1:])\n")
    (lib / "sh_node").write_text("#!/bin/sh\necho sh \"$@\"\n")
    shutil.copy(shutil.which("echo") or "/bin/echo", lib / "bin_node")
    for f in lib.iterdir():
        f.chmod(0o755)
    jail = Jail(bwrap=probe().bwrap, ro=(str(tmp_path / "install"),), uid=65534 if probe().uid_drop else None)
    env = child_env(prefixes=[prefix], base={"PATH": os.environ.get("PATH", "")})
    out = {}
    for name in ("py_node", "sh_node", "bin_node"):
        argv = command(find_executable("pkg", name, [prefix]), ["a", "b"])
        p = prepare(jail, argv, env)
        done = subprocess.run(p.argv, env=p.env, cwd=p.cwd, preexec_fn=p.preexec, capture_output=True, text=True)
        out[name] = done.stdout.strip() or done.stderr
    assert out == {"py_node": f"py {lib / 'py_node'} a b", "sh_node": "sh a b", "bin_node": "a b"}, out


def test_bubblewrap_without_size_still_jails(tmp_path: Path, monkeypatch) -> None:
    """Ubuntu 22.04 (Gradescope's base image) has bubblewrap 0.6.1, which has no ``--size`` (added
    in 0.7.0): the filesystem jail still works there, with an uncapped scratch, and says so. The
    stand-in below is the real bubblewrap refusing ``--size`` the way 0.6.1 does."""
    require_protections("filesystem")
    real = probe().bwrap
    old = tmp_path / "bwrap"
    old.write_text("#!/bin/sh\n[ \"$1\" = --version ] && { echo 'bubblewrap 0.6.1'; exit 0; }\n"
                   "for a in \"$@\"; do [ \"$a\" = --size ] && { echo 'bwrap: Unknown option --size' >&2; exit 1; }; done\n"
                   f"exec {real} \"$@\"\n")
    old.chmod(0o755)
    monkeypatch.setenv("GRADER_BWRAP", str(old))
    probe.cache_clear()
    try:
        caps = probe()
        fs = next(p for p in protections(caps) if p.name == "filesystem")
        assert caps.bwrap == str(old) and not caps.bwrap_size and fs.active, fs.detail
        assert "bubblewrap 0.6.1" in fs.detail and "not size-capped" in fs.detail
        from grader.sandbox.scenario import SandboxPolicy, student_jail

        given = tmp_path / "given"
        given.mkdir()
        (given / "a.txt").write_text("ok")
        jail = student_jail(caps, SandboxPolicy(), ro=[str(given)])
        code = ("import os, sys; open('/sandbox/w', 'w').write('x'); print(open(sys.argv[1]).read(), "
                "os.path.exists(sys.argv[2]), os.getuid())")
        p = prepare(jail, [sys.executable, "-c", code, str(given / "a.txt"), str(REPO / "grader")], {})
        assert "--size" not in p.argv
        done = subprocess.run(p.argv, env=p.env, cwd=p.cwd, preexec_fn=p.preexec, capture_output=True, text=True)
        assert done.stdout.split()[:2] == ["ok", "False"], done.stderr
        if caps.root:
            assert done.stdout.split()[2] == "65534"
    finally:
        monkeypatch.delenv("GRADER_BWRAP")
        probe.cache_clear()


def test_a_cpu_quota_above_an_ancestors_is_left_to_the_ancestor() -> None:
    """cgroup v1 refuses (EINVAL) a child's CPU quota above an ancestor's, as in a container
    given half a CPU: the scenario's group is made without one instead of failing the scenario."""
    from grader.sandbox.cgroups import CgroupSet, CgroupSupport, find_cgroup_support

    base = find_cgroup_support().bases.get("cpu")
    if base is None or not (Path(base) / "cpu.cfs_quota_us").exists():
        pytest.skip("no writable cgroup v1 cpu controller here")
    outer = Path(base) / f"grader-test-quota-{os.getpid()}"
    outer.mkdir()
    try:
        (outer / "cpu.cfs_period_us").write_text("100000")
        (outer / "cpu.cfs_quota_us").write_text("50000")              # half a CPU above the grader
        group = CgroupSet.create(CgroupSupport(bases={"cpu": str(outer)}), "scenario")
        group.set_limits(cpus=1.0)
        assert (outer / "scenario" / "cpu.cfs_quota_us").read_text().strip() == "-1"
        group.set_limits(cpus=0.25)                                  # below it: applied
        assert (outer / "scenario" / "cpu.cfs_quota_us").read_text().strip() == "25000"
    finally:
        for d in (outer / "scenario", outer):
            if d.exists():
                d.rmdir()


def test_listing_a_groups_members_passes_over_a_group_removed_meanwhile(tmp_path: Path) -> None:
    """Two gradings side by side sweep the same stale group of a killed grader: one removed its
    subgroups while the other listed their members, and ``Path.rglob`` raised FileNotFoundError
    out of the sandbox's start, ending that whole batch. A tree of plain folders that a thread
    keeps making and removing stands in for the cgroup tree."""
    import threading

    from grader.sandbox.cgroups import CgroupSet, CgroupSupport

    base = tmp_path / "grader-1-2-drive"
    (base / "students").mkdir(parents=True)
    (base / "cgroup.procs").write_text("101\n")
    (base / "students" / "cgroup.procs").write_text("102\n")
    group = CgroupSet(CgroupSupport(bases={"cpu": str(tmp_path)}), {"cpu": base})
    stop = threading.Event()

    def churn() -> None:
        while not stop.is_set():
            for i in range(20):
                (base / "students" / f"p{i}" / "q").mkdir(parents=True, exist_ok=True)
            for i in range(20):
                shutil.rmtree(base / "students" / f"p{i}", ignore_errors=True)

    thread = threading.Thread(target=churn)
    thread.start()
    try:
        for _ in range(3000):
            assert {101, 102} <= group.pids()
    finally:
        stop.set()
        thread.join()


def test_a_scenario_child_dies_with_the_grader_killed_outright() -> None:
    """``run_scenario`` starts its child from a batch's worker thread, in a session of its own; a
    grader killed with SIGKILL left it running, a lockstep drive up to 1000 s beside the next
    batch. Started the same way (``die_with_parent``, from a thread that waits on it), the child
    goes with the grader."""
    import signal
    import time

    script = ("import subprocess, sys, threading\n"
              "from grader.runner import die_with_parent\n"
              "def start():\n"
              "    p = subprocess.Popen(['sleep', '120'], start_new_session=True, preexec_fn=die_with_parent)\n"
              "    print(p.pid, flush=True)\n"
              "    p.wait()\n"
              "threading.Thread(target=start).start()\n")
    grader = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, cwd=REPO)
    child = int(grader.stdout.readline())
    assert Path(f"/proc/{child}").exists()
    grader.send_signal(signal.SIGKILL)
    grader.wait(10)
    deadline = time.monotonic() + 5
    while Path(f"/proc/{child}").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    try:
        assert not Path(f"/proc/{child}").exists() or \
            Path(f"/proc/{child}/stat").read_text().split()[2] == "Z"
    finally:
        try:
            os.kill(child, signal.SIGKILL)
        except ProcessLookupError:
            pass
