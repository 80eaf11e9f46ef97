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

from typing import Self

from pydantic import BaseModel, ConfigDict, Field, ModelWrapValidatorHandler, PrivateAttr, model_validator

from grader.contracts.document import Number
from grader.contracts.scenario_record import ClockRecord, ReusedNote
from grader.contracts.values import JsonValue

__all__ = ["ClockUse", "EarlyEnd", "KeptOrder", "Recording", "ReusedFrom", "ReusedRecording"]


class KeptOrder(BaseModel):
    """A record that remembers the order of the keys it was made from and writes them back so."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False, populate_by_name=True)

    _order: list[str] = PrivateAttr(default_factory=list)

    @model_validator(mode="wrap")
    @classmethod
    def _keep_order(cls, data: JsonValue, handler: ModelWrapValidatorHandler[Self]) -> Self:
        made = handler(data)
        if isinstance(data, dict):
            made._order = [str(k) for k in data]
        return made

    def to_json(self) -> dict[str, JsonValue]:
        """The keys it was given, in the order it was given them."""
        dumped = self.model_dump(mode="json", by_alias=True, exclude_unset=True)
        first = {k: dumped[k] for k in self._order if k in dumped}
        return first | {k: v for k, v in dumped.items() if k not in first}


class ClockUse(KeptOrder, ClockRecord):
    """result.json's ``time_scale[scenario]``: the scenario record's ``time_scale`` (at
    ``--time-scale`` K > 1), or its ``lockstep`` with ``clock: "lockstep"`` first."""

    clock: str | None = None


class ReusedRecording(KeptOrder, ReusedNote):
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
