"""Every command of ``grader --help`` (and every subcommand of a group) has a section in
docs/commands.md, so the short README can send a newcomer there for the rest."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from grader.cli import build_parser

REPO = Path(__file__).resolve().parents[2]


def _commands(parser: argparse.ArgumentParser, prefix: str = "grader") -> list[str]:
    out: list[str] = []
    for action in parser._actions:                       # argparse keeps subparsers here
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out.append(f"{prefix} {name}")
                out += _commands(sub, f"{prefix} {name}")
    return out


def test_every_command_has_a_section_in_the_command_reference() -> None:
    headings = [line for line in (REPO / "docs" / "commands.md").read_text().splitlines() if line.startswith("#")]
    text = "\n".join(headings)
    commands = _commands(build_parser())
    assert len(commands) > 20, commands
    missing = []
    for command in commands:
        *group, name = command.split()
        # "grader rubric check`, `schema`, ..." names a group's subcommands after the first
        if not (re.search(rf"`{re.escape(command)}[` ]", text) or
                (len(group) > 1 and re.search(rf"`{re.escape(' '.join(group))} [^`]*`.*`{re.escape(name)}`", text))):
            missing.append(command)
    assert not missing, f"commands without a section in docs/commands.md: {missing}"


def test_the_readme_is_short() -> None:
    assert len((REPO / "README.md").read_text().splitlines()) <= 200
