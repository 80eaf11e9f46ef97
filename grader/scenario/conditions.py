"""The ``until:`` conditions of a scenario step: when a step is over (one class each, dispatched
on ``condition``; ``grader.scenario.steps`` holds the predicate of each)."""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal, Union

from pydantic import BeforeValidator, Field, field_validator, model_validator

from grader.contracts.fields import (ActionType, Goal, LocalId, Model, NonNegativeFloat, PositiveFloat,
                                    PositiveInt, RosName)


class GoalReached(Model):
    """The turtle is within ``tolerance`` of ``goal`` (default: the step's ``goal:``) and stays
    there for ``settle`` seconds."""

    condition: Literal["goal_reached"]
    goal: Goal | None = Field(None, description="absent: the step's goal")
    tolerance: PositiveFloat = Field(0.1, description="m")
    settle: NonNegativeFloat = Field(0.5, description="s it must stay within the tolerance")
    pose_topic: RosName = "/turtle1/pose"
    give_up_still: PositiveFloat | None = Field(
        None, description="s: end the step early once the turtle, away from the goal, has not moved and "
        "its commands on `cmd_topic` have not changed for this long (a fixed point it cannot leave); "
        "the result says so. None: wait for the whole timeout")
    cmd_topic: RosName = Field("/turtle1/cmd_vel", description="the turtle's commands (`give_up_still`)")


class ActionDone(Model):
    """The step's action goal was rejected or returned a result."""

    condition: Literal["action_done"]


class ServiceDone(Model):
    """The step's service call returned (or could not be made)."""

    condition: Literal["service_done"]


class ReplayDone(Model):
    """The step's replay published its last message."""

    condition: Literal["replay_done"]


class ProcessExit(Model):
    """Every OS process of ``process`` has exited."""

    condition: Literal["process_exit"]
    process: LocalId


class Output(Model):
    """A stdout/stderr line of ``process`` printed since the step began matches ``pattern``."""

    condition: Literal["output"]
    process: LocalId
    pattern: str = Field(description="a regular expression (Python syntax)")

    @field_validator("pattern")
    @classmethod
    def _regex(cls, pattern: str) -> str:
        try:
            re.compile(pattern)
        except re.error as exc:
            raise ValueError(f"invalid regular expression: {exc}") from None
        return pattern


class Messages(Model):
    """At least ``count`` messages on ``topic`` since the step began, counted as the recorder writes
    them, so the messages that end the step are in the recording (a topic the scenario does not
    record: as the grader hears them)."""

    condition: Literal["messages"]
    topic: RosName
    count: PositiveInt = Field(1, description="messages since the step began")


class Advertised(Model):
    """A student node offers the topic (and the recorder has matched every publisher of it, so
    what is published from then on is recorded), service or action."""

    condition: Literal["advertised"]
    topic: RosName | None = None
    service: RosName | None = None
    action: RosName | None = None
    action_type: ActionType | None = Field(
        None, description="with `action`: holds too once a student node offers one action of this type "
                          "under another name (the goals' `by_type`); filled from the contract with `by_type`")
    by_type: bool = Field(False, description="with `action`: an action of the contract's type under another "
                                             "name counts too (see `action_type`)")

    @model_validator(mode="after")
    def _exactly_one(self) -> "Advertised":
        if sum(v is not None for v in (self.topic, self.service, self.action)) != 1:
            raise ValueError("advertised needs exactly one of topic, service or action")
        if self.by_type and (self.action is None or self.action_type is None):
            raise ValueError("by_type needs an action of the contract (its type is the contract's) or action_type")
        return self


class Subscribed(Model):
    """A node other than the grader's subscribes to ``topic``."""

    condition: Literal["subscribed"]
    topic: RosName


def _condition_name(value: Any) -> Any:
    return {"condition": value} if isinstance(value, str) else value


Condition = Annotated[
    Union[GoalReached, ActionDone, ServiceDone, ReplayDone, ProcessExit, Output, Messages,
          Advertised, Subscribed],
    Field(discriminator="condition"), BeforeValidator(_condition_name)]
