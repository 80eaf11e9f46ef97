"""Intake: submissions as the LMS hands them over (a Canvas download, a Gradescope export,
GitHub Classroom clones, a folder of workspaces or archives), each matched to a roster student
with an id, a submission time and who says so; and the late policy applied to that time.

``read_intake`` (grader.intake.batch) is what ``grader grade`` runs first; ``apply_intake``
(grader.intake.apply) puts the late policy's verdict on a scored Result, at grading and at every
regrade.
"""

from grader.intake.batch import IntakeBatch, read_intake
from grader.intake.late import LatePenalty, SubmissionTime, assess
from grader.intake.model import Arrival

__all__ = ["Arrival", "IntakeBatch", "LatePenalty", "SubmissionTime", "assess", "read_intake"]
