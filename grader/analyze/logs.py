"""What nodes say: log lines (``/rosout``, where ``get_logger().info`` goes) and text messages.

* ``logged``: a node logged a line matching a pattern through the ROS logger. A line that only
  reached stdout (``print()``) does not count, and the feedback says so; a line logged under
  another student node's name is logged and counts (the name is the contract's to judge), and
  the feedback says whose it was.
* ``text_messages``: string messages on a topic match a pattern, and optionally count up.
* ``heard_messages``: a subscriber logs what it received: each logged text is a published one,
  and (almost) every message published while it listened was logged. The subscriber is the node
  that subscribes to the topic, whatever it is called, unless the rubric names its logger.
"""

from __future__ import annotations

import re
from typing import Any, Iterable, cast

import numpy as np
import pandas as pd
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, graded, register
from grader.analyze.evidence import SHARE
from grader.analyze._common import (EVENTS, Frames, events, missing_topic_feedback, rosout_lines,
                                    sim_node, stdout_lines, times, topic, traceback_mask)
from grader.contracts.events import EventRecord, Graph, StepStart

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    "logger": ("logger", ""), "matching": ("matching lines", ""), "lines_from_logger": ("lines logged by it", ""),
    "pattern": ("pattern", ""), "printed": ("lines printed instead of logged", ""), "min_count": ("lines needed", ""),
    "messages": ("messages", ""), "first": ("first messages", ""), "not_matching": ("messages not matching", ""),
    "counter": ("counter values", ""), "counting": ("counts up", ""), "published": ("messages published", ""),
    "heard": ("lines logged as heard", ""), "first_heard": ("first heard", ""), "share": ("share heard", SHARE),
    "foreign": ("logged but never published", ""), "published_while_listening": ("published while it listened", ""),
    "min_share": ("share needed", SHARE), "logged_by": ("matching lines logged by other nodes", ""),
    "after_step": ("judged from the start of step", ""), "max_messages": ("messages judged, at most", ""),
    "judged": ("messages judged", ""), "other_names": ("a node of another name may log it", ""),
    "logged_as": ("logged under the node name", ""),
}


def _logger_lines(frames: Frames, logger: str | Iterable[str]) -> pd.DataFrame:
    wanted = {_short(logger)} if isinstance(logger, str) else {_short(n) for n in logger}
    logs = rosout_lines(frames)
    return logs[logs["logger"].map(_short).isin(wanted)]


def _short(name: Any) -> str:
    """A logger or node name without namespace (``ns.talker``, ``/ns/talker`` -> ``talker``)."""
    return str(name).strip("/").replace("/", ".").rsplit(".", 1)[-1]


def _printed(frames: Frames, pattern: re.Pattern) -> list[str]:
    """Lines matching ``pattern`` that a student process wrote to stdout/stderr *without* the
    ROS logger: a line in the ROS console format (``[INFO] [stamp] [node]: text``) was logged
    (rclpy prints what it logs), and a traceback is a crash, not output."""
    lines = stdout_lines(frames)
    if lines.empty:
        return []
    plain = lines[lines["logger"].isna() & ~traceback_mask(lines["text"])]
    return [str(t) for t in plain["text"] if pattern.search(str(t))]


def _logged_by_others(frames: Frames, pattern: re.Pattern, loggers: set[str]) -> dict[str, list[str]]:
    """Matching lines logged under another logger than ``loggers`` (on /rosout, or in the ROS
    console format on a student's stdout): logger -> its lines. The grader's own and the
    simulator's loggers are not students'."""
    sim = sim_node(frames)
    mine = {_short(n) for n in loggers}
    out: dict[str, list[str]] = {}
    console = stdout_lines(frames)
    console = console[console["logger"].notna()] if not console.empty else console
    rosout = rosout_lines(frames)
    for logger, text in [*zip(rosout["logger"], rosout["text"]), *zip(console["logger"], console["text"])]:
        name = str(logger).strip("/")
        if _short(name) in mine or _short(name).startswith("grader_") or _short(name) == sim:
            continue
        if pattern.search(str(text)) and str(text) not in out.get(name, []):
            out.setdefault(name, []).append(str(text))
    return out


def _console_only(frames: Frames, pattern: re.Pattern, loggers: set[str]) -> list[str]:
    """Matching lines a student process printed in the ROS console format under one of
    ``loggers`` that are not on /rosout (a bare ``rclpy.logging.get_logger`` is not a node's)."""
    mine = {_short(n) for n in loggers}
    on_rosout = {str(t) for t in _logger_lines(frames, mine)["text"]}
    console = stdout_lines(frames)
    if console.empty:
        return []
    console = console[console["logger"].notna()]
    return [str(t) for lg, t in zip(console["logger"], console["text"])
            if _short(lg) in mine and pattern.search(str(t)) and str(t) not in on_rosout]


