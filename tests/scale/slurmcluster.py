"""A real single-node Slurm for the tests: ``slurmctld`` + ``slurmd`` of Debian's ``slurm-wlm``
(``make bootstrap`` installs them when run as root), started with a configuration of their own in
a temporary folder and stopped (every job cancelled, both daemons ended by their pid) afterwards.

What it is not: a cluster. No munge (``auth/none``, which Slurm 22.05 still has; a real cluster
authenticates with munge), no accounting, no cgroup plugins (``proctrack/linuxproc``,
``task/none``: the grader makes its own cgroups), one node named ``gradernode`` at 127.0.0.1 with
this machine's CPUs and memory, and one partition ``test``.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

NODE = "gradernode"
DAEMONS = ("slurmctld", "slurmd", "sbatch", "squeue", "scancel", "sinfo")


def missing() -> list[str]:
    return [d for d in DAEMONS if shutil.which(d) is None]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _memory_mb() -> int:
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemTotal:"):
            return int(int(line.split()[1]) / 1024 * 0.9)
    return 4096


@dataclass
class SlurmCluster:
    root: Path
    conf: Path
    procs: list[subprocess.Popen]

    @property
    def env(self) -> dict[str, str]:
        """What a user's shell on the login node has: SLURM_CONF pointing at this cluster."""
        return {"SLURM_CONF": str(self.conf)}

    def run(self, *cmd: str, timeout: float = 30) -> str:
        done = subprocess.run(cmd, env={**os.environ, **self.env}, capture_output=True, text=True, timeout=timeout)
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)}: {done.stderr.strip()}\n{self.logs()}")
        return done.stdout

    def wait_idle(self, timeout: float) -> None:
        """Until no job is queued or running (``squeue`` empty)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if not self.run("squeue", "--noheader", "--format=%i %T").strip():
                return
            time.sleep(3)
        raise TimeoutError(f"jobs still queued after {timeout:.0f} s:\n{self.run('squeue')}")

    def logs(self) -> str:
        return "\n".join(f"--- {f.name}\n" + f.read_text(errors="replace")[-3000:]
                         for f in sorted(self.root.glob("*.log")))

    def stop(self) -> None:
        try:
            self.run("scancel", "--full", f"--partition=test")
        except (RuntimeError, subprocess.TimeoutExpired):
            pass
        for proc in self.procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc in self.procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def start(root: Path, *, timeout: float = 60) -> SlurmCluster:
    """Start ``slurmctld`` and ``slurmd`` configured in ``root``; wait until the node is idle."""
    for d in ("state", "spool"):
        (root / d).mkdir(parents=True, exist_ok=True)
    conf = root / "slurm.conf"
    cpus = os.cpu_count() or 1
    conf.write_text("\n".join([
        "ClusterName=gradertest", "SlurmctldHost=localhost",
        f"SlurmctldPort={_free_port()}", f"SlurmdPort={_free_port()}",
        "AuthType=auth/none", "CredType=cred/none", "SlurmUser=root", "SlurmdUser=root",
        f"StateSaveLocation={root / 'state'}", f"SlurmdSpoolDir={root / 'spool'}",
        f"SlurmctldPidFile={root / 'slurmctld.pid'}", f"SlurmdPidFile={root / 'slurmd.pid'}",
        f"SlurmctldLogFile={root / 'slurmctld.log'}", f"SlurmdLogFile={root / 'slurmd.log'}",
        "ProctrackType=proctrack/linuxproc", "TaskPlugin=task/none", "SwitchType=switch/none",
        "MpiDefault=none", "SchedulerType=sched/backfill", "SelectType=select/cons_tres",
        "SelectTypeParameters=CR_Core", "ReturnToService=2", "JobCompType=jobcomp/none",
        "AccountingStorageType=accounting_storage/none", "JobAcctGatherType=jobacct_gather/none",
        f"NodeName={NODE} NodeAddr=127.0.0.1 CPUs={cpus} RealMemory={_memory_mb()} State=UNKNOWN",
        f"PartitionName=test Nodes={NODE} Default=YES MaxTime=INFINITE State=UP", ""]))
    env = {**os.environ, "SLURM_CONF": str(conf)}
    procs = [subprocess.Popen(["slurmctld", "-D", "-i"], env=env, stdout=open(root / "slurmctld.out", "wb"),
                              stderr=subprocess.STDOUT, start_new_session=True)]
    cluster = SlurmCluster(root, conf, procs)
    try:
        time.sleep(1)
        procs.append(subprocess.Popen(["slurmd", "-D", "-N", NODE], env=env, stdout=open(root / "slurmd.out", "wb"),
                                      stderr=subprocess.STDOUT, start_new_session=True))
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if any(p.poll() is not None for p in procs):
                raise RuntimeError("a Slurm daemon exited at start:\n" + cluster.logs())
            try:
                if cluster.run("sinfo", "--noheader", "--format=%T").strip() == "idle":
                    return cluster
            except (RuntimeError, subprocess.TimeoutExpired):
                pass
            time.sleep(1)
        raise TimeoutError(f"the Slurm node is not idle after {timeout:.0f} s:\n{cluster.logs()}")
    except BaseException:
        cluster.stop()
        raise
