"""The paths of an output folder (``OUT``), named once: what ``grader grade`` writes and every
reader finds again.

    OUT/grades.csv, OUT/index.html            the batch (grader.report)
    OUT/similarity/                           the class's similarity (grader.similarity.summary)
    OUT/<submission>/result.json              the grade (ResultDocument)
    OUT/<submission>/report.html              its page
    OUT/<submission>/intake.json              how it arrived (IntakeRecord)
    OUT/<submission>/scenarios/<scenario>/    one run of a scenario: scenario.json (ScenarioRecord),
                                              run.json (ScenarioRun), bag/, canvas.png, logs/

The writers (the pipeline, the scenario child, the report) and the readers (regrade, the class
view, ``grader scores merge``, shards, the audit, the cache's prune) used to join these names as
strings each in its own module; a name changed in one was a file the others no longer found.
The build area's ``result.json`` (``grader.workspace.build``) is another file, not one of these.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["BAG_DIR", "CANVAS_PNG", "GRADES_CSV", "INDEX_HTML", "INTAKE_JSON", "LOGS_DIR", "OutputFolder",
           "REPORT_HTML", "RESULT_JSON", "RUN_JSON", "SCENARIOS_DIR", "SCENARIO_JSON", "SCENARIO_LOG",
           "SIMILARITY_DIR", "ScenarioFolder", "SubmissionFolder"]

GRADES_CSV = "grades.csv"
INDEX_HTML = "index.html"
SIMILARITY_DIR = "similarity"
RESULT_JSON = "result.json"
REPORT_HTML = "report.html"
INTAKE_JSON = "intake.json"
SCENARIOS_DIR = "scenarios"
SCENARIO_JSON = "scenario.json"
RUN_JSON = "run.json"
BAG_DIR = "bag"
CANVAS_PNG = "canvas.png"
LOGS_DIR = "logs"
SCENARIO_LOG = "scenario.log"


@dataclass(frozen=True)
class ScenarioFolder:
    """``OUT/<submission>/scenarios/<scenario>/`` (``<scenario>.run2`` for a repeat's second run)."""

    path: Path

    @property
    def scenario_json(self) -> Path:
        return self.path / SCENARIO_JSON

    @property
    def run_json(self) -> Path:
        return self.path / RUN_JSON

    @property
    def bag(self) -> Path:
        return self.path / BAG_DIR

    @property
    def canvas_png(self) -> Path:
        return self.path / CANVAS_PNG


@dataclass(frozen=True)
class SubmissionFolder:
    """``OUT/<submission>/``."""

    path: Path

    @property
    def id(self) -> str:
        return self.path.name

    @property
    def result_json(self) -> Path:
        return self.path / RESULT_JSON

    @property
    def report_html(self) -> Path:
        return self.path / REPORT_HTML

    @property
    def intake_json(self) -> Path:
        return self.path / INTAKE_JSON

    @property
    def scenarios(self) -> Path:
        return self.path / SCENARIOS_DIR

    def scenario(self, name: str) -> ScenarioFolder:
        return ScenarioFolder(self.scenarios / name)


@dataclass(frozen=True)
class OutputFolder:
    """``OUT``: a batch's folder, one :class:`SubmissionFolder` per submission."""

    root: Path

    def submission(self, sid: str) -> SubmissionFolder:
        return SubmissionFolder(self.root / sid)

    @property
    def grades_csv(self) -> Path:
        return self.root / GRADES_CSV

    @property
    def index_html(self) -> Path:
        return self.root / INDEX_HTML

    @property
    def similarity(self) -> Path:
        return self.root / SIMILARITY_DIR
