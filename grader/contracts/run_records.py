"""The run's records a graded submission carries into result.json, typed: how each scenario's
clock ran (``time_scale``), which recordings were copied (``scenarios_reused``) and whose they
are (``recordings``), the steps ended once decided (``ended_early``).

``grader.grading.graded.GradedSubmission`` holds them as these models, so its readers use
attributes; ``grader.grading.outputs`` writes them with :meth:`KeptOrder.to_json`. The models
of scenario.json that mean the same (``ClockRecord``, ``ReusedNote``) are reused, with one
difference: a record here is written back in the key order it was made with, not the declared
one. result.json has always written these dicts as the pipeline built them (``{"clock":
"lockstep", **lockstep}``, ``{"requested", "used", "fallback"}``), and its bytes must not change
(the seal is a MAC over them, ``grader scores merge`` compares them).
"""

from __future__ import annotations

from pydantic import Field

from grader.contracts.document import KeptOrder, Number
from grader.contracts.scenario_record import ClockRecord, ReusedNote
from grader.contracts.values import JsonValue

__all__ = ["ClockUse", "EarlyEnd", "Recording", "ReusedFrom", "ReusedRecording"]


class ClockUse(ClockRecord):
    """result.json's ``time_scale[scenario]``: the scenario record's ``time_scale`` (at
    ``--time-scale`` K > 1), or its ``lockstep`` with ``clock: "lockstep"`` first."""

    clock: str | None = None


class ReusedRecording(ReusedNote):
    """result.json's ``scenarios_reused[scenario]``: the scenario record's ``reused``."""


class ReusedFrom(KeptOrder):
    from_: str | None = Field(None, alias="from")
    recorded: str | None = None


class Recording(KeptOrder):
    """result.json's ``recordings[scenario]`` (``grader.grading.provenance.scenario_recordings``):
    the recording's key and maker (None: a grader that did not note it), and whose copy it is."""

    key: str | None = None
    made_by: JsonValue = None
    reused_from: ReusedFrom | None = None


class EarlyEnd(KeptOrder):
    """One of result.json's ``ended_early[scenario]``: a step that ended once its outcome was
    decided, when, its limit and why."""

    step: str
    at_s: Number | None = None
    limit_s: Number | None = None
    reason: str | None = None
