"""A lab's contract: the names students must use exactly, declared once per rubric.

A lab text fixes some names (Lab 3's package ``random_numbers`` and topic ``/random_numbers``,
the goal-setter's ``/set_goal`` service and its nodes' names in the launch file) and leaves the
others open (what the subscriber node is called, which launch file starts the application).
The rubric's ``contract:`` section lists the first kind, each under a role id; everything else
is found by behaviour (the node that subscribes to ``/robot_news``, whatever it is called).

* The rubric refers to a contract name as ``$role`` (a whole value, e.g. ``topic: $news``) or
  ``${role}`` inside text (a title, a hint), so each name is written once. The loader resolves
  the references before validating (:func:`resolve_references`); a process naming an
  ``executable: $greeter`` (or ``launch: $app``) takes the package from the contract.
* Which items depend on which names is derived (:func:`item_roles`, :func:`scenario_roles`):
  the names an item's parameters mention, and those its scenario runs or drives.
* After a run, the names are looked for in the recording (``grader.analyze.contract``); a name
  the student spelt differently is one :class:`Mismatch` ("your service is called /setgoal;
  this lab asks for /set_goal"), and the items that depend on it and did not pass are blocked by
  it (``grader.rubric.score``) instead of each failing with a message of its own.
"""

from __future__ import annotations

import re
from dataclasses import replace
from typing import Any, Iterable, Iterator

from grader.contracts.contract import KINDS, REF, TEXT_REF, WHAT, Contract, Mismatch, _a, _short, node_name
from grader.contracts.text import suggest


# ------------------------------------------------------------------------ references, resolved
#: the contract kind a value under this key must name (``None``: the parent key decides)
_KEY_KIND = {"package": "packages", "executable": "executables", "launch": "launch_files",
             "topic": "topics", "topics": "topics", "goal_topic": "topics", "pose_topic": "topics",
             "cmd_topic": "topics", "action_name": "actions", "nodes": "nodes", "logger": "nodes"}
_NAME_UNDER = {"service": "services", "action": "actions"}


def _expected_kind(path: tuple) -> str | None:
    """The kind a name at ``path`` must be: ``service: {name: $x}`` a service, ``until:
    {condition: advertised, service: $x}`` too, ``package: $x`` a package; None: any."""
    keys = [p for p in path if isinstance(p, str)]
    if not keys:
        return None
    if keys[-1] == "name":
        return _NAME_UNDER.get(keys[-2]) if len(keys) >= 2 else None
    return _NAME_UNDER.get(keys[-1]) or _KEY_KIND.get(keys[-1])


def resolve_references(data: Any) -> tuple[Any, list[tuple[tuple, str]]]:
    """The rubric's raw data with every ``$role`` and ``${role}`` replaced by the contract's name,
    and the problems found, as ``(path, message)``. Unchanged when there is no reference."""
    if not isinstance(data, dict):
        return data, []
    problems: list[tuple[tuple, str]] = []
    raw = data.get("contract")
    contract = raw if isinstance(raw, dict) else {}
    table: dict[str, tuple[str, dict]] = {}     # role -> (kind, raw entry)
    for kind in KINDS:
        group = contract.get(kind)
        if not isinstance(group, dict):
            continue
        for role, entry in group.items():
            if role in table:
                problems.append((("contract", kind, role), f"role {role!r} is already {_a(WHAT[table[role][0]])} "
                                 f"(contract.{table[role][0]}.{role}); a role names one thing"))
                continue
            table[role] = (kind, _short(entry) if isinstance(entry, (str, dict)) else {})
    out = dict(data)
    if contract:
        out["contract"] = _resolve_contract(contract, table, problems)
    for key, value in data.items():
        if key != "contract":
            out[key] = _walk(value, (key,), table, problems)
    return out, problems


def _name_of(role: str, table: dict, path: tuple, problems: list, kinds: tuple[str, ...] | None) -> Any:
    found = table.get(role)
    if found is None:

        known = ", ".join(f"${r}" for r in table) or "none: the rubric has no contract"
        problems.append((path, f"${role} is not in the contract{suggest(role, list(table))} (roles: {known})"))
        return None
    kind, entry = found
    if kinds is not None and kind not in kinds:
        problems.append((path, f"${role} is {_a(WHAT[kind])} of the contract; this key needs "
                         f"{' or '.join(_a(WHAT[k]) for k in kinds)}"))
        return None
    return entry.get("name")


