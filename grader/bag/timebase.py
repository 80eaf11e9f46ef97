"""Bags of faster-than-real-time runs: every wall-clock time mapped to simulated time.

When a scenario runs with a time scale, the simulator publishes ``/clock`` and everything else
follows it, but the times a bag holds are wall clock: the recorder's log times and publish times
are DDS stamps, and the stamps inside ``/rosout`` messages and ROS console lines come from the
system clock whatever the node's clock is. Rather than mixing time bases, the bag keeps wall
clock everywhere (as recorded) plus the ``/clock`` messages, and readers map times through
:class:`TimeMap`: each ``/clock`` message pairs the wall time it was sent (its publish time)
with the simulated time it carries; between two of them time is interpolated, so a message
sent a third of the way through a tick gets a third of a tick. Analyzers then see simulated
seconds, the time base in which the student's timers ran, and measure exactly what they measure
at 1x.

A bag of a lockstep run (:mod:`grader.scenario.lockstep`, noted under :data:`LOCKSTEP_KEY`)
maps each time to the tick of the last ``/clock`` sent before it instead: there every message of
a tick is sent after its ``/clock`` and before the next, and the wall time in between says only
how busy the machine was, which must not move a time by a fraction of a tick.

``load_frames`` applies the map to every frame's index and ``pub_t`` and leaves it in the
frames under :data:`TIMEBASE`, so helpers that read wall-clock stamps out of message fields
(``_common.rosout_lines``, ``stdout_lines``) map those too (:func:`to_scenario_time`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from grader.sim.clock import CLOCK_TOPIC

#: custom_data key of the recorder's metadata: the run's time scale (absent: wall clock, 1x)
TIME_SCALE_KEY = "grader.time_scale"
#: custom_data key noting a lockstep run ("true")
LOCKSTEP_KEY = "grader.lockstep"
#: key of the :class:`TimeMap` in a frames dict loaded from a bag on simulated time
TIMEBASE = "__timebase__"


@dataclass(frozen=True)
class TimeMap:
    """Piecewise-linear map from wall seconds to simulated seconds (``wall`` increasing,
    ``sim`` non-decreasing); outside the recorded clock it continues with slope ``scale``."""

    wall: np.ndarray
    sim: np.ndarray
    scale: float
    #: lockstep: the simulated time of the last ``/clock`` sent at or before ``t`` (after the
    #: last one: its time; before the first: wall seconds before it)
    stepwise: bool = False

    def __call__(self, t: Any) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if self.stepwise:
            i = np.searchsorted(self.wall, t, side="right") - 1
            out = self.sim[np.clip(i, 0, len(self.sim) - 1)]
        else:
            out = np.interp(t, self.wall, self.sim)
        before = t < self.wall[0]
        after = t > self.wall[-1]
        out = np.where(before, self.sim[0] - (self.wall[0] - t) * self.scale, out)
        if self.stepwise:       # the clock ticks no more: what follows its last tick is in it
            return out
        return np.where(after, self.sim[-1] + (t - self.wall[-1]) * self.scale, out)


def time_map(clock: Any, scale: float, stepwise: bool = False) -> TimeMap | None:
    """The map of a bag's ``/clock`` frame (wall-clock index and ``pub_t``, fields
    ``clock.sec``/``clock.nanosec``); None when it holds no message."""
    if clock is None or not len(clock) or "clock.sec" not in clock.columns:
        return None
    wall = np.asarray(clock.index, dtype=float)
    if "pub_t" in clock.columns:          # the simulator's send time: no transport delay
        pub = clock["pub_t"].to_numpy(float)
        wall = np.where(np.isfinite(pub), pub, wall)
    sim = clock["clock.sec"].to_numpy(float) + clock["clock.nanosec"].to_numpy(float) * 1e-9
    order = np.argsort(wall, kind="stable")
    wall, sim = wall[order], np.maximum.accumulate(sim[order])
    keep = np.concatenate([[True], np.diff(wall) > 0])   # np.interp needs increasing x
    return TimeMap(wall[keep], sim[keep], float(scale), stepwise)


def to_scenario_time(frames: Mapping[str, Any], t: Any) -> np.ndarray:
    """Wall-clock times read out of messages (log stamps) in the frames' time base: simulated
    seconds when the bag ran on simulated time, else unchanged."""
    tmap = frames.get(TIMEBASE)
    arr = np.asarray(t, dtype=float)
    return tmap(arr) if isinstance(tmap, TimeMap) else arr


def bag_time_scale(custom_data: dict[str, str] | None) -> float:
    """The time scale a bag's metadata notes (1.0 when none)."""
    try:
        return max(1.0, float((custom_data or {}).get(TIME_SCALE_KEY, 1.0)))
    except (TypeError, ValueError):
        return 1.0


def bag_lockstep(custom_data: dict[str, str] | None) -> bool:
    """Whether a bag's metadata notes a lockstep run."""
    return (custom_data or {}).get(LOCKSTEP_KEY) == "true"


__all__ = ["CLOCK_TOPIC", "TIME_SCALE_KEY", "LOCKSTEP_KEY", "bag_lockstep", "TIMEBASE", "TimeMap", "time_map", "to_scenario_time",
           "bag_time_scale"]
