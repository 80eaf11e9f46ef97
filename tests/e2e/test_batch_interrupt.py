"""Ctrl-C in the middle of a batch: exit 130, the bag being recorded is finalized, nothing keeps
running, and `--resume` later grades what was left."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "fixtures" / "submissions" / "enee467_lab3"


def _processes_mentioning(text: str) -> set[int]:
    """Processes whose command line or environment names ``text`` (this test's folder: every
    process of the run names it, the grader's through ROS_LOG_DIR or the output folder, a
    sandboxed student process through its jail's build-cache paths)."""
    found = set()
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            try:
                cmd = b" ".join((proc / f).read_bytes() for f in ("cmdline", "environ")).decode(errors="replace")
            except OSError:
                continue
            if text in cmd and int(proc.name) != os.getpid():
                found.add(int(proc.name))
    return found


@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.timeout(900)
def test_ctrl_c_mid_batch(tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = subprocess.Popen(  # --no-reuse: the scenarios must really run when Ctrl-C comes
        [sys.executable, "-m", "grader.cli", "grade", str(FIXTURES), "--rubric",
                             str(REPO / "rubrics" / "enee467_lab3.yaml"), "-o", str(out),
                             "--only", "reference", "pub_10hz", "--cache-dir", str(tmp_path / "cache"), "--no-reuse"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # wait until the first scenario is recording, then press Ctrl-C (at load 20 the builds alone
    # took 4.4 min: Ctrl-C came during the build, and there was no bag to check)
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and not list(out.glob("*/scenarios/*/bag/*.mcap")):
        time.sleep(0.2)
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=240)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "--resume" in err
    assert not list(out.glob("*/result.json")), "a half-graded submission must not get a result"
    bags = list(out.glob("*/scenarios/*/bag"))
    assert bags
    from grader.bag.frames import load_bag_meta
    assert all(load_bag_meta(b).finalized for b in bags)
    time.sleep(1.0)
    assert not _processes_mentioning(str(tmp_path)), "a process of the batch outlived it"
