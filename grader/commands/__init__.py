"""The ``grader`` command's front-ends: each subcommand's arguments, its printing and its exit
status, over ``grader.api`` and the engine's packages below it. Nothing below this floor
registers a command or prints a table for one.

``grading`` (``grade``, ``check``, ``regrade``), ``rubric`` (``rubric check|schema|guide|audit|
collateral``), ``options`` (what several of them take, parsed once).
"""
