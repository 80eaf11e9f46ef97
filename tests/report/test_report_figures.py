"""Figures: one registered function per analyzer family, drawn from real recorded evidence, as
accessible inline SVG (title, description, units, legend), never breaking on bad evidence."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from grader.grading.outputs import effective_params
from grader.grading.analysis import analyze_item, scenario_frames
from grader.report.figures import FigureContext, Plot, _FIGURES, figure, figures_for, registered
from grader.rubric import score

REPO = Path(__file__).resolve().parents[2]
BAGS = REPO / "fixtures" / "bags" / "lab3"

#: item -> figures expected on the reference solution's real bags (every family of the issue)
REFERENCE_FIGURES = {
    "ex1.pub_rate": 1, "ex2.control_rate": 1,                          # rates
    "ex1.boxmuller": 1, "ex1.normality": 2,                            # scatter; histogram + QQ
    "ex2.goals_reached": 1, "ex2.turn_direction": 1, "ex2.control_law": 1,   # trajectory, controller
    "ex3.goals_succeed": 1, "ex3.rejects_out_of_bounds": 1, "ex3.timeout": 1,  # action timeline
    "ex3.control_law": 1,                                              # the server loop's law
}


@pytest.fixture(scope="module")
def recorded(lab3):
    """submission -> scored Result from its committed real bags."""
    out = {}
    for sub in ("reference", "bm_log10", "no_wrap"):
        findings = {}
        for sc in sorted(p for p in (BAGS / sub).iterdir() if (p / "bag").is_dir()):
            frames = scenario_frames(sc)
            for item in lab3.items:
                if item.analyzer and sc.name in item.scenario:
                    findings[item.id] = analyze_item(item, frames)
        out[sub] = score(lab3, findings)
    return out


def _figures(result, item_id, params):
    item = result.item(item_id)
    return figures_for(FigureContext(item, item.evidence, params.get(item_id, {})), "t")


def test_every_family_is_registered():
    reg = registered()
    for analyzer in ("goals_reached", "turn_direction", "control_law", "publish_rate", "boxmuller",
                     "normality", "action_goals_succeed", "action_rejects_out_of_bounds", "action_timeout"):
        assert reg.get(analyzer), analyzer


def test_reference_has_every_figure_with_units_legend_and_alt_text(lab3, recorded):
    params = effective_params(lab3)
    result = recorded["reference"]
    for item in result.items:
        figs, errors = _figures(result, item.id, params)
        assert errors == []
        assert len(figs) == REFERENCE_FIGURES.get(item.id, 0), item.id
        for fig in figs:
            svg = fig.svg
            assert svg.startswith('<svg xmlns="http://www.w3.org/2000/svg"') and "<?xml" not in svg
            assert 'role="img"' in svg and re.search(r'width="\d+" height="\d+"', svg)
            assert "<title id=" in svg and len(fig.alt) > 60 and len(fig.title) > 20
            labels = re.findall(r"\((m|s|m/s|rad|rad/s|°|unitless|count|per unit of z)\)</text>", svg)
            assert len(labels) >= 2, f"{item.id}: both axes say their unit"
            assert 'id="t-' in svg and "legend" in svg, f"{item.id}: legend"


def test_boxmuller_mistake_is_visible_at_a_glance(lab3, recorded):
    figs, _ = _figures(recorded["bm_log10"], "ex1.boxmuller", effective_params(lab3))
    assert len(figs) == 1
    assert "log10" in figs[0].alt and "slope ≈ 0.66" in figs[0].alt and "0 on the diagonal" in figs[0].alt
    (hist, qq), _ = _figures(recorded["bm_log10"], "ex1.normality", effective_params(lab3))
    slope = float(re.search(r"slope ([0-9.]+)", qq.alt).group(1))
    assert abs(slope - math.sqrt(1 / math.log(10))) < 0.05          # log10 shrinks z by 0.659


def test_missing_wrap_shows_both_fits(lab3, recorded):
    figs, _ = _figures(recorded["no_wrap"], "ex2.control_law", effective_params(lab3))
    assert "not wrapped" in figs[0].alt and "unwrapped fit" in figs[0].svg
    traj, _ = _figures(recorded["no_wrap"], "ex2.goals_reached", effective_params(lab3))
    assert "hit a wall" in traj[0].alt and "wall contact" in traj[0].svg


def test_page_ids_are_unique(lab3, recorded):
    from grader.report import render_html

    html = render_html(recorded["reference"], "reference", params=effective_params(lab3))
    ids = re.findall(r'\bid="([^"]+)"', html)
    assert len(ids) == len(set(ids))
    assert html.count('class="plot"') == sum(REFERENCE_FIGURES.values())


def test_adding_a_figure_is_one_function(lab3, make_finding):
    @figure("topic_type")
    def pie(ctx):
        fig, ax = ctx.axes("Messages seen: one slice per type")
        ax.bar(["seen"], [ctx.evidence.get("count", 0)], label="messages")
        ax.set(ylabel="messages", xlabel="type")
        ax.legend()
        return Plot(fig, "Messages seen: one slice per type", "A bar of the number of messages.")

    try:
        result = score(lab3, {"ex1.pub_topic": make_finding(evidence={"count": 5})})
        figs, errors = figures_for(FigureContext(result.item("ex1.pub_topic"), {"count": 5}), "x")
        assert errors == [] and len(figs) == 1 and "Messages seen" in figs[0].svg
    finally:
        _FIGURES["topic_type"].remove(pie)


def test_a_failing_figure_is_reported_not_raised(lab3, make_finding):
    @figure("topic_type")
    def broken(ctx):
        raise ValueError("bad data")

    try:
        result = score(lab3, {"ex1.pub_topic": make_finding(evidence={"count": 5})})
        figs, errors = figures_for(FigureContext(result.item("ex1.pub_topic"), {"count": 5}), "x")
        assert figs == [] and "ValueError: bad data" in errors[0]
    finally:
        _FIGURES["topic_type"].remove(broken)


JUNK = [None, 3, "x", [], {}, [1, "a"], {"t": "x"}, {"t": [1, 2], "dt": [1]}, [{"x": None}],
        {"goals": [{"t_sent": None}]}, {"expected_z": [1, 2], "printed": [1]},
        {"d_e": [1], "theta_e": [1], "theta_e_unwrapped": [1], "linear_x": [1], "angular_z": "a"}]


@pytest.mark.parametrize("analyzer", sorted(registered()))
def test_figures_never_raise_on_junk_evidence(lab3, make_finding, analyzer):
    item = next((i for i in lab3.items if i.analyzer == analyzer), None)
    if item is None:
        pytest.skip(f"no Lab 3 item uses {analyzer}")
    keys = ("trajectory", "goals", "wall_points", "heading_error", "fit_rows", "intervals", "pairs",
            "histogram", "qq", "timeline")
    for junk in JUNK:
        ev = {k: junk for k in keys}
        result = score(lab3, {item.id: make_finding(evidence=ev)})
        figs, errors = figures_for(FigureContext(result.item(item.id), ev), "j")
        assert errors == [], (junk, errors)
