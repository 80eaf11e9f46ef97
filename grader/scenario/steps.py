"""Executing scenario steps: one function per action, one predicate per ``until`` condition."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any, Callable

from grader.scenario.driver import Driver, fill, import_type, to_plain
from grader.scenario.spec import Step


class StepOutcome(dict):
    """JSON-able record of a step: id, action, start/end (wall), duration, ended_by, detail."""


def _goal_reached(driver: Driver, cond: dict[str, Any], settle_s: float) -> Callable[[], bool]:
    """Turtle within ``tol`` of (x, y) and, for ``settle_s``, never farther than ``tol``."""
    x, y, tol = float(cond["x"]), float(cond["y"]), float(cond.get("tol", 0.1))
    state = {"since": None}

    def check() -> bool:
        pose = driver.pose
        if pose is None:
            return False
        inside = math.hypot(pose.x - x, pose.y - y) <= tol
        now = time.monotonic()
        if not inside:
            state["since"] = None
            return False
        if state["since"] is None:
            state["since"] = now
        return now - state["since"] >= settle_s

    return check


def _condition(driver: Driver, step: Step, ctx: dict[str, Any]) -> Callable[[], bool] | None:
    until = step.until or {}
    if not until:
        return None
    settle = float(until.get("settle_s", 0.0))
    if "goal_reached" in until:
        return _goal_reached(driver, until["goal_reached"], settle)
    if "messages" in until:
        topic = until["messages"]["topic"]
        want = int(until["messages"].get("count", 1))
        base = ctx.setdefault("message_base", {}).get(topic, 0)
        return lambda: driver.counts.get(topic, 0) - base >= want
    if "idle_s" in until:
        idle = float(until["idle_s"])
        return lambda: time.monotonic() - driver.last_output >= idle
    if "action_done" in until:
        return lambda: ctx.get("action_done", False)
    if "process_exit" in until:
        name = until["process_exit"]
        return lambda: (driver.processes.get(name) is None
                        or driver.processes[name].returncode is not None)
    if "output" in until:
        import re
        pattern = re.compile(until["output"]["pattern"])
        name = until["output"].get("process")
        start = {n: len(lines) for n, lines in driver.lines.items()}
        return lambda: any(pattern.search(line)
                           for n, lines in list(driver.lines.items()) if name in (None, n)
                           for line in lines[start.get(n, 0):])
    if "advertised" in until:
        what = until["advertised"]
        ready = {"publisher": what["topic"]} if "topic" in what else \
            {"service": what["service"]} if "service" in what else {"action_server": what["action"]}
        if "topic" in what:
            # advertised *and* recorded: the recorder's subscription must be in place too
            return lambda: driver.is_ready(ready) and all(driver.recorder_matched(n) for n in driver.student_nodes())
        return lambda: driver.is_ready(ready)
    if "subscribed" in until:
        return lambda: driver.is_ready({"subscriber": until["subscribed"]})
    raise ValueError(f"unknown until condition in step {step.id}: {sorted(until)}")


def prepare(driver: Driver, steps: list[Step]) -> None:
    """Create publishers and counters before student nodes start, so the recorder sees them."""
    for step in steps:
        if step.publish:
            driver.publisher(step.publish["topic"], step.publish["type"])
        if step.replay:
            driver.publisher(step.replay["topic"], step.replay.get("type", "std_msgs/msg/Float32MultiArray"))
        msgs = (step.until or {}).get("messages")
        if msgs:
            driver.count_messages(msgs["topic"], msgs.get("type"), wait_s=0.0)


def _do_publish(driver: Driver, spec: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    pub = driver.publisher(spec["topic"], spec["type"])
    msg = fill(import_type(spec["type"])(), spec.get("msg", {}))
    count = int(spec.get("count", 1))
    period = 1.0 / float(spec["rate_hz"]) if spec.get("rate_hz") else 0.0
    for i in range(count):
        pub.publish(msg)
        if i + 1 < count and period:
            time.sleep(period)
    plain = to_plain(msg)
    fields: dict[str, Any] = {"topic": spec["topic"], "type": spec["type"], "msg": plain}
    if spec["type"].endswith("Float32MultiArray") and len(plain.get("data", [])) >= 2:
        driver.event("goal_sent", goal=plain["data"][:2], topic=spec["topic"])
    else:
        driver.event("message_sent", **fields)
    return fields


def _do_stdin(driver: Driver, spec: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    proc = driver.processes.get(spec["process"])
    line = str(spec["line"])
    ok = False
    if proc is not None and proc.alive() and proc.popen.stdin is not None:
        try:
            proc.popen.stdin.write((line + "\n").encode())
            proc.popen.stdin.flush()
            ok = True
        except (BrokenPipeError, OSError, ValueError):
            ok = False
    driver.event("stdin_line", process=spec["process"], line=line, delivered=ok)
    return {"process": spec["process"], "line": line, "delivered": ok}


def _load_replay_rows(spec: dict[str, Any]) -> list[list[float]]:
    from grader.bag.frames import load_frames

    frames = load_frames(Path(spec["bag"]), topics=[spec["topic"]])
    df = frames[spec["topic"]]
    cols = sorted((c for c in df.columns if c.startswith("data[")), key=lambda c: int(c[5:-1]))
    rows = df[cols].to_numpy().tolist()
    return rows[: int(spec.get("count", len(rows)))]


def _do_replay(driver: Driver, spec: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    """Publish recorded array messages at a fixed pace (the student's node must keep up)."""
    type_name = spec.get("type", "std_msgs/msg/Float32MultiArray")
    pub = driver.publisher(spec["topic"], type_name)
    cls = import_type(type_name)
    rows = _load_replay_rows(spec)
    period = 1.0 / float(spec.get("rate_hz", 50.0))
    driver.event("replay_start", topic=spec["topic"], count=len(rows), rate_hz=1.0 / period,
                 bag=str(spec["bag"]))
    window = int(spec.get("window", 4))
    base = driver.output_count()
    lockstep = True
    t0 = t_start = time.monotonic()
    for i, row in enumerate(rows):
        pub.publish(cls(data=[float(v) for v in row if v == v]))
        delay = t0 + (i + 1) * period - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        if lockstep:
            # never run more than `window` inputs ahead of the student's outputs, so a slow
            # subscriber is paced instead of losing messages in its QoS history
            if not driver.wait_until(lambda: driver.output_count() - base >= i + 1 - window, 0.25,
                                     poll=0.002):
                base = driver.output_count() - (i + 1)   # inputs were lost or ignored: re-sync
            if i == 4 * window and driver.output_count() == base:
                lockstep = False      # it prints nothing per message: plain fixed rate
        t0 = max(t0, time.monotonic() - (i + 1) * period)   # no burst after a wait
    driver.last_output = time.monotonic()   # idle is measured from the last input
    driver.event("replay_end", topic=spec["topic"], count=len(rows), outputs=driver.output_count() - base,
                 lockstep=lockstep, duration_s=round(time.monotonic() - t_start, 3))
    return {"topic": spec["topic"], "count": len(rows)}


def _do_action_goal(driver: Driver, spec: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    from rclpy.action import ActionClient

    clients = ctx.setdefault("action_clients", {})
    key = (spec["action"], spec["type"])
    if key not in clients:
        clients[key] = ActionClient(driver.node, import_type(spec["type"]), spec["action"])
    client = clients[key]
    goal_id = spec.get("id", spec["action"])
    ctx["action_done"] = False
    ctx["goal_handle"] = None
    found = client.wait_for_server(timeout_sec=float(spec.get("server_timeout_s", 5.0)))
    driver.event("action_server_found" if found else "action_server_missing", action=spec["action"],
                 id=goal_id)
    if not found:
        ctx["action_done"] = True
        return {"id": goal_id, "server": False}
    goal = fill(import_type(spec["type"]).Goal(), spec.get("goal", {}))
    driver.event("action_goal_sent", action=spec["action"], id=goal_id, goal=to_plain(goal))
    result: dict[str, Any] = {"id": goal_id, "server": True}

    def on_result(future) -> None:
        res = future.result()
        result.update(status=int(res.status), result=to_plain(res.result))
        driver.event("action_result", action=spec["action"], id=goal_id, status=int(res.status),
                     result=to_plain(res.result))
        ctx["action_done"] = True

    def on_response(future) -> None:
        handle = future.result()
        result["accepted"] = bool(handle.accepted)
        driver.event("action_goal_response", action=spec["action"], id=goal_id, accepted=bool(handle.accepted))
        if handle.accepted:
            ctx["goal_handle"] = handle
            handle.get_result_async().add_done_callback(on_result)
        else:
            ctx["action_done"] = True

    client.send_goal_async(goal).add_done_callback(on_response)
    ctx["action_result"] = result
    return result


def _do_service(driver: Driver, spec: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    cls = import_type(spec["type"])
    client = driver.node.create_client(cls, spec["service"])
    out: dict[str, Any] = {"service": spec["service"]}
    if not client.wait_for_service(timeout_sec=float(spec.get("server_timeout_s", 5.0))):
        driver.event("service_missing", service=spec["service"])
        return out | {"available": False}
    request = fill(cls.Request(), spec.get("request", {}))
    driver.event("service_call", service=spec["service"], request=to_plain(request))
    future = client.call_async(request)
    driver.wait_until(future.done, float(spec.get("response_timeout_s", 5.0)))
    response = to_plain(future.result()) if future.done() else None
    driver.event("service_response", service=spec["service"], response=response)
    return out | {"available": True, "response": response}


def _do_stop(driver: Driver, spec: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    codes = {}
    for name in spec.get("processes", [spec.get("process")]):
        proc = driver.processes.get(name)
        codes[name] = proc.stop() if proc else None
        driver.event("node_stopped", process=name, returncode=codes[name])
    return {"returncodes": codes}


def _do_start(driver: Driver, spec: dict[str, Any], ctx: dict[str, Any]) -> dict[str, Any]:
    started = [name for name in spec.get("processes", []) if ctx["start_node"](name)]
    return {"started": started}


ACTIONS = {"publish": _do_publish, "stdin": _do_stdin, "replay": _do_replay,
           "action_goal": _do_action_goal, "service": _do_service, "stop": _do_stop,
           "start": _do_start}


def run_step(driver: Driver, step: Step, ctx: dict[str, Any]) -> StepOutcome:
    action = step.action()
    until = step.until or {}
    msgs = until.get("messages")
    if msgs:
        driver.count_messages(msgs["topic"], msgs.get("type"), wait_s=0.0)
        ctx.setdefault("message_base", {})[msgs["topic"]] = driver.counts.get(msgs["topic"], 0)
    start_wall, t0 = time.time(), time.monotonic()
    driver.event("step_start", step=step.id, action=action)
    detail: dict[str, Any] = {}
    ended_by = "done"
    gone = ctx.get("students_gone", lambda: False)

    def wait_for(cond) -> str:
        remaining = max(0.0, step.timeout_s - (time.monotonic() - t0))
        driver.wait_until(lambda: cond() or gone(), remaining)
        return "condition" if cond() else ("students_exited" if gone() else "timeout")

    if action == "wait":
        if driver.wait_until(gone, float(step.wait or 0.0)):
            ended_by = "students_exited"
        cond = _condition(driver, step, ctx)
        if cond is not None and ended_by != "students_exited":
            ended_by = wait_for(cond)
    else:
        try:
            detail = ACTIONS[action](driver, getattr(step, action), ctx)
        except Exception as exc:  # noqa: BLE001 - a bad step must not kill the whole run
            detail = {"error": f"{type(exc).__name__}: {exc}"}
            ended_by = "error"
        cond = _condition(driver, step, ctx) if ended_by != "error" else None
        if cond is not None:
            ended_by = wait_for(cond)
            if "settle_s" in until and "goal_reached" not in until:
                time.sleep(float(until["settle_s"]))
    if action == "action_goal" and ended_by == "timeout" and ctx.get("goal_handle") is not None:
        ctx["goal_handle"].cancel_goal_async()
        driver.event("action_cancel_sent", id=detail.get("id"))
    duration = time.monotonic() - t0
    driver.graph_snapshot()
    driver.event("step_end", step=step.id, action=action, ended_by=ended_by, duration_s=round(duration, 3))
    return StepOutcome(id=step.id, action=action, start=start_wall, duration_s=round(duration, 3),
                       ended_by=ended_by, detail=detail)
