"""The ``grader`` command's front-ends: each subcommand's arguments, its printing and its exit
status, over ``grader.api`` (and ``grader.contracts``, ``grader.errors``) only: pyproject's
import-linter contract "front-ends reach the engine through grader.api" holds them to it.
Nothing below this floor registers a command or prints for one.

``grading`` (``grade``, ``check``, ``regrade``, ``merge``), ``rubric`` (``rubric
check|schema|guide|audit|collateral``), ``similarity`` (and the options ``grade``/``merge`` share
with it), ``bag`` (``record``, ``bag info|repair|verify``, ``replay``), ``cache``, ``build``,
``sim``, ``scores``, ``labs``, ``options`` (what several of them take, parsed once).
"""