def _on_rosout(frames: Frames, others: dict[str, list[str]]) -> tuple[str, str] | None:
    """The first (logger, line) of ``others`` that reached /rosout: logged through a node's own
    ROS logger (``get_logger().info``), not only printed in its format."""
    logs = rosout_lines(frames)
    for logger, text in zip(logs["logger"], logs["text"]):
        name = str(logger).strip("/")
        if str(text) in others.get(name, ()):
            return name, str(text)
    return None


def _subscribers(frames: Frames, name: str) -> set[str]:
    """Student nodes seen subscribing to ``name`` in the driver's graph snapshots."""
    sim = sim_node(frames)
    out = set()
    for e in events(frames, Graph):
        for node in e.subscribers.get(name) or []:
            if not str(node).startswith("grader_") and str(node) != sim:
                out.add(str(node))
    return out


class LoggedParams(AnalyzerParams):
    logger: str = Field(description="the node's logger name, e.g. my_first_node")
    pattern: str = Field(description="regular expression the line must match")
    min_count: int = Field(1, ge=1, description="matching lines needed")
    other_names: bool = Field(True, description="a student node of another name that logged it earns it too")


@register("logged", judges=("logging",), evidence={**EVIDENCE, "value": ('logged line', '')},
          expect='a line matching {pattern!r} logged by {logger}', params=LoggedParams)
def logged(frames: Frames, p: LoggedParams) -> Finding:
    """A node logged a line matching ``pattern`` through the ROS logger: on /rosout, where
    ``get_logger().info`` goes. A student node of another name that logged it earns it as well
    (``other_names``): its name is judged by the contract and the item about the name, so a
    greeting under ``first_node`` costs the name's point once, not the greeting's too (issue 37:
    five of seven real first packages used another name). The feedback tells a printed line
    from a logged one and names the node that logged it."""
    pattern = re.compile(p.pattern)
    logger = p.logger.strip("/")
    lines = _logger_lines(frames, logger)
    hits = [str(t) for t in lines["text"] if pattern.search(str(t))]
    ev = {"logger": logger, "matching": hits[:10], "lines_from_logger": int(len(lines)),
          "pattern": p.pattern}
    if len(hits) >= p.min_count:
        return Finding(hits[0], 1.0, "pass", f"{logger} logged {hits[0]!r}.", ev)
    others = _logged_by_others(frames, pattern, {logger})
    if others:
        name, texts = next(iter(others.items()))
        ev["logged_by"] = {k: v[:3] for k, v in others.items()}
        on_rosout = _on_rosout(frames, others) if p.other_names else None
        if on_rosout:
            # the student's node logged it through the ROS logger under a name of its own: the
            # name is the contract's (and its own item's) to charge, not this item's
            other, text = on_rosout
            return Finding(text, 1.0, "pass", f"{other} logged {text!r} through the ROS logger (this lab asks "
                                              f"for the node name {logger}).", {**ev, "logged_as": other})
        return Finding.fail(f"{texts[0]!r} was logged by the node {name}, not by {logger}: the node that logs it "
                            f"must be called {logger}.", ev, value=texts[0])
    console = _console_only(frames, pattern, {logger})
    if console:
        return Finding.fail(f"{console[0]!r} reached the console under the name {logger} but not /rosout: log it "
                            "through the node's own logger, self.get_logger().info(...).", ev, value=console[0])
    printed = _printed(frames, pattern)
    ev["printed"] = printed[:10]
    if printed:
        return Finding.fail(f"{printed[0]!r} was printed, not logged: use self.get_logger().info(...) so the "
                            f"line goes to /rosout under the logger {logger}.", ev, value=printed[0])
    if len(lines):
        return Finding.fail(f"{logger} logged {len(lines)} line(s), none matching {p.pattern!r} "
                            f"(first: {str(lines['text'].iloc[0])!r}).", ev)
    return Finding.fail(f"Nothing matching {p.pattern!r} was logged or printed (the lab asks {logger} to log it "
                        "with get_logger().info).", ev)


class TextMessagesParams(AnalyzerParams):
    topic: str = Field(description="the topic of the string messages, e.g. /robot_news")
    pattern: str = Field(description="regex every message must match; group 1 = the counter")
    min_count: int = Field(3, ge=1, description="messages needed")
    counting: bool = Field(False, description="the counter (group 1) goes up by one per message")
    after_step: str | None = Field(None, description="judge only messages sent after this step began (None: all)")
    max_messages: int | None = Field(None, ge=1, description="... and only the first this many of them (None: all)")


@register("text_messages", evidence={**EVIDENCE, "value": ('messages matching', '')},
          expect='at least {min_count} messages matching {pattern!r}', params=TextMessagesParams)
