"""What a process the grader starts may use and is typed: its resource limits and its scripted
standard input. Shared by the rubric's scenarios (``grader.scenario.model``), the process runner
(``grader.runner``) and ``grader doctor``: the ground floor, so none of them reaches up for it."""

from __future__ import annotations


from pydantic import Field, model_validator

from grader.contracts.fields import Model, NonNegativeFloat, PositiveFloat, PositiveInt


class StdinLine(Model):
    """A line typed into a process ``delay`` seconds after the previous one (or after the prompt)."""

    line: str = Field(description="the text typed (Enter is added)")
    delay: NonNegativeFloat = Field(0.5, description="s after the previous line (the first: after the "
                                    "node is up and its topics are recorded)")

    @model_validator(mode="before")
    @classmethod
    def _plain(cls, value: object) -> object:
        return {"line": value} if isinstance(value, str) else value


class Limits(Model):
    """Resource limits of a process or a scenario; None leaves the grader's default.

    ``memory_mb`` of a process bounds its address space (rclpy + Fast DDS need about 1 GiB);
    ``memory_mb`` of a scenario bounds the memory of all its student processes together (the
    sandbox's cgroup; default 2048).
    """

    wall_s: PositiveFloat | None = Field(None, description="wall-clock seconds")
    cpu_s: PositiveInt | None = Field(None, description="CPU seconds")
    memory_mb: PositiveInt | None = Field(None, description="MiB: a process's address space; a scenario's "
                                          "student processes together")
