"""Services a student node offers, judged from the driver's calls and what followed them.

The driver records every call it makes (``service_call``: request and type) and the answer
(``service_response``; None when none came in time), so both "the service answers success"
and "each request is republished as a message" are checked from the bag.
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np
import pandas as pd
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, graded, register
from grader.analyze.evidence import SINCE_START
from grader.analyze._common import Frames, events, missing_topic_feedback, since_start, times, topic
from grader.contracts.events import ServiceCall, ServiceMissing, ServiceResponse

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    "calls": ("calls", ""), "call": ("call", ""), "request": ("request", ""), "answered": ("answered", ""),
    "ok": ("as expected", ""), "service_type": ("service type", ""), "service_missing": ("calls without a server", ""),
    "messages": ("messages after the call", ""), "got": ("message values", ""), "wanted": ("requested values", ""),
    "match": ("values match", ""), "service": ("service", ""), "field": ("response field", ""),
    "expected": ("expected value", ""), "fields": ("message field: request field", ""),
    "window_s": ("time allowed for the message", "s"), "tol": ("allowed difference", ""),
    "success": ("success", ""), "t": ("called at", SINCE_START), "message_t": None,
    "called_as": ("called under the name", ""),
}


def _calls(frames: Frames, service: str) -> list[dict[str, Any]]:
    """Calls to ``service`` in order, each with its response (None: no response in time); a
    call the driver made to the name the student's node serves it under instead
    (``ServiceCall.served_by``) is one too, with that name in ``under``."""
    out: list[dict[str, Any]] = []
    for e in events(frames, (ServiceCall, ServiceResponse)):
        if service not in (e.service, e.asked_for):
            continue
        if isinstance(e, ServiceCall):
            under = e.service if e.asked_for == service else None
            out.append({"t": e.t, "step": e.step, "type": e.type, "under": under,
                        "request": e.request, "response": None, "answered": False})
        elif out and not out[-1]["answered"]:
            out[-1].update(response=e.response, answered=e.response is not None)
    return out


def _no_calls(frames: Frames, service: str) -> Finding:
    missing = [e for e in events(frames, ServiceMissing) if e.service == service]
    if missing:
        return Finding.fail(f"The service {service} never appeared: create it with "
                            f"create_service(<type>, '{service.lstrip('/')}', callback) and keep spinning.",
                            {"service_missing": len(missing)})
    return Finding.error(f"The scenario made no calls to {service}, so this item could not be tested.")


class ServiceAnswersParams(AnalyzerParams):
    service: str = Field(description="the service, e.g. /set_goal")
    field: str = Field("success", description="response field to check")
    expected: bool | int | float | str = Field(True, description="value it must have")


@register("service_answers", params=ServiceAnswersParams, judges=("ros names",),
          evidence={**EVIDENCE, "value": ('calls answered as expected', '')},
          expect='{field} = {expected} in every response')
def service_answers(frames: Frames, p: ServiceAnswersParams) -> Finding:
    """Every call got a response, with ``field`` equal to ``expected``."""
    calls = _calls(frames, p.service)
    if not calls:
        return _no_calls(frames, p.service)
    rows, ok = [], 0
    for k, c in enumerate(calls, 1):
        got = (c["response"] or {}).get(p.field) if c["answered"] else None
        good = c["answered"] and got == p.expected
        ok += good
        rows.append({"call": k, "request": c["request"], "answered": c["answered"], p.field: got, "ok": good})
    frac = ok / len(calls)
    ev = {"calls": rows, "service_type": calls[0]["type"]}
    value = f"{ok}/{len(calls)} answered {p.field}={p.expected}"
    under = calls[0]["under"]
    if under is not None:       # the item about the service's name: the one charge for it
        ev["called_as"] = under
        return Finding(f"served as {under}", 0.0, "fail",
                       f"There is no {p.service}: your node serves it as {under} (called there, {ok} of "
                       f"{len(calls)} calls answered {p.field} = {p.expected}). Give create_service the "
                       f"name '{p.service.lstrip('/')}': the lab's callers ask for {p.service}.", ev)
    if ok == len(calls):
        return Finding(value, 1.0, "pass", f"All {len(calls)} calls to {p.service} answered "
                                           f"{p.field} = {p.expected}.", ev)
    bad = next(r for r in rows if not r["ok"])
    why = ("no response arrived" if not bad["answered"]
           else f"the response had {p.field} = {bad[p.field]!r}")
    return Finding(value, frac, graded(frac), f"Call {bad['call']} to {p.service} "
                   f"({bad['request']}): {why}; set response.{p.field} = {p.expected} before "
                   "returning the response.", ev)


class RequestEchoedParams(AnalyzerParams):
    service: str = Field(description="the service, e.g. /set_goal")
    topic: str = Field(description="where each request must be published, e.g. /goal")
    fields: dict[str, str] = Field(description="message field -> request field, e.g. {x: x, y: y}")
    window_s: float = Field(2.0, ge=0, description="s: after the call in which the message must arrive")
    tol: float = Field(1e-6, ge=0, description="allowed difference of numeric fields")


@register("request_echoed", params=RequestEchoedParams, timing="a message within window_s of the call",
          evidence={**EVIDENCE, "value": ('requests republished', '')},
          expect='one message on {topic} per request, with its values')
def request_echoed(frames: Frames, p: RequestEchoedParams) -> Finding:
    """Each call is followed by exactly one message on ``topic`` carrying the request's values."""
    calls = _calls(frames, p.service)
    if not calls:
        return _no_calls(frames, p.service)
    df = topic(frames, p.topic)
    t = times(df) if df is not None else np.array([])
    rows, score = [], 0.0
    for k, c in enumerate(calls, 1):
        t_next = calls[k]["t"] if k < len(calls) else math.inf
        lo, hi = c["t"] - 0.2, min(c["t"] + p.window_s, t_next)
        idx = np.nonzero((t >= lo) & (t < hi))[0]
        row: dict[str, Any] = {"call": k, "request": c["request"], "messages": int(len(idx)),
                               "t": float(since_start(frames, [c["t"]])[0]),
                               "message_t": since_start(frames, t[idx]).tolist()}
        if len(idx):
            msg = cast(pd.DataFrame, df).iloc[idx[0]]      # (messages found: df is there)
            got = {f: _value(msg.get(f)) for f in p.fields}
            want = {f: _value(c["request"].get(r)) for f, r in p.fields.items()}
            match = all(_same(got[f], want[f], p.tol) for f in p.fields)
            row.update(got=got, wanted=want, match=match)
            score += (1.0 if len(idx) == 1 else 0.5) if match else 0.0
        rows.append(row)
    frac = score / len(calls)
    ev = {"calls": rows, "topic": p.topic}
    n_ok = sum(1 for r in rows if r.get("match") and r["messages"] == 1)
    value = f"{n_ok}/{len(calls)} echoed"
    under = calls[0]["under"]
    called = (f" (called as {under}, the name your node serves it under; the lab's name is {p.service})"
              if under is not None else "")
    if under is not None:
        ev["called_as"] = under
    if n_ok == len(calls):
        return Finding(value, 1.0, "pass", f"Each of the {len(calls)} requests was published once on "
                                           f"{p.topic} with the requested values{called}.", ev)
    if df is None:
        return Finding(value, 0.0, "fail", missing_topic_feedback(frames, p.topic, "one message per request")
                       + f" Publish each {p.service} request there.", ev)
    bad = next(r for r in rows if not (r.get("match") and r["messages"] == 1))
    if bad["messages"] == 0:
        why = f"no message on {p.topic} within {p.window_s:g} s"
    elif not bad.get("match"):
        why = f"the message had {bad['got']} instead of {bad['wanted']}"
    else:
        why = f"{bad['messages']} messages instead of one"
    return Finding(value, frac, graded(frac), f"Request {bad['call']} ({bad['request']}){called}: {why}.", ev)


def _value(v: Any) -> Any:
    try:
        return float(v)
    except (TypeError, ValueError):
        return v


def _same(a: Any, b: Any, tol: float) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return math.isfinite(a) and math.isfinite(b) and abs(a - b) <= tol
    return bool(a == b)