def text_messages(frames: Frames, p: TextMessagesParams) -> Finding:
    """Every message on ``topic`` matches ``pattern`` (and counts up). With ``after_step`` and
    ``max_messages``, the same share of a run is judged in every run: a publisher's first
    messages reach the bag or not depending on when the recorder matched it (a counter that
    counts down matched the pattern with its first message only, graded 0.27 of 3 points in two
    runs and 0 in the third, bench_flake), so only messages sent after a step that begins once
    the recorder has matched the publisher count, and only as many as the step waits for."""
    df = topic(frames, p.topic)
    if df is None or "data" not in df.columns:
        return Finding.fail(missing_topic_feedback(frames, p.topic, "string messages"))
    judged = _judged(frames, df, p)
    if judged is None:
        return Finding.error(f"The scenario has no step {p.after_step!r} to judge {p.topic} from "
                             "(a rubric problem).", {"after_step": p.after_step})
    df = judged
    pattern = re.compile(p.pattern)
    texts = [str(v) for v in df["data"]]
    matches = [pattern.fullmatch(t) or pattern.search(t) for t in texts]
    ok = [m is not None for m in matches]
    ev: dict[str, Any] = {"messages": len(texts), "matching": int(sum(ok)), "first": texts[:5],
          "not_matching": [t for t, k in zip(texts, ok) if not k][:5]}
    problems = []
    if p.after_step:
        ev["judged"] = f"sent after step {p.after_step!r} began" + (
            f", the first {p.max_messages}" if p.max_messages else "")
    if len(texts) < p.min_count:
        when = " while the grader listened" if p.after_step else ""
        problems.append(f"only {len(texts)} message(s) on {p.topic}{when} (needs {p.min_count})")
    if not all(ok):
        problems.append(f"{len(texts) - sum(ok)} message(s) do not match {p.pattern!r}, e.g. "
                        f"{ev['not_matching'][0]!r}")
    if p.counting and all(ok) and matches and cast(re.Match, matches[0]).groups():
        numbers = [int(cast(re.Match, m).group(1)) for m in matches]      # (all matched)
        steps = np.diff(numbers)
        ev["counter"] = numbers[:20]
        if len(steps) and not np.all(steps == 1):
            problems.append(f"the counter does not go up by one per message ({numbers[:6]}...)")
    value = f"{sum(ok)}/{len(texts)} match"
    if not problems:
        return Finding(value, 1.0, "pass", f"{len(texts)} messages on {p.topic} like {texts[0]!r}.", ev)
    frac = sum(ok) / len(texts) if texts else 0.0
    frac = frac if len(texts) >= p.min_count else 0.0
    return Finding(value, frac if frac < 1 else 0.5, graded(frac if frac < 1 else 0.5),
                   "; ".join(problems).capitalize() + ".", ev)


def _judged(frames: Frames, df: pd.DataFrame, p: TextMessagesParams) -> pd.DataFrame | None:
    """The messages of ``df`` sent after step ``after_step`` began (send time when the bag has
    it, else receive time; the step's start event likewise), the first ``max_messages`` of them.
    None when the bag has no such step."""
    if p.after_step:
        starts = [e for e in events(frames, StepStart) if e.step == p.after_step]
        if not starts:
            return None
        t0 = starts[0].t
        sent = times(df)
        if "pub_t" in df.columns:
            pt = df["pub_t"].to_numpy(float)
            sent = np.where(np.isfinite(pt), pt, sent)
            ev_t = _event_sent(frames, starts[0])
            t0 = ev_t if ev_t is not None else t0
        df = df[sent >= t0]
    if p.max_messages:
        df = df.iloc[:p.max_messages]
    return df


def _event_sent(frames: Frames, event: EventRecord) -> float | None:
    """The send time of one /grader/events message (None when the bag has none for it)."""
    ev = topic(frames, EVENTS)
    if ev is None or "pub_t" not in ev.columns:
        return None
    row = np.flatnonzero(times(ev) == event.t)
    if not len(row):
        return None
    v = float(ev["pub_t"].to_numpy(float)[row[0]])
    return v if np.isfinite(v) else None


#: seconds between a message's recording and its subscriber's log line, at most, and how far
#: back a first line that is not a published message is taken to have been listening
HEARD_LAG_S = 1.0


def _listening_since(published: list[str], pub_t: np.ndarray, first: tuple[float, str]) -> float:
    """When the subscriber's listening is judged from: the recording of the first message it
    logged (the latest one with that text recorded before the line). One published before it may
    have gone out before DDS had matched the student's two processes, which no code of theirs
    decides: bench_flake at load ~24 judged a correct subscriber from 1 s before its first line,
    and its first two messages, sent before the match, cost it 0.4 points in one run of three."""
    t, text = first
    sent = [pt for pt, msg in zip(pub_t, published) if msg == text and pt <= t + HEARD_LAG_S]
    return float(sent[-1]) if sent else t - HEARD_LAG_S


