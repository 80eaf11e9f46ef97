"""How a paced replay (``Replay.lead``) waits for a student's node to answer each message.

A subscriber that logs one line per message is fed no faster than it answers: the replay stays
at most ``lead`` messages ahead of the student's output lines, so the node's QoS history (10
messages in the lab's code) never overflows and every pair it is sent is one it can answer. The
question is how long to wait for an answer that does not come:

* A correct node starved of CPU (a MultiThreadedExecutor on a loaded 2-core machine) stops
  answering for a while, then answers everything queued. A replay that gives up after 0.25 s and
  sends ``lead`` more each time overflows its history in a stall of ~0.6 s (tests/scenario/
  test_pacing.py): a CI run graded a correct MultiThreadedExecutor subscriber 855 of 1000, every
  value it printed right and 145 pairs without a line, pairs it by all appearances never got.
  So each wait lasts up to ``lead_wait_s`` (2 s: a stall of ~5 s fits a depth-10 history).
* A node that answers only some messages (throttled logging, a filter) would make every such
  wait run out: the waits beyond the old 0.25 s share one budget, ``lead_budget_s``; once it is
  spent the replay waits 0.25 s, as it did before. A node whose processes all exited is not
  waited for at all.
* A node that prints nothing per message is waited for 0.25 s (it is not slow: it has not
  answered anything), noticed after ``4 * lead`` messages and given the plain schedule
  (measured before this module: a silent subscriber made the 10 s replay last 61 s, re-synced
  every ``lead`` messages for 0.25 s; now 10.9 s).

The decisions are this class's alone (no ROS), so they are tested without a graph; the replay
step (:func:`grader.scenario.steps._replay`) supplies the waiting.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

#: a wait once the budget is spent (the replay's only wait before: it keeps slow runs bounded)
SHORT_WAIT_S = 0.25


@dataclass
class Pacer:
    """The answers needed before the next message of a replay, and how long to wait for them."""

    lead: int
    wait_s: float
    budget_s: float
    base: int                       # the student's output count when the replay started
    paced: bool = True
    resyncs: int = 0                # waits that ran out: messages counted as not answered
    waited_s: float = 0.0           # wall seconds spent waiting for answers
    extra_s: float = 0.0            # of which beyond ``SHORT_WAIT_S`` per wait (the budget's)
    _offset: int = field(default=0, repr=False)   # answers given up on (re-syncs)

    def needed(self, i: int) -> int:
        """Output lines needed after message ``i`` (0-based) was sent before sending the next."""
        return self.base + self._offset + i + 1 - self.lead

    def timeout(self, answered: bool = True) -> float:
        """How long the next wait may last: up to ``wait_s`` while the budget lasts, once the
        node has answered anything (a silent node is not slow)."""
        if not answered:
            return SHORT_WAIT_S
        return max(SHORT_WAIT_S, min(self.wait_s, SHORT_WAIT_S + self.budget_s - self.extra_s))

    def after(self, i: int, count: Callable[[], int], wait: Callable[[Callable[[], bool], float], tuple[bool, float]],
              students_gone: Callable[[], bool] = lambda: False) -> None:
        """Wait (``wait(predicate, timeout) -> (met, seconds)``) until the student has answered
        enough after message ``i``; on a timeout, the unanswered messages are given up on."""
        if not self.paced:
            return
        if students_gone():
            self.paced = False      # nobody left to answer: the plain schedule
            return
        need = self.needed(i)
        if count() < need:
            met, took = wait(lambda: count() >= need, self.timeout(count() > self.base))
            self.waited_s += took
            self.extra_s += max(0.0, took - SHORT_WAIT_S)
            if not met:
                self.resyncs += 1
                self._offset = count() - self.base - (i + 1)     # ``lead`` more before the next wait
        if i + 1 == 4 * self.lead and count() == self.base:
            self.paced = False      # it prints nothing per message: the plain schedule from here on

    def summary(self) -> dict[str, float | int | bool]:
        """For the replay's end event: whether it stayed paced, the waits that ran out, the time."""
        return {"paced": self.paced, "resyncs": self.resyncs, "waited_s": round(self.waited_s, 3)}
