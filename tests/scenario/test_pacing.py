"""How a paced replay waits for the student's answers (grader.scenario.pacing), against a model
of a subscriber: a keep-last history of 10 messages (the lab's ``qos_profile=10``), a few ms per
callback, and pauses in which it gets no CPU. The model runs on virtual time, so the tests are
exact and fast; the replay step that uses the pacer is graded live by the fixture tests."""

from __future__ import annotations

import collections
from dataclasses import dataclass, field
from typing import Callable

from grader.scenario.pacing import SHORT_WAIT_S, Pacer

DT = 0.001


@dataclass
class Subscriber:
    """A node fed by the replay: answers (one output line) ``answers(k)`` of the messages it takes."""

    stalls: list[tuple[float, float]] = field(default_factory=list)   # no CPU in [start, end)
    per_message_s: float = 0.004
    depth: int = 10
    answers: Callable[[int], bool] = lambda k: True
    dies_at: float | None = None
    now: float = 0.0
    queue: collections.deque = field(default_factory=collections.deque)
    received: int = 0
    lost: int = 0
    outputs: int = 0
    busy_until: float = 0.0

    def deliver(self, k: int) -> None:
        if len(self.queue) == self.depth:
            self.queue.popleft()        # keep-last: the oldest is dropped
            self.lost += 1
        self.queue.append(k)

    def alive(self) -> bool:
        return self.dies_at is None or self.now < self.dies_at

    def advance(self, dt: float) -> None:
        end = self.now + dt
        while self.now < end - 1e-12:
            self.now = min(end, self.now + DT)
            stalled = any(a <= self.now < b for a, b in self.stalls)
            if self.alive() and not stalled and self.queue and self.now >= self.busy_until:
                k = self.queue.popleft()
                self.received += 1
                self.outputs += self.answers(k)
                self.busy_until = self.now + self.per_message_s


def replay(sub: Subscriber, pacer: Pacer | None, n: int = 1000, rate_hz: float = 100.0) -> float:
    """The replay step's loop on virtual time; returns its duration."""
    def wait(predicate: Callable[[], bool], timeout: float) -> tuple[bool, float]:
        t = sub.now
        while not predicate() and sub.now - t < timeout:
            sub.advance(DT)
        return predicate(), sub.now - t

    for i in range(n):
        sub.deliver(i)
        sub.advance(1.0 / rate_hz)
        if pacer is not None:
            pacer.after(i, lambda: sub.outputs, wait, lambda: not sub.alive())
    sub.advance(2.0)
    return sub.now


def pacer(**kw: float) -> Pacer:
    return Pacer(lead=4, wait_s=kw.get("wait_s", 2.0), budget_s=kw.get("budget_s", 10.0), base=0)


def test_a_prompt_subscriber_is_never_waited_for_long() -> None:
    sub = Subscriber()
    p = pacer()
    took = replay(sub, p)
    assert (sub.lost, sub.outputs, p.resyncs) == (0, 1000, 0)
    assert took < 12.5 and p.paced


def test_a_starved_subscriber_loses_nothing_and_answers_every_message() -> None:
    # three pauses without CPU, the longest 4 s: what a MultiThreadedExecutor node showed on CI
    stalls = [(2.0, 2.8), (5.0, 6.5), (8.0, 12.0)]
    sub = Subscriber(stalls=stalls)
    p = pacer()
    replay(sub, p)
    assert (sub.lost, sub.outputs) == (0, 1000)
    assert p.paced and p.resyncs <= 1
    # the old pacing (0.25 s per wait, no budget) overflows the history in the same pauses
    old = Subscriber(stalls=stalls)
    replay(old, pacer(wait_s=SHORT_WAIT_S, budget_s=0.0))
    assert old.lost > 20 and old.outputs < 980


def test_a_silent_subscriber_gets_the_plain_schedule_after_four_leads() -> None:
    sub = Subscriber(answers=lambda k: False)
    p = pacer()
    took = replay(sub, p)
    assert not p.paced and p.waited_s < 3 * SHORT_WAIT_S + 0.01
    assert took < 10.0 + 2.0 + p.waited_s + 0.5          # was 61 s: a 0.25 s wait per 4 messages


def test_a_node_answering_some_messages_costs_at_most_the_budget() -> None:
    sub = Subscriber(answers=lambda k: k % 3 != 0)           # one message in three unanswered
    p = pacer(budget_s=10.0)
    took = replay(sub, p)
    assert p.paced and p.resyncs > 50
    assert p.extra_s <= 10.0 + 2.0                           # the last long wait may overrun it
    assert took <= 12.0 + p.waited_s and p.waited_s <= 12.0 + SHORT_WAIT_S * p.resyncs
    assert (sub.lost, sub.outputs) == (0, sum(k % 3 != 0 for k in range(1000)))


def test_pacing_stops_when_the_student_is_gone() -> None:
    sub = Subscriber(dies_at=3.0)
    p = pacer()
    took = replay(sub, p)
    assert not p.paced and took < 14.0 + 2.0