class HeardMessagesParams(AnalyzerParams):
    topic: str = Field(description="the topic the subscriber listens to")
    logger: str | None = Field(None, description="the subscriber's logger name; None: the nodes subscribing "
                                                 "to topic")
    pattern: str = Field(r"I heard: (.*)", description="regex of the logged line; group 1 = the text it heard")
    min_share: float = Field(0.9, ge=0, le=1, description="share: of the messages published while it listened, "
                                                          "those it logged")


@register("heard_messages", judges=("logging",), evidence={**EVIDENCE, "value": ('messages heard', '')},
          expect='{min_share:.0%} of the published messages logged', params=HeardMessagesParams)
def heard_messages(frames: Frames, p: HeardMessagesParams) -> Finding:
    """A subscriber logs what it received: each logged text is a published one, and (almost)
    every message published from the first one it logged on was logged (one sent before DDS had
    matched the two processes was never its to hear). Without ``logger``, the subscriber is
    whichever node subscribes to ``topic`` (its name is the student's choice)."""
    df = topic(frames, p.topic)
    published = [str(v) for v in df["data"]] if df is not None and "data" in df.columns else []
    pub_t = times(df) if df is not None else np.array([])
    subscribers = _subscribers(frames, p.topic)
    if p.logger:
        loggers, who = {p.logger.strip("/")}, p.logger.strip("/")
    elif subscribers:
        loggers, who = subscribers, "Your subscriber " + ", ".join(sorted(subscribers))
    else:                           # nobody subscribed (or an older bag without graph snapshots)
        sim = sim_node(frames)
        loggers = {str(n) for n in rosout_lines(frames)["logger"]
                   if not _short(n).startswith("grader_") and _short(n) != sim}
        who = "No node"
    lines = _logger_lines(frames, loggers)
    pattern = re.compile(p.pattern)
    heard = [(float(t), m.group(1).strip()) for t, text in zip(lines["time"], lines["text"])
             if (m := pattern.search(str(text)))]
    ev = {"published": len(published), "heard": len(heard), "first_heard": [h for _, h in heard[:5]],
          "logger": sorted(loggers)}
    if not heard:
        others = _logged_by_others(frames, pattern, loggers)
        if others:
            name, texts = next(iter(others.items()))
            ev["logged_by"] = {k: v[:3] for k, v in others.items()}
            whose = (f"not by {p.logger}" if p.logger else f"which does not subscribe to {p.topic}")
            return Finding.fail(f"{texts[0]!r} was logged by the node {name}, {whose}.", ev)
        printed = _printed(frames, pattern)
        if printed:
            ev["printed"] = printed[:10]
            return Finding.fail(f"{printed[0]!r} was printed, not logged: use self.get_logger().info(...).", ev)
        if not published:
            return Finding.error(missing_topic_feedback(frames, p.topic, "nothing was published to hear"), ev)
        if not p.logger and not subscribers:
            return Finding.fail(f"No node subscribed to {p.topic} while {len(published)} messages were published "
                                "on it.", ev)
        return Finding.fail(f"{who} logged nothing matching {p.pattern!r} while {len(published)} "
                            f"messages were published on {p.topic} (is it spinning?).", ev)
    known = set(published)
    # lines heard before the recorder's first message may be messages the recorder had not yet
    # subscribed for: they cannot be checked, so they do not count either way
    first = float(pub_t[0]) - 0.05 if len(pub_t) else float("inf")
    foreign = [h for t, h in heard if h not in known and t >= first]
    window = (pub_t >= _listening_since(published, pub_t, heard[0])) & (pub_t <= heard[-1][0])
    expected = int(window.sum()) or len(heard)
    share = min(1.0, sum(1 for _, h in heard if h in known) / expected)
    ev.update(share=share, foreign=foreign[:5], published_while_listening=expected)
    value = f"{share:.0%} heard"
    name = ", ".join(sorted({str(n) for n in lines["logger"]})) or who
    if foreign:
        return Finding(value, 0.5, "partial", f"{len(foreign)} logged line(s) are not messages that were published, "
                       f"e.g. {foreign[0]!r}: log the received msg.data.", ev)
    if share >= p.min_share:
        return Finding(value, 1.0, "pass", f"{name} logged {len(heard)} messages it heard on {p.topic}.", ev)
    return Finding(value, share, graded(share), f"{name} logged only {share:.0%} of the messages published "
                   f"while it listened (needs {p.min_share:.0%}).", ev)
