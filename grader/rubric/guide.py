"""Reference material generated from the code, so it cannot drift from what the grader does.

* :func:`json_schema`: the rubric's JSON Schema for editors (VS Code's YAML extension reads it
  through a ``# yaml-language-server: $schema=...`` line), generated from the rubric model
  (``grader.rubric.schema`` and ``grader.scenario.model``). pydantic describes the canonical
  shapes; the YAML shorthands the loader accepts (``goal: [2, 7]``, ``until: action_done``,
  ``section: report``, ``start: client``...) are added where the model's before-validators
  take them.
* :func:`analyzer_reference`, :func:`scenario_reference`: the Markdown tables of
  ``rubrics/README.md`` between its ``<!-- generated:... -->`` markers.

``grader rubric schema`` prints the schema; ``grader rubric guide`` refreshes the README's
generated parts (a test fails when they are stale); the command line is ``grader.commands.rubric``'s.
"""

from __future__ import annotations

import json
import typing
from pathlib import Path
from typing import Any, Callable, Mapping

from pydantic_core import PydanticUndefined

from grader.errors import GraderError
from grader.contracts import contract as c
from grader.contracts.params import AnalyzerParams, bounds, type_words
from grader.rubric.load import load_rubric
from grader.rubric.schema import Rubric
from grader.scenario import model as m


# -------------------------------------------------------------------------------- JSON Schema
def json_schema() -> dict[str, Any]:
    schema = Rubric.model_json_schema(by_alias=True)
    defs = schema["$defs"]
    name = {"type": "string", "pattern": r"^[A-Za-z][A-Za-z0-9_-]*$"}
    defs["Goal"] = {"anyOf": [defs["Goal"], {"type": "array", "items": {"type": "number"},
                                              "minItems": 2, "maxItems": 2, "description": "[x, y]"}]}
    defs["StdinLine"] = {"anyOf": [defs["StdinLine"], {"type": "string", "description": "a line, typed after 0.5 s"}]}
    for key in ("Start", "Stop"):
        defs[key] = {"description": defs[key].get("description", ""),
                     "anyOf": [name, {"type": "array", "items": name, "minItems": 1}]}
    section = defs["Section"]
    defs["Section"] = {"description": section.get("description", ""), "anyOf": [
        {"type": "string", "pattern": r"^[a-z][a-z0-9_]*$"},
        {"type": "object", "minProperties": 1, "maxProperties": 1,
         "patternProperties": {r"^[a-z][a-z0-9_]*$": {"anyOf": [{"type": "integer", "minimum": 0},
                                                                {"type": "string"}]}},
         "additionalProperties": False}]}
    pair = {"type": "array", "items": {"type": "number", "minimum": 0, "maximum": 1}, "minItems": 2, "maxItems": 2}
    defs["Partial"] = {"description": defs["Partial"].get("description", ""), "anyOf": [
        {"enum": ["linear", "none"]},
        {"type": "object", "properties": {"steps": {"type": "array", "items": pair, "minItems": 1}},
         "required": ["steps"], "additionalProperties": False}]}
    for field in ("scenario", "requires"):
        prop = defs["Item"]["properties"][field]
        prop.pop("type", None)
        items = prop.pop("items", {"type": "string"})
        prop["anyOf"] = [items, {"type": "array", "items": items}]
    until = defs["Step"]["properties"]["until"]
    conditions = sorted(until["anyOf"][0]["discriminator"]["mapping"])
    until["anyOf"].insert(0, {"enum": conditions, "description": "a condition without parameters"})
    for field in ("publishes", "subscribes", "serves"):     # one name or a list
        prop = defs["NodeEntry"]["properties"][field]
        items = prop.pop("items", {"type": "string"})
        prop.pop("type", None)
        prop["anyOf"] = [items, {"type": "array", "items": items}]
    for key in ("PackageEntry", "ExecutableEntry", "NodeEntry", "TopicEntry", "ServiceEntry", "ActionEntry",
                "LaunchEntry"):        # `news: /robot_news` is `news: {name: /robot_news}`
        defs[key] = {"description": defs[key].get("description", ""),
                     "anyOf": [defs[key], {"type": "string", "description": "the name alone"}]}
    for key in ("ActionGoal", "Publish"):  # a contract name's type is filled in: `name: $turtle_goal`
        defs[key]["required"] = [r for r in defs[key].get("required", []) if r != "type"]
    schema = dict(_with_references(schema))
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "grader rubric"
    return schema


