"""Manual scores and gradebooks: a TA's CSV merged into a graded batch (``merge``), and the
batch exported for Canvas, Gradescope or a spreadsheet (``export``).

The functions are the Python API; ``grader scores merge|export`` (grader.commands.scores) is a thin
front-end::

    from grader.scores import export_gradebook, merge_manual_scores, parse_mapping, read_roster

    merge_manual_scores("OUT", "manual.csv")
    roster = read_roster("roster.csv", parse_mapping(["submission=github"]))
    export_gradebook("OUT", "canvas", roster=roster, assignment="Lab 3 (12345)")
"""

from grader.scores.errors import ScoresError
from grader.scores.export import FORMATS, ExportReport, export_gradebook
from grader.scores.merge import MergeReport, merge_manual_scores
from grader.scores.roster import Roster, Student, parse_mapping, read_roster
from grader.scores.store import MANUAL_SCORES, ManualScore, apply_saved_manual_scores, load_manual_scores

__all__ = ["FORMATS", "MANUAL_SCORES", "ExportReport", "ManualScore", "MergeReport", "Roster",
           "ScoresError", "Student", "apply_saved_manual_scores", "export_gradebook",
           "load_manual_scores", "merge_manual_scores", "parse_mapping", "read_roster"]
