"""The analyzer plug-in point (grader.analyze.plugins): a Python file named by a rubric, an
installed distribution's ``grader.analyzers`` entry point, and the package's own modules found
without a list. A rubric's file is loaded with the rubric, grades offline from a recorded bag,
draws its own figure, gets the built-ins' ``file:line`` parameter checks, and is staged with the
rubric; every bad file is a located rubric problem."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import grader.analyze as A
from grader.analyze import plugins
from grader.rubric.load import RubricError, load_rubric
from grader.rubric.stage import stage_rubrics
from grader.testing.bags import FIXTURE_BAGS
from grader.testing.batch import recorded_batch

CHECKS = '''\
"""A lab's own analyzer and figure: how many messages a topic carried."""
from grader.analyze import REQUIRED, Finding, graded, register
from grader.report.figures import FigureContext, Plot, figure


@register("message_count", defaults={"topic": REQUIRED, "at_least": 1},
          evidence={"value": ("messages received", "messages"), "count": ("messages received", "messages")},
          expect="at least {at_least} messages")
def message_count(frames, params):
    df = frames.get(params["topic"])
    n = 0 if df is None else len(df)
    fraction = min(1.0, n / params["at_least"])
    return Finding(n, fraction, graded(fraction), f"{n} messages on {params['topic']}.", {"count": n})


@figure("message_count")
def count_bar(ctx: FigureContext):
    n = ctx.evidence.get("count")
    if not isinstance(n, int):
        return None
    title = "Messages counted against the minimum"
    fig, ax = ctx.axes(title)
    ax.bar(["received", "needed"], [n, ctx.param("at_least", 0)], label="messages")
    ax.set(ylabel="messages (count)")
    ax.legend()
    return Plot(fig, title, alt=f"{n} messages received, {ctx.param('at_least')} needed.")
'''

RUBRIC = '''\
lab: plugin-demo
title: A lab graded by its own analyzer
analyzers: [{file}]
scenarios:
  ex1_publisher:
    sim: false
    processes:
      - {{name: publisher, package: random_numbers, executable: simple_publisher}}
    steps:
      - {{id: run, wait: 8.5}}
items:
  - id: count
    title: The publisher sends enough numbers
    section: {{exercise: 1}}
    points: 2
    scenario: ex1_publisher
    analyzer: message_count
    params: {{{params}}}