def _resolve_contract(contract: dict, table: dict, problems: list) -> dict:
    """Inside the contract: an executable's or launch file's ``package: $pkg``, and the names a
    node is found by (``serves: $set_goal``)."""
    out = dict(contract)
    for kind, keys in (("executables", {"package": ("packages",)}), ("launch_files", {"package": ("packages",)}),
                       ("nodes", {"publishes": ("topics",), "subscribes": ("topics",), "serves": ("services", "actions")})):
        group = contract.get(kind)
        if not isinstance(group, dict):
            continue
        new_group = {}
        for role, entry in group.items():
            if isinstance(entry, dict):
                entry = dict(entry)
                for key, kinds in keys.items():
                    value = entry.get(key)
                    at = ("contract", kind, role, key)
                    if isinstance(value, str) and (ref := REF.match(value)):
                        entry[key] = _name_of(ref[1], table, at, problems, kinds) or value
                    elif isinstance(value, list):
                        entry[key] = [(_name_of(ref[1], table, at + (i,), problems, kinds) or v)
                                      if isinstance(v, str) and (ref := REF.match(v)) else v
                                      for i, v in enumerate(value)]
                if table.get(role, ("",))[0] == kind:
                    table[role] = (kind, entry)      # a process using it takes the resolved package
            new_group[role] = entry
        out[kind] = new_group
    return out


def _walk(value: Any, path: tuple, table: dict, problems: list) -> Any:
    if isinstance(value, str):
        match = REF.match(value)
        if match:
            kind = _expected_kind(path)
            name = _name_of(match[1], table, path, problems, (kind,) if kind else None)
            return value if name is None else name
        if "${" in value:
            def sub(m: re.Match) -> str:
                name = _name_of(m[1], table, path, problems, None)
                return m[0] if name is None else str(name)
            return TEXT_REF.sub(sub, value)
        return value
    if isinstance(value, list):
        return [_walk(v, path + (i,), table, problems) for i, v in enumerate(value)]
    if isinstance(value, dict):
        out = {k: _walk(v, path + (k,), table, problems) for k, v in value.items()}
        # a process started by a contract executable or launch file takes its package from it
        for key, kind in (("executable", "executables"), ("launch", "launch_files")):
            ref = value.get(key)
            match = REF.match(ref) if isinstance(ref, str) else None
            if match and table.get(match[1], ("",))[0] == kind:
                package = table[match[1]][1].get("package")
                given = out.get("package")
                if given is None:
                    out["package"] = package
                elif given != package:
                    problems.append((path + ("package",), f"${match[1]} is {WHAT[kind]} {out[key]!r} of package "
                                     f"{package!r}; this process says package {given!r} (leave it out)"))
        # a step publishing on, calling or sending to a contract name takes its type from it
        ref_key = {"publish": "topic", "service": "name", "action": "name"}.get(path[-1] if path else "")
        ref = value.get(ref_key) if ref_key else None
        match = REF.match(ref) if isinstance(ref, str) else None
        if match and "type" not in value and table.get(match[1], ("", {}))[1].get("type"):
            out["type"] = table[match[1]][1]["type"]
        # ``until: {condition: advertised, action: $x, by_type: true}`` takes the action's type
        ref = value.get("action") if value.get("condition") == "advertised" and value.get("by_type") else None
        match = REF.match(ref) if isinstance(ref, str) else None
        if match and "action_type" not in value and table.get(match[1], ("", {}))[1].get("type"):
            out["action_type"] = table[match[1]][1]["type"]
        return out
    return value


# ------------------------------------------------------------------------ which items need which
def _strings(value: Any, path: tuple = ()) -> Iterator[tuple[tuple, str]]:
    if isinstance(value, str):
        yield path, value
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from _strings(v, path + (k,))
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            yield from _strings(v, path + (i,))


def _named_roles(contract: Contract, values: Iterable[str]) -> set[str]:
    """Roles of the topics, services, actions and nodes some value names."""
    names = {node_name(v) for v in values if v and not v.startswith("$")}
    out = set()
    for kind in ("topics", "services", "actions", "nodes"):
        for role, entry in getattr(contract, kind).items():
            if node_name(entry.name) in names:
                out.add(role)
    return out


def item_roles(contract: Contract, item: Any) -> set[str]:
    """Contract roles an item's parameters name (a topic it measures, a node it looks for)."""
    if not contract:
        return set()
    return _named_roles(contract, (s for _, s in _strings(dict(item.params))))


def scenario_roles(contract: Contract, scenario: Any) -> set[str]:
    """Contract roles a scenario runs (packages, executables, launch files of its processes) or
    drives (topics, services, actions its steps use)."""
    if not contract:
        return set()
    out: set[str] = set()
    for proc in scenario.processes:
        for role, pkg in contract.packages.items():
            if proc.package == pkg.name:
                out.add(role)
        for role, exe in contract.executables.items():
            if (proc.package, proc.executable) == (exe.package, exe.name):
                out.add(role)
        for role, launch in contract.launch_files.items():
            if (proc.package, proc.launch) == (launch.package, launch.name):
                out.add(role)
    data = scenario.model_dump(mode="json", include={"goal_topic", "steps"})
    return out | _named_roles(contract, (s for _, s in _strings(data)))


def merge_mismatches(per_scenario: dict[str, list[Mismatch]]) -> tuple[Mismatch, ...]:
    """One mismatch per role and found name, with every scenario it was seen in."""
    merged: dict[tuple, Mismatch] = {}
    for scenario, found in per_scenario.items():
        for m in found:
            key = (m.role, m.found)
            old = merged.get(key)
            merged[key] = replace(m, scenarios=(*(old.scenarios if old else ()), scenario))
    return tuple(merged.values())

