"""The `grader` program freezes its heap (grader.cli.freeze_heap: its shutdown and later
collections skip what start-up made); a caller of ``main(argv)`` that goes on is left alone."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
from pathlib import Path

from grader.cli import main

REPO = Path(__file__).resolve().parents[2]


def test_main_called_with_arguments_leaves_the_collector_alone(capsys) -> None:
    before = gc.get_freeze_count()
    assert main(["labs", "--json"]) == 0
    assert gc.get_freeze_count() == before
    assert "enee467-lab3" in capsys.readouterr().out


def test_the_program_freezes_what_it_made_before_it_exits() -> None:
    code = ("import gc, sys\nfrom grader.cli import main\nsys.argv = ['grader', 'labs', '--json']\n"
            "rc = main()\nprint('frozen', gc.get_freeze_count(), 'rc', rc)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    frozen, count, _, rc = proc.stdout.strip().splitlines()[-1].split()
    assert (frozen, rc) == ("frozen", "0")
    assert int(count) > 10_000          # the modules the CLI imported, at least
