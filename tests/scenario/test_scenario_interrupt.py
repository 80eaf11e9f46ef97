"""Stopping a scenario midway (batch Ctrl-C / time limit) still leaves a finalized bag and a record."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from grader.scenario import run as scenario_run
from grader.scenario.model import Scenario, Step
from grader.scenario.runspec import ScenarioRun


@pytest.mark.ros
def test_sigterm_mid_scenario_finalizes_bag(tmp_path: Path) -> None:
    run = ScenarioRun(id="long", scenario=Scenario(steps=[Step(id="wait", wait=60.0)],
                                                   limits={"wall_s": 90}), launched={})
    (tmp_path / "run.json").write_text(run.model_dump_json())
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "grader.scenario.run", str(tmp_path / "run.json"), str(out)],
                            start_new_session=True)
    # the scenario under way: the simulator writes its own record of the poses it publishes once
    # the recorder and the driver are up (on a loaded machine that takes seconds, not a fixed time)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (out / scenario_run.SIM_RECORD).exists():
        time.sleep(0.1)
    time.sleep(3.0)
    os.killpg(proc.pid, signal.SIGTERM)
    assert proc.wait(timeout=30) == 1
    record = json.loads((out / "scenario.json").read_text())
    assert record["interrupted"] is True
    from grader.bag.frames import load_bag_meta
    meta = load_bag_meta(out / "bag")
    assert meta.finalized, meta.problems
    assert meta.counts["/turtle1/pose"] > 60
