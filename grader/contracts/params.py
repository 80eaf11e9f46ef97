"""The parameters an analyzer accepts: one pydantic model per analyzer, declared beside it.

Why a model: every threshold that decides a grade is rubric data, and a value of the wrong kind
(``tol_reached: -1``, ``tol_reached: "x"``) must be refused where the rubric is loaded, on the
line it is written, with what is allowed, instead of raising inside an analysis or deciding a
grade nobody meant. One model carries each value from the rubric to the analyzer (which reads
attributes, typed), to the rubric guide (type, bounds and meaning) and to the finding (``params``:
every value it ran with).

The models are lax where YAML is (an integer for a float, a list for a tuple) and closed to
unknown names; frozen, so no analysis changes the values another one reads.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import annotated_types
from pydantic import BaseModel, ConfigDict, ValidationError
from pydantic.fields import FieldInfo
from pydantic_core import ErrorDetails

__all__ = ["AnalyzerParams", "bounds", "default_values", "explained", "problems", "type_words"]


class AnalyzerParams(BaseModel):
    """Base of every analyzer's ``Params``: fields with a default (``Field(0.1, gt=0,
    description="m: ...")``) or required (``Field(description=...)``, no default)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


_BOUND_WORDS = (("gt", "> {}"), ("ge", ">= {}"), ("lt", "< {}"), ("le", "<= {}"))


def bounds(info: FieldInfo) -> str:
    """A field's bounds in words, e.g. ``> 0`` or ``>= 0, <= 1`` ('' when it has none)."""
    words = []
    for meta in info.metadata:
        if isinstance(meta, (annotated_types.BaseMetadata, annotated_types.Interval)):
            words += [form.format(_number(getattr(meta, key))) for key, form in _BOUND_WORDS
                      if getattr(meta, key, None) is not None]
    return ", ".join(words)


def _number(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) and math.isfinite(value) else str(value)


def type_words(info: FieldInfo) -> str:
    """A field's type as a rubric author reads it (``number``, ``list of text``...)."""
    return _words(info.annotation)


_SIMPLE = {bool: "true/false", int: "integer", float: "number", str: "text", type(None): "null"}


def _words(annotation: object) -> str:
    if annotation in _SIMPLE:
        return _SIMPLE[annotation]
    args = [a for a in getattr(annotation, "__args__", ()) if a is not Ellipsis]
    origin = getattr(annotation, "__origin__", None)
    if origin in (list, tuple, set, frozenset):
        return f"list of {_words(args[0])}" if args else "list"
    if origin is dict:
        return f"map of {_words(args[0])} to {_words(args[1])}" if len(args) == 2 else "map"
    if args:                                            # a union (X | None, Literal...)
        if all(not isinstance(a, type) for a in args):  # Literal["a", "b"]
            return " or ".join(repr(a) for a in args)
        return " or ".join(_words(a) for a in args)
    return "any value" if annotation is Any else getattr(annotation, "__name__", str(annotation))


def default_values(model: type[AnalyzerParams]) -> dict[str, object]:
    """``{name: default}`` as the model declares them; a required field is missing here."""
    return {name: info.get_default(call_default_factory=True)
            for name, info in model.model_fields.items() if not info.is_required()}


def problems(model: type[AnalyzerParams], given: Mapping[str, object]) -> list[tuple[str, str]]:
    """``(parameter, what is wrong)`` for each value of ``given`` the model refuses (a missing
    required parameter or an unknown name is the caller's to say: it knows the item)."""
    try:
        model.model_validate(dict(given))
    except ValidationError as exc:
        return explained(model, exc)
    return []


def explained(model: type[AnalyzerParams], exc: ValidationError) -> list[tuple[str, str]]:
    """:func:`problems` of an error the caller's own validation raised (it validated once)."""
    return [_problem(model, error) for error in exc.errors()
            if error["type"] not in ("missing", "extra_forbidden")]


def _problem(model: type[AnalyzerParams], error: ErrorDetails) -> tuple[str, str]:
    where = [str(part) for part in error["loc"]]
    name = where[0] if where else ""
    info = model.model_fields.get(name)
    allowed = ""
    if info is not None:
        shape = ", ".join(w for w in (type_words(info), bounds(info)) if w)
        allowed = f"; allowed: {shape}" if shape else ""
    inner = "".join(f"[{part}]" for part in where[1:])
    inner = f" at {name}{inner}" if inner else ""
    return name, f"{error['msg']}{inner} (got {error.get('input')!r}){allowed}"
