"""The ROS graph a submission builds: which nodes run, and what its launch file declares.

The driver snapshots the graph (node names, publishers, subscribers, services) at the end of
every step (``graph`` events) and records what a launch file declared (``launch_resolved``), so
"the launch file starts these three nodes with these names" is checked from the bag alone.
"""

from __future__ import annotations

from typing import cast

from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, graded, register
from grader.analyze._common import Frames, events, own_exits, sim_node
from grader.contracts.events import Graph, LaunchResolved, NodeStarted, NodeUnavailable

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {

    "nodes": ("nodes", ""), "node": ("node", ""), "running": ("ran", ""), "declared": ("declared by the launch file", ""),
    "seen": ("nodes seen in the ROS graph", ""), "launch": ("launch file", ""), "launch_process": ("the rubric process running the launch file", ""),
    "installed": ("installed with the package", ""), "notes": ("notes", ""),
    "node_name": ("node name", ""), "package": ("package", ""), "executable": ("executable", ""),
    "stand_in": ("played by the reference simulator", ""), "error": ("error", ""), "start_delay": ("start delay", "s"),
}


def _full(name: str) -> str:
    return "/" + str(name).strip("/")


class NodesRunningParams(AnalyzerParams):
    nodes: tuple[str, ...] = Field(description="node names, e.g. [/turtlesim, /goal_setter]")
    launch_process: str | None = Field(None, description="rubric process of a launch file: nodes must also be "
                                                         "declared there")


@register("nodes_running", params=NodesRunningParams, judges=("node names",),
          evidence={**EVIDENCE, "value": ('nodes running', '')}, expect='{nodes}')
def nodes_running(frames: Frames, p: NodesRunningParams) -> Finding:
    """Each expected node ran (seen in a graph snapshot) and, with ``launch_process``, was
    declared by that launch file under that name."""
    expected = [_full(n) for n in p.nodes]
    if not expected:
        return Finding.error("The rubric lists no nodes to look for (params: nodes).")
    snapshots = events(frames, Graph)
    if not snapshots:
        return Finding.error("The scenario recorded no graph snapshots (scenario problem).")
    seen = sorted({_full(n) for e in snapshots for n in e.nodes})
    stale = [n for n in expected if n in seen and not _seen_running(frames, snapshots, n)]
    declared: list[str] | None = None
    launch = None
    if p.launch_process:
        resolved = [e for e in events(frames, LaunchResolved) if e.process == p.launch_process]
        if not resolved:
            return Finding.error(f"No launch file was resolved for process {p.launch_process!r} "
                                 "(scenario problem).")
        launch = resolved[-1].launch
        nodes = resolved[-1].nodes
        declared = [_full(n["node_name"]) for n in nodes if n.get("node_name")]
        failed = [n.get("error") for n in nodes if n.get("error") and not n.get("node_name")]
        if failed:
            return Finding(f"0/{len(expected)} nodes", 0.0, "fail",
                           f"The launch file could not be used: {failed[0]}", {"launch": launch, "nodes": nodes})
    rows, problems = [], []
    for name in expected:
        running = name in seen and name not in stale
        in_launch = declared is None or name in declared
        rows.append({"node": name, "running": running, "declared": in_launch})
        if not in_launch:
            problems.append(f"{name} is not declared by {launch} (it declares "
                            f"{', '.join(declared or ()) or 'no named node'}; set name='{name.strip('/')}')")
        elif not running:
            problems.append(f"{name} was never seen running in the ROS graph ({_why_absent(frames, name, seen)})")
    ok = sum(1 for r in rows if r["running"] and r["declared"])
    frac = ok / len(rows)
    ev = {"nodes": rows, "seen": seen, "declared": declared, "launch": launch}
    if stale:
        ev["stale"] = stale
    value = f"{ok}/{len(rows)} nodes"
    if not problems:
        return Finding(value, 1.0, "pass", f"All {len(rows)} nodes ran: {', '.join(expected)}.", ev)
    return Finding(value, frac, graded(frac), "; ".join(problems) + ".", ev)


def _makers(frames: Frames, name: str) -> list[str]:
    """The student processes that could have created node ``name``: those started to make it
    (a launch file's node), else those whose node names nobody declared (``ros2 run``) unless
    ``name`` is the reference simulator's or the grader's own."""
    started = events(frames, NodeStarted)
    declared = [e.process for e in started if _full(e.node_name or "") == name]
    if declared or name == _full(sim_node(frames)) or name.rsplit("/", 1)[-1].startswith("grader_"):
        return declared
    return [e.process for e in started if not e.node_name]


def _seen_running(frames: Frames, snapshots: list[Graph], name: str) -> bool:
    """Node ``name`` is in a snapshot taken while a process that could have made it was alive.

    The graph lags behind a process that has died, so a snapshot taken after the crash of the
    only process that could have made the node shows a node no one could reach any more: a
    greeter that raised in its constructor was once credited with its name by the snapshot its
    crash ended the step with, and not in other runs. Not a student process's node (the
    reference simulator's), or a bag from before snapshots said what was ``running``: seen is seen.
    """
    makers = set(_makers(frames, name))
    for e in snapshots:
        if name not in {_full(n) for n in e.nodes}:
            continue
        running = e.running
        if not makers or running is None or makers & set(running):
            return True
    return False


def _why_absent(frames: Frames, name: str, seen: list[str]) -> str:
    """What became of the process that should have created node ``name``: it could not be
    started, it exited (crashed, or returned on its own), or it ran and created other nodes."""
    mine = _makers(frames, name)
    unavailable = [e for e in events(frames, NodeUnavailable)
                   if not e.node_name or _full(e.node_name) == name]
    if not mine and unavailable:
        return f"{unavailable[0].process} could not be started"
    exits = [e for e in own_exits(frames) if e.process in mine]
    if exits:
        code = exits[0].returncode
        return (f"{exits[0].process} crashed with exit code {code}" if code not in (0, None)
                else f"{exits[0].process} returned on its own before its node was seen running")
    others = [n for n in seen if not n.rsplit("/", 1)[-1].startswith("grader_")]
    return ("its process kept running; the nodes seen are " + ", ".join(others)) if others else \
        "its process kept running without creating a node"


class LaunchInstalledParams(AnalyzerParams):
    launch_process: str = Field(description="the rubric process that runs the launch file")


@register("launch_installed", params=LaunchInstalledParams, evidence={**EVIDENCE, "value": ('launch file', '')},
          expect='installed in share/<package>')
def launch_installed(frames: Frames, p: LaunchInstalledParams) -> Finding:
    """The launch file is installed into the package's share folder, where ``ros2 launch
    <package> <file>`` looks (setup.py ``data_files``)."""
    resolved = [e for e in events(frames, LaunchResolved) if e.process == p.launch_process]
    if not resolved:
        return Finding.error(f"No launch file was resolved for process {p.launch_process!r}.")
    e = resolved[-1]
    ev = {"launch": e.launch, "installed": e.installed, "notes": list(e.notes)}
    if e.installed:
        return Finding("installed", 1.0, "pass", f"{e.launch} is installed with the package.", ev)
    if not ev["notes"] and any(c in str(e.launch) for c in "*?["):
        return Finding.fail(f"The package has no launch file ({e.launch}).", ev, value="no launch file")
    return Finding.fail(" ".join(cast(list, ev["notes"])) or f"{e.launch} is not installed with the package.", ev,
                        value="not installed")
