"""What an analyzer outside this package may use: the public, stable part of the helpers.

A lab's own analyzer file (``analyzers: [my_lab_checks.py]`` in its rubric) or an installed
plug-in (entry point group ``grader.analyzers``, see ``grader.analyze.plugins``) imports from
here and from ``grader.analyze`` (``register``, ``Finding``, ``graded``, ``REQUIRED``), never from
the underscored modules, whose names may change with the built-in analyzers::

    from grader.analyze import REQUIRED, Finding, graded, register
    from grader.analyze.toolkit import events, missing_topic_feedback, since_start, sim_pose, thin
    from grader.contracts.events import StepStart      # the driver's events, one model per kind

    starts = [e.t for e in events(frames, StepStart) if e.step == "goal1"]

The frames an analyzer gets are described in docs/ARCHITECTURE.md ("Bag → DataFrames"): topic
name → DataFrame indexed by receive time ``t`` (seconds), plus ``"__meta__"`` (one row per topic).
"""

from __future__ import annotations

from grader.analyze._common import (
    EVENTS,
    META,
    ROSOUT,
    STDOUT,
    Frames,
    end_time,
    events,
    fmt,
    missing_topic_feedback,
    publishers_of,
    rosout_lines,
    scenario_end_time,
    scenario_start,
    sentence,
    service_calls,
    sim_pose,
    since_start,
    stdout_lines,
    thin,
    times,
    topic,
    topics_present,
)
from grader.contracts.world import WORLD_SIZE_M

__all__ = [
    "EVENTS", "META", "ROSOUT", "STDOUT", "WORLD_SIZE_M", "Frames",
    "end_time", "events", "fmt", "missing_topic_feedback", "publishers_of", "rosout_lines",
    "scenario_end_time", "scenario_start", "sentence", "service_calls", "sim_pose", "since_start",
    "stdout_lines", "thin", "times", "topic", "topics_present",
]
