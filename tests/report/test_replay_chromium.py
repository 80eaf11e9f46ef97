"""The replay player of a report in a real headless Chromium (issue 39), on the committed real
bags of Lab 3 regraded offline (no ROS): the page opened at ``#replay=<scenario>&t=<s>`` draws
the turtle where the bag has it then, playing advances time, a failing item links to the moment
that decided it, and the page opened from ``file://`` loads nothing from anywhere else.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from grader.analyze._common import since_start, sim_pose, times
from grader.grading.analysis import scenario_frames
from grader.report.replay import REPLAY_FILE
from grader.rubric.load import load_rubric
from grader.testing.batch import LAB3_BAGS, recorded_batch
from grader.testing.browser import Browser, find_chromium

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(find_chromium() is None, reason="chromium is not installed (apt-get install chromium)")

STATE = "JSON.stringify([...document.querySelectorAll('figure.replay')].map(f => ({sc: f.dataset.scenario, " \
        "t: +f.dataset.t, x: +f.dataset.x, y: +f.dataset.y, status: f.querySelector('.replay-status').textContent})))"


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("replay-batch")
    recorded_batch(LAB3_BAGS, out, load_rubric(REPO / "rubrics" / "enee467_lab3.yaml"), only=["reference", "no_wrap"])
    return out


@pytest.fixture(scope="module")
def browser():
    with Browser() as b:
        yield b


def _state(page) -> dict:
    import json

    return {f["sc"]: f for f in json.loads(page.eval(STATE))}


def _bag_pose(scenario_dir: Path, t: float) -> tuple[float, float]:
    frames = scenario_frames(scenario_dir)
    df = sim_pose(frames, "/turtle1/pose")
    ts = since_start(frames, times(df))
    return float(np.interp(t, ts, df["x"])), float(np.interp(t, ts, df["y"]))


def test_every_recorded_scenario_has_a_player_and_its_data_is_small(batch: Path) -> None:
    for sid in ("reference", "no_wrap"):
        scenarios = sorted(p.name for p in (batch / sid / "scenarios").iterdir() if (p / "bag").is_dir())
        html = (batch / sid / "report.html").read_text()
        assert scenarios and all(f'data-scenario="{sc}"' in html for sc in scenarios), scenarios
        data = [batch / sid / "scenarios" / sc / REPLAY_FILE for sc in scenarios]
        assert sum(p.stat().st_size for p in data) <= 2 * 2**20
        assert "ros2 bag play scenarios/" in html


def test_a_moment_link_draws_the_turtle_where_the_bag_has_it(batch: Path, browser) -> None:
    sub = batch / "no_wrap"
    for t in (20.0, 7.31):
        page = browser.open((sub / "report.html").as_uri() + f"#replay=ex2_controller&t={t:g}")
        try:
            shown = _state(page)["ex2_controller"]
            assert shown["status"] == "" and shown["t"] == pytest.approx(t)
            x, y = _bag_pose(sub / "scenarios" / "ex2_controller", t)
            assert np.hypot(shown["x"] - x, shown["y"] - y) <= 0.05, (shown, x, y)
            assert page.collect() == []                       # no console errors
        finally:
            page.close()


def test_playing_advances_time_and_the_link_follows(batch: Path, browser) -> None:
    page = browser.open((batch / "reference" / "report.html").as_uri() + "#replay=ex2_controller&t=3")
    try:
        assert _state(page)["ex2_controller"]["t"] == pytest.approx(3.0)
        page.eval("document.querySelector('#replay-ex2_controller select.speed').value = '4';"
                  "document.querySelector('#replay-ex2_controller select.speed').dispatchEvent(new Event('change'));"
                  "document.querySelector('#replay-ex2_controller button.play').click(); true")
        time.sleep(1.0)
        page.eval("document.querySelector('#replay-ex2_controller button.play').click(); true")     # pause
        t = _state(page)["ex2_controller"]["t"]
        assert 4.0 < t < 12.0, t                           # ~1 s at 4x
        link = page.eval("document.querySelector('#replay-ex2_controller a.moment-link').getAttribute('href')")
        assert link == f"#replay=ex2_controller&t={t:.3f}".rstrip("0").rstrip("."), link
        page.eval("document.querySelector('#replay-ex2_controller button.on').click(); true")       # one tick
        assert _state(page)["ex2_controller"]["t"] == pytest.approx(t + 0.016, abs=1e-3)
    finally:
        page.close()


def test_a_failing_item_links_to_the_moment_that_decided_it(batch: Path, browser) -> None:
    html = (batch / "no_wrap" / "report.html").read_text()
    assert 'href="#replay=ex2_controller&amp;t=' in html and "the moment that decided it" in html
    page = browser.open((batch / "no_wrap" / "report.html").as_uri())
    try:
        href = page.eval("document.querySelector('#item-ex2\\\\.goals_reached .moment a').getAttribute('href')")
        at = float(href.split("t=")[1])
        assert at > 0
        page.eval("document.querySelector('#item-ex2\\\\.goals_reached .moment a').click(); true")
        time.sleep(0.3)
        assert _state(page)["ex2_controller"]["t"] == pytest.approx(at)
    finally:
        page.close()


def test_offline_from_file_nothing_else_is_loaded(batch: Path, browser) -> None:
    page = browser.open((batch / "reference" / "report.html").as_uri())
    try:
        urls = page.eval("JSON.stringify(performance.getEntriesByType('resource').map(e => e.name))")
        assert all(u.startswith("file://") for u in __import__("json").loads(urls)), urls
        assert all(f["status"] == "" for f in _state(page).values())           # every player's data loaded
    finally:
        page.close()


def test_the_class_view_links_an_item_to_the_replay_of_a_submission_that_lost_it(batch: Path, browser) -> None:
    index = (batch / "index.html").read_text()
    link = 'href="no_wrap/report.html#replay-item=ex2.goals_reached"'
    assert link in index
    page = browser.open((batch / "no_wrap" / "report.html").as_uri() + "#replay-item=ex2.goals_reached")
    try:
        time.sleep(0.3)
        href = page.eval("document.querySelector('#item-ex2\\\\.goals_reached .moment a').getAttribute('href')")
        assert page.eval("location.hash") == href
        assert _state(page)["ex2_controller"]["t"] == pytest.approx(float(href.split("t=")[1]))
    finally:
        page.close()
