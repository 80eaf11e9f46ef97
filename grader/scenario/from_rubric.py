"""Translate a validated rubric scenario (grader.rubric.scenarios) into the driver's JSON spec.

The rubric model is what instructors write (validated, with line numbers); the spec is what
crosses the process boundary to the scenario child. Keeping the translation in one place means
neither side needs to know the other's details.
"""

from __future__ import annotations

from typing import Any

from grader.errors import GraderError
from grader.scenario.spec import NodeSpec, Scenario, Step


def _until(cond) -> dict[str, Any]:
    if cond is None:
        return {}
    p = dict(cond.params)
    name = cond.name
    if name == "goal_reached":
        x, y = p["goal"]
        return {"goal_reached": {"x": float(x), "y": float(y), "tol": float(p.get("tolerance", 0.1))},
                "settle_s": float(p.get("settle", 0.0))}
    if name == "messages":
        return {"messages": {"topic": p["topic"], "count": int(p.get("count", 1))}}
    if name == "action_done":
        return {"action_done": True}
    if name in ("service_done", "replay_done"):
        return {}          # those actions are synchronous in the driver
    if name == "process_exit":
        return {"process_exit": p["process"]}
    if name == "output":
        return {"output": {"process": p.get("process"), "pattern": p["pattern"]}}
    if name == "advertised":
        return {"advertised": {k: v for k, v in p.items() if k in ("topic", "service", "action") and v}}
    if name == "subscribed":
        return {"subscribed": p["topic"]}
    raise GraderError(f"scenario condition {name!r} is not supported by this driver")


def _step(step) -> Step:
    from grader.rubric import scenarios as rs

    a = step.action
    out = Step(id=step.id, timeout_s=float(step.timeout), until=_until(step.until),
               abort_on_timeout=step.on_timeout == "abort")
    if a is None:
        # no action: either a pure wait (no until) or wait for the condition
        out.wait = float(step.timeout) if step.until is None else 0.0
    elif isinstance(a, rs.PublishGoal):
        out.publish = {"topic": a.topic, "type": "std_msgs/msg/Float32MultiArray",
                       "msg": {"data": [float(a.x), float(a.y)]}}
    elif isinstance(a, rs.Publish):
        out.publish = {"topic": a.topic, "type": a.type, "msg": dict(a.msg), "count": a.count,
                       "rate_hz": a.rate_hz}
    elif isinstance(a, rs.ServiceCall):
        out.service = {"service": a.name, "type": a.type, "request": dict(a.request)}
    elif isinstance(a, rs.ActionGoal):
        out.action_goal = {"action": a.name, "type": a.type, "goal": dict(a.goal), "id": step.id}
    elif isinstance(a, rs.Replay):
        topics = list(a.topics or [])
        out.replay = {"bag": str(a.bag), "topic": topics[0] if topics else "/random_numbers",
                      "rate_hz": a.rate_hz or 50.0, **({"count": a.count} if a.count else {})}
    elif isinstance(a, rs.Start):
        out.start = {"processes": list(a.processes)}
    elif isinstance(a, rs.Stop):
        out.stop = {"processes": list(a.processes)}
    else:
        raise GraderError(f"step {step.id}: action {type(a).__name__} is not supported by this driver")
    return out


def _node(proc) -> NodeSpec:
    if proc.launch:
        raise GraderError(f"process {proc.name}: launch files are not supported yet "
                          "(list the launch file's nodes as processes instead)")
    return NodeSpec(
        name=proc.name, package=proc.package or "", executable=proc.executable, module=proc.module,
        params=dict(proc.parameters), remap=dict(proc.remappings), args=list(proc.args),
        stdin_script=[[ln.text, ln.delay] for ln in proc.stdin] if proc.stdin is not None else [],
        stdin=proc.stdin is not None, stdin_close=proc.stdin_close, env=dict(proc.env),
        autostart=proc.autostart, start_delay_s=proc.start_delay,
        wall_s=proc.limits.wall_s, cpu_s=proc.limits.cpu_s, memory_mb=proc.limits.memory_mb)


def scenario_from_rubric(sc) -> Scenario:
    return Scenario(id=sc.id, sim=sc.sim, nodes=[_node(p) for p in sc.processes],
                    steps=[_step(s) for s in sc.steps], record=list(sc.record or []),
                    time_limit_s=float(sc.limits.wall_s or max(60.0, sc.budget_s + 30.0)))