'''


@pytest.fixture(autouse=True)
def _unload_plugins():
    """Each test's files are forgotten after it (the registry is per process)."""
    yield
    for path in list(plugins.loaded_files()):
        plugins.unload_file(path)


def lab(tmp_path: Path, checks: str = CHECKS, *, file: str = "my_lab_checks.py",
        params: str = "topic: /random_numbers, at_least: 5") -> Path:
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "my_lab_checks.py").write_text(checks)
    rubric = tmp_path / "rubric.yaml"
    rubric.write_text(RUBRIC.format(file=file, params=params))
    return rubric


def problems(rubric: Path) -> str:
    with pytest.raises(RubricError) as err:
        load_rubric(rubric)
    return str(err.value)


def test_rubric_with_an_analyzer_file_loads_and_registers_it(tmp_path: Path) -> None:
    rubric = load_rubric(lab(tmp_path))
    assert rubric.analyzers == (tmp_path / "my_lab_checks.py",)
    assert "message_count" in A.names()
    assert A.origin("message_count") == str(tmp_path / "my_lab_checks.py")
    assert A.origin("publish_rate") == "grader.analyze.rate"
    load_rubric(tmp_path / "rubric.yaml")             # loading again is no duplicate
    # without the file's analyzers the same rubric fails (the test would pass on a no-op loader)
    plugins.unload_file(tmp_path / "my_lab_checks.py")
    assert "message_count" not in A.names()
    bare = tmp_path / "bare.yaml"
    bare.write_text((tmp_path / "rubric.yaml").read_text().replace("analyzers: [my_lab_checks.py]\n", ""))
    assert "bare.yaml:16: items[0].analyzer: unknown analyzer 'message_count'" in problems(bare)


def test_a_plugin_grades_offline_from_a_recorded_bag_with_its_figure(tmp_path: Path) -> None:
    rubric = load_rubric(lab(tmp_path / "lab"))
    out = tmp_path / "out"
    graded, = recorded_batch(FIXTURE_BAGS / "lab3", out, rubric, only=["reference"])
    item = graded.result.item("count")
    assert item.status == "pass" and item.points == 2, item.feedback
    assert item.value >= 5 and item.params == {"topic": "/random_numbers", "at_least": 5}
    saved = json.loads((out / "reference" / "result.json").read_text())
    assert "messages on /random_numbers" in json.dumps(saved)
    page = (out / "reference" / "report.html").read_text()
    assert "Messages counted against the minimum" in page          # the plug-in's own figure
    assert "at least 5 messages" in page                           # its expect= text


def test_a_plugins_parameters_get_the_same_located_checks(tmp_path: Path) -> None:
    text = problems(lab(tmp_path, params="topic: /random_numbers, at_leats: 20"))
    assert "rubric.yaml:18: items[0].params.at_leats: analyzer 'message_count' takes no parameter " \
           "'at_leats' (did you mean 'at_least'?)" in text
    text = problems(lab(tmp_path, params="at_least: 20"))
    assert "rubric.yaml:18: items[0].params: analyzer 'message_count' needs the parameter 'topic'" in text


def test_a_missing_file_is_a_located_problem(tmp_path: Path) -> None:
    text = problems(lab(tmp_path, file="nope_checks.py"))
    assert "rubric.yaml:3: analyzers[0]: analyzer file not found" in text
    assert "nope_checks.py" in text
    text = problems(lab(tmp_path, file="checks.txt"))
    assert "rubric.yaml:3: analyzers[0]: an analyzer file is a Python module ending in .py" in text


def test_an_import_error_names_the_file_and_line(tmp_path: Path) -> None:
    text = problems(lab(tmp_path, "import math\nimport no_such_module_here\n"))
    assert "rubric.yaml:3: analyzers[0]: cannot import my_lab_checks.py (line 2): ModuleNotFoundError: " \
           "No module named 'no_such_module_here'" in text
    text = problems(lab(tmp_path, "def broken(:\n"))
    assert "cannot import my_lab_checks.py (line 1): SyntaxError" in text
    text = problems(lab(tmp_path, "X = 1\n"))
    assert "my_lab_checks.py defines no analyzer and no figure" in text
    assert "message_count" not in A.names()


def test_a_duplicate_analyzer_name_is_a_located_problem(tmp_path: Path) -> None:
    dup = CHECKS.replace('@register("message_count"', '@register("publish_rate"')
    text = problems(lab(tmp_path, dup))
    assert "rubric.yaml:3: analyzers[0]: my_lab_checks.py (line 6): analyzer 'publish_rate' is defined twice: " \
           "by grader.analyze.rate and by " in text
    assert A.origin("publish_rate") == "grader.analyze.rate"     # the built-in is untouched
    # two different files of two rubrics defining one name
    load_rubric(lab(tmp_path / "a"))
    other = CHECKS.replace("messages on", "msgs on")
    text = problems(lab(tmp_path / "b", other))
    assert f"analyzer 'message_count' is defined twice: by {tmp_path / 'a' / 'my_lab_checks.py'} and by " \
           f"{tmp_path / 'b' / 'my_lab_checks.py'}" in text
    # a byte-identical copy (a staged rubric next to its source) is the same plug-in
    load_rubric(lab(tmp_path / "c"))


def test_a_changed_file_replaces_its_definitions(tmp_path: Path) -> None:
    rubric = lab(tmp_path)
    load_rubric(rubric)
    checks = tmp_path / "my_lab_checks.py"
    checks.write_text(CHECKS.replace('"at_least": 1}', '"at_least": 1, "window_s": 5.0}'))
    os.utime(checks, ns=(1, 1))
    load_rubric(rubric)
    assert "window_s" in A.defaults("message_count")


def test_staging_copies_the_analyzer_file(tmp_path: Path) -> None:
    rubric = lab(tmp_path / "src" / "rubrics")
    staged, = stage_rubrics([rubric], tmp_path / "staged")
    copy = staged.parent / "my_lab_checks.py"
    assert copy.read_text() == CHECKS
    assert load_rubric(staged).analyzers == (copy,)


def test_gradescope_bundle_carries_the_analyzer_file(tmp_path: Path) -> None:
    import zipfile

    from grader.lms.gradescope_bundle import write_bundle

    rubric = lab(tmp_path / "lab")
    wheel = tmp_path / "grader-0.1.0-py3-none-any.whl"      # (its content is not read here)
    wheel.write_bytes(b"")
    summary = write_bundle(rubric, tmp_path / "autograder.zip", wheel=wheel)
    names = zipfile.ZipFile(summary["zip"]).namelist()
    assert any(n.endswith("rubric/my_lab_checks.py") for n in names), names


SITE_MODULE = '''\
from grader.analyze import Finding, register
from grader.report.figures import figure


@register("installed_check", defaults={"topic": "/x"})
def installed_check(frames, params):
    return Finding(len(frames), 1.0, "pass", "ok")


@figure("installed_check")
def installed_figure(ctx):
    return None
'''


def test_an_installed_distributions_entry_point_registers_analyzers(tmp_path: Path) -> None:
    site = tmp_path / "site"
    dist = site / "my_lab_checks-1.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: my-lab-checks\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[grader.analyzers]\nmy_lab = installed_lab_checks\n")
    (site / "installed_lab_checks.py").write_text(SITE_MODULE)
    code = textwrap.dedent("""
        import grader.analyze as A
        from grader.report.figures import registered
        print(A.origin("installed_check"))
        print(A.defaults("installed_check"), registered()["installed_check"], "publish_rate" in A.names())
    """)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    first, second = run.stdout.splitlines()
    assert first == "entry point my_lab = installed_lab_checks of my-lab-checks"
    assert second == "{'topic': '/x'} ['installed_figure'] True"
    # a broken plug-in is one sentence naming it, not a traceback in every grade
    (site / "installed_lab_checks.py").write_text("raise RuntimeError('half installed')\n")
    run = subprocess.run([str(Path(sys.executable).with_name("grader")), "rubric", "check", "rubrics/first_nodes.yaml"],
                         env=env, capture_output=True, text=True, timeout=120,
                         cwd=Path(__file__).resolve().parents[2])
    assert run.returncode == 2, run.stderr
    assert "grader: error: analyzer plug-in (entry point my_lab = installed_lab_checks of my-lab-checks, " \
           "group grader.analyzers) cannot be imported: RuntimeError: half installed" in run.stderr


def test_builtin_modules_are_discovered_without_a_list() -> None:
    found = plugins.builtin_modules()
    assert "grader.analyze.rate" in found and "grader.analyze.pen" in found
    assert not any(m.rsplit(".", 1)[1].startswith("_") for m in found)
    assert {A.origin(n).rsplit(".", 1)[0] for n in A.names()} == {"grader.analyze"}
