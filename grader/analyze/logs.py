"""What nodes say: log lines (``/rosout``, where ``get_logger().info`` goes) and text messages.

* ``logged``: a node logged a line matching a pattern through the ROS logger. A line that only
  reached stdout (``print()``) does not count, and the feedback says so.
* ``text_messages``: string messages on a topic match a pattern, and optionally count up.
* ``heard_messages``: a subscriber logs what it received: each logged text is a published one,
  and (almost) every message published while it listened was logged.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from grader.analyze import REQUIRED, Finding, graded, register
from grader.analyze.evidence import SHARE
from grader.analyze._common import (Frames, missing_topic_feedback, rosout_lines, stdout_lines,
                                    times, topic)

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    "logger": ("logger", ""), "matching": ("matching lines", ""), "lines_from_logger": ("lines logged by it", ""),
    "pattern": ("pattern", ""), "printed": ("lines printed instead of logged", ""), "min_count": ("lines needed", ""),
    "messages": ("messages", ""), "first": ("first messages", ""), "not_matching": ("messages not matching", ""),
    "counter": ("counter values", ""), "counting": ("counts up", ""), "published": ("messages published", ""),
    "heard": ("lines logged as heard", ""), "first_heard": ("first heard", ""), "share": ("share heard", SHARE),
    "foreign": ("logged but never published", ""), "published_while_listening": ("published while it listened", ""),
    "min_share": ("share needed", SHARE),
}


def _logger_lines(frames: Frames, logger: str) -> pd.DataFrame:
    logs = rosout_lines(frames)
    return logs[logs["logger"].astype(str).str.strip("/") == logger.strip("/")]


@register("logged", evidence={**EVIDENCE, "value": ('logged line', '')},
          expect='a line matching {pattern!r} logged by {logger}', defaults={
    "logger": REQUIRED,            # required: the node's logger name, e.g. my_first_node
    "pattern": REQUIRED,           # required: regular expression the line must match
    "min_count": 1,
})
def logged(frames: Frames, p: dict) -> Finding:
    pattern = re.compile(p["pattern"])
    lines = _logger_lines(frames, p["logger"])
    hits = [str(t) for t in lines["text"] if pattern.search(str(t))]
    ev = {"logger": p["logger"], "matching": hits[:10], "lines_from_logger": int(len(lines)),
          "pattern": p["pattern"]}
    if len(hits) >= p["min_count"]:
        return Finding(hits[0], 1.0, "pass", f"{p['logger']} logged {hits[0]!r}.", ev)
    printed = [str(t) for t in stdout_lines(frames)["text"] if pattern.search(str(t))]
    ev["printed"] = printed[:10]
    if printed:
        return Finding.fail(f"{printed[0]!r} was printed, not logged: use self.get_logger().info(...) so the "
                            f"line goes to /rosout under the logger {p['logger']}.", ev, value=printed[0])
    if len(lines):
        return Finding.fail(f"{p['logger']} logged {len(lines)} line(s), none matching {p['pattern']!r} "
                            f"(first: {str(lines['text'].iloc[0])!r}).", ev)
    return Finding.fail(f"Nothing was logged by {p['logger']} (is the node named {p['logger']!r}, and does it "
                        "log with get_logger().info?).", ev)


@register("text_messages", evidence={**EVIDENCE, "value": ('messages matching', '')},
          expect='at least {min_count} messages matching {pattern!r}', defaults={
    "topic": REQUIRED,             # required: e.g. /robot_news
    "pattern": REQUIRED,           # required: regex every message must match; group 1 = the counter
    "min_count": 3,            # messages needed
    "counting": False,         # the counter (group 1) goes up by one per message
})
def text_messages(frames: Frames, p: dict) -> Finding:
    df = topic(frames, p["topic"])
    if df is None or "data" not in df.columns:
        return Finding.fail(missing_topic_feedback(frames, p["topic"], "string messages"))
    pattern = re.compile(p["pattern"])
    texts = [str(v) for v in df["data"]]
    matches = [pattern.fullmatch(t) or pattern.search(t) for t in texts]
    ok = [m is not None for m in matches]
    ev = {"messages": len(texts), "matching": int(sum(ok)), "first": texts[:5],
          "not_matching": [t for t, k in zip(texts, ok) if not k][:5]}
    problems = []
    if len(texts) < p["min_count"]:
        problems.append(f"only {len(texts)} message(s) on {p['topic']} (needs {p['min_count']})")
    if not all(ok):
        problems.append(f"{len(texts) - sum(ok)} message(s) do not match {p['pattern']!r}, e.g. "
                        f"{ev['not_matching'][0]!r}")
    if p["counting"] and all(ok) and matches and matches[0].groups():
        numbers = [int(m.group(1)) for m in matches]
        steps = np.diff(numbers)
        ev["counter"] = numbers[:20]
        if len(steps) and not np.all(steps == 1):
            problems.append(f"the counter does not go up by one per message ({numbers[:6]}...)")
    value = f"{sum(ok)}/{len(texts)} match"
    if not problems:
        return Finding(value, 1.0, "pass", f"{len(texts)} messages on {p['topic']} like {texts[0]!r}.", ev)
    frac = sum(ok) / len(texts) if texts else 0.0
    frac = frac if len(texts) >= p["min_count"] else 0.0
    return Finding(value, frac if frac < 1 else 0.5, graded(frac if frac < 1 else 0.5),
                   "; ".join(problems).capitalize() + ".", ev)


@register("heard_messages", evidence={**EVIDENCE, "value": ('messages heard', '')},
          expect='{min_share:.0%} of the published messages logged', defaults={
    "topic": REQUIRED,             # required: the topic the subscriber listens to
    "logger": REQUIRED,            # required: the subscriber's logger name
    "pattern": r"I heard: (.*)",   # group 1 = the text it heard
    "min_share": 0.9,          # share of messages published while it listened that it logged
})
def heard_messages(frames: Frames, p: dict) -> Finding:
    df = topic(frames, p["topic"])
    published = [str(v) for v in df["data"]] if df is not None and "data" in df.columns else []
    pub_t = times(df) if df is not None else np.array([])
    lines = _logger_lines(frames, p["logger"])
    pattern = re.compile(p["pattern"])
    heard = [(float(t), m.group(1).strip()) for t, text in zip(lines["time"], lines["text"])
             if (m := pattern.search(str(text)))]
    ev = {"published": len(published), "heard": len(heard), "first_heard": [h for _, h in heard[:5]]}
    if not heard:
        printed = [str(t) for t in stdout_lines(frames)["text"] if pattern.search(str(t))]
        if printed:
            return Finding.fail(f"{printed[0]!r} was printed, not logged: use self.get_logger().info(...).", ev)
        if not published:
            return Finding.error(missing_topic_feedback(frames, p["topic"], "nothing was published to hear"), ev)
        return Finding.fail(f"{p['logger']} logged nothing matching {p['pattern']!r} while {len(published)} "
                            f"messages were published on {p['topic']} (is it subscribed to {p['topic']} and spinning?).", ev)
    known = set(published)
    # lines heard before the recorder's first message may be messages the recorder had not yet
    # subscribed for: they cannot be checked, so they do not count either way
    first = float(pub_t[0]) - 0.05 if len(pub_t) else float("inf")
    foreign = [h for t, h in heard if h not in known and t >= first]
    window = (pub_t >= heard[0][0] - 1.0) & (pub_t <= heard[-1][0])
    expected = int(window.sum()) or len(heard)
    share = min(1.0, sum(1 for _, h in heard if h in known) / expected)
    ev.update(share=share, foreign=foreign[:5], published_while_listening=expected)
    value = f"{share:.0%} heard"
    if foreign:
        return Finding(value, 0.5, "partial", f"{len(foreign)} logged line(s) are not messages that were published, "
                       f"e.g. {foreign[0]!r}: log the received msg.data.", ev)
    if share >= p["min_share"]:
        return Finding(value, 1.0, "pass", f"{p['logger']} logged {len(heard)} messages it heard on {p['topic']}.", ev)
    return Finding(value, share, graded(share), f"{p['logger']} logged only {share:.0%} of the messages published "
                   f"while it listened (needs {p['min_share']:.0%}).", ev)
