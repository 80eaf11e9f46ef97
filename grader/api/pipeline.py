"""One submission through the pipeline, and the files and text it leaves: for the front-ends that
drive it themselves (the mutation audit, Gradescope's ``run_autograder``, ``grader check``'s table).

This module loads ``grader.grading.pipeline``, hence pandas and numpy (424 ms CPU in a fresh
interpreter): the front-ends import it inside the function that needs it, as they imported the
pipeline before (``grader`` itself starts without it).

:func:`grade_submission` builds, records, analyzes, scores and writes one submission;
:func:`regrade_submission` does it again from the recordings only; :func:`write_batch_outputs`
rebuilds ``grades.csv`` and ``index.html`` of a batch; :func:`check_table` and
:func:`contract_lines` are ``grader check``'s text (the engine returns it; the command prints it);
:func:`atomic_write` is how every result file is written (never half a file).
"""

from __future__ import annotations

from grader.contracts.output_folder import SCENARIOS_DIR
from grader.grading.outputs import check_table, contract_lines, write_batch_outputs
from grader.grading.pipeline import grade_submission, regrade_submission
from grader.report.result import atomic_write

__all__ = ["SCENARIOS_DIR", "atomic_write", "check_table", "contract_lines", "grade_submission",
           "regrade_submission", "write_batch_outputs"]