_REFERENCE = {"type": "string", "pattern": r"^\$[a-z][a-z0-9_]*$", "description": "a contract name: $role"}


def _with_references(node: Any) -> Any:
    """Every name-like text may also be a ``$role`` reference to the contract."""
    if isinstance(node, dict):
        if node.get("type") == "string" and "pattern" in node:
            return {"anyOf": [node, _REFERENCE]}
        return {k: _with_references(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_with_references(v) for v in node]
    return node


# ------------------------------------------------------------------------------ Markdown tables
def analyzer_reference() -> str:
    """Every registered analyzer: what it checks, its parameters with defaults and meaning."""
    from grader import analyze  # noqa: PLC0415 - analyze loads pandas, numpy (424 ms CPU), only on this path
    from grader.analyze.plugins import loaded_files  # noqa: PLC0415 - analyze.plugins loads pandas, numpy (424 ms CPU), only on this path

    # a lab's own analyzers (a rubric's ``analyzers:`` file) are documented with that lab, and are
    # loaded only in processes that loaded its rubric: the guide lists the grader's (and plug-ins')
    lab_files = {n for defined in loaded_files().values() for n in defined}
    out = []
    for name in analyze.names():
        if name in lab_files:
            continue
        fn = analyze.get(name)
        doc = (fn.__doc__ or "").strip().split("\n\n")[0].replace("\n", " ")
        module = fn.__module__.rsplit(".", 1)[-1]
        labels = analyze.evidence_labels(name)
        out.append(f"### `{name}` ({module})\n")
        if doc:
            out.append(doc + "\n")
        expect = analyze.expected_text(name)
        if expect:
            out.append(f"Expected, in the report: *{expect}*\n")
        timing = analyze.timing(name)
        if timing:
            out.append(f"Depends on timing ({timing}): on a recording the grading machine starved, a lost "
                       "point is an `error`, not a `fail` ([docs/busy-machines.md](../docs/busy-machines.md)).\n")
        model = analyze.params_model(name)
        out += _model_table(model) if model is not None else _defaults_table(name, labels)
        out.append("")
    return "\n".join(out)


def _model_table(model: type[AnalyzerParams]) -> list[str]:
    """The rows of an analyzer's parameters from its model: type and bounds, default, meaning."""
    rows = ["| parameter | type | default | meaning |", "|---|---|---|---|"]
    for key, info in model.model_fields.items():
        shape = ", ".join(w for w in (type_words(info), bounds(info)) if w)
        shown = "**required**" if info.is_required() else f"`{json.dumps(info.get_default())}`"
        cells = (shape, shown, info.description or "")
        rows.append(f"| `{key}` | " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return rows


def _defaults_table(name: str, labels: Mapping[str, Any]) -> list[str]:
    """The rows of a plug-in's parameters declared as a plain dict (no types: the evidence's
    labels say what a name means, when they know it)."""
    from grader import analyze  # noqa: PLC0415 - analyze loads pandas, numpy (424 ms CPU), only on this path
    from grader.analyze import REQUIRED  # noqa: PLC0415 - analyze loads pandas, numpy (424 ms CPU), only on this path

    rows = ["| parameter | default | meaning |", "|---|---|---|"]
    for key, default in analyze.defaults(name).items():
        label = labels.get(key)
        meaning = (f"{label[0]}" + (f" ({label[1]})" if label[1] and label[1] not in ("share", "time")
                                     else " (0..1)" if label[1] == "share" else "")) if label else ""
        shown = "**required**" if default is REQUIRED else f"`{json.dumps(default)}`"
        rows.append(f"| `{key}` | {shown} | {meaning} |")
    return rows


def _schema_type(prop: dict[str, Any]) -> str:
    """A field's type in words, from its JSON Schema."""
    if "$ref" in prop:
        return str(prop["$ref"]).rsplit("/", 1)[-1]
    if "anyOf" in prop:
        kinds = [_schema_type(p) for p in prop["anyOf"] if p.get("type") != "null"]
        return " or ".join(dict.fromkeys(kinds))
    if "enum" in prop or "const" in prop:
        return " \\| ".join(f"`{v}`" for v in prop.get("enum", [prop.get("const")]))
    kind = prop.get("type", "any")
    if kind == "array":
        return f"list of {_schema_type(prop.get('items', {}))}"
    if kind == "object":
        return "mapping"
    return str({"number": "number", "integer": "integer", "string": "text", "boolean": "true/false"}.get(kind, kind))


def _fields_table(cls: Any, skip: tuple[str, ...] = ()) -> str:
    props = cls.model_json_schema(by_alias=True).get("properties", {})
    rows = ["| key | type | default | meaning |", "|---|---|---|---|"]
    for key, field in cls.model_fields.items():
        if key in skip:
            continue
        name = field.alias or key
        default = field.default
        shown = "required" if default is PydanticUndefined else f"`{json.dumps(default, default=str)}`"
        meaning = (field.description or "").replace("\n", " ")
        rows.append(f"| `{name}` | {_schema_type(props.get(name, {}))} | {shown} | {meaning} |")
    return "\n".join(rows)


def scenario_reference() -> str:
    """Every step action and every ``until`` condition, from the scenario model."""
    out = ["#### Step actions (one per step)\n"]
    for key, cls in (("goal", m.Goal), ("publish", m.Publish), ("service", m.ServiceCall),
                     ("action", m.ActionGoal), ("replay", m.Replay), ("start", m.Start), ("stop", m.Stop)):
        doc = (cls.__doc__ or "").strip().split("\n\n")[0].replace("\n", " ")
        out.append(f"**`{key}:`** {doc}\n")
        if cls not in (m.Start, m.Stop):
            out.append(_fields_table(cls) + "\n")
    out.append("#### Conditions (`until:`)\n")
    for cls in typing.get_args(typing.get_args(m.Condition)[0]):
        tag = typing.get_args(cls.model_fields["condition"].annotation)[0]
        doc = (cls.__doc__ or "").strip().replace("\n", " ")
        params = [k for k in cls.model_fields if k != "condition"]
        out.append(f"**`{tag}`**: {doc}\n")
        if params:
            out.append(_fields_table(cls, skip=("condition",)) + "\n")
    out.append("#### Processes\n")
    out.append(_fields_table(m.Process) + "\n")
    out.append("#### Scenario\n")
    out.append(_fields_table(m.Scenario) + "\n")
    return "\n".join(out)


def contract_reference(rubrics: Path) -> str:
    """The contract's kinds and their keys, then the contract of every rubric in ``rubrics``."""
    out = ["#### Kinds of names\n"]
    for kind, cls in (("packages", c.PackageEntry), ("executables", c.ExecutableEntry), ("nodes", c.NodeEntry),
                      ("topics", c.TopicEntry), ("services", c.ServiceEntry), ("actions", c.ActionEntry),
                      ("launch_files", c.LaunchEntry)):
        doc = " ".join((cls.__doc__ or "").split())
        out.append(f"**`{kind}:`** {doc}\n")
        out.append(_fields_table(cls) + "\n")
    out.append("#### The labs' contracts\n")
    for path in sorted(rubrics.glob("*.yaml")):
        rubric = load_rubric(path)
        lines = rubric.contract.lines()
        out.append(f"**`{path.name}`** ({rubric.lab})" + ("" if lines else ": no contract") + "\n")
        if lines:
            out.append("| name | kind | used as | where it is fixed |\n|---|---|---|---|")
            out += [f"| `{name}` | {what} | {use} | {why} |" for what, name, use, why in lines]
            out.append("")
    return "\n".join(out)


#: the generated parts of a rubric guide, each made from the folder of rubrics it documents
GENERATED: dict[str, Callable[[Path], str]] = {"analyzers": lambda _rubrics: analyzer_reference(),
                                               "scenario": lambda _rubrics: scenario_reference(),
                                               "contract": contract_reference}


def refresh(readme: Path, check: bool = False) -> list[str]:
    """Rewrite the generated parts of ``readme`` (the guide of the rubrics beside it); returns
    the names of the parts that changed."""
    text = readme.read_text(encoding="utf-8")
    changed = []
    for name, make in GENERATED.items():
        begin, end = f"<!-- generated:{name} -->", f"<!-- /generated:{name} -->"
        if begin not in text or end not in text:
            raise GraderError(f"{readme} lacks the markers {begin} ... {end}")
        head, rest = text.split(begin, 1)
        old, tail = rest.split(end, 1)
        new = "\n" + make(readme.parent).strip() + "\n"
        if old != new:
            changed.append(name)
            text = head + begin + new + end + tail
    if changed and not check:
        readme.write_text(text, encoding="utf-8")
    return changed
