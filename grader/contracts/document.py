"""The files grader writes and reads back (``result.json``, ``scenario.json``): one pydantic model
per file, and one way in and out of it.

Why a model: a file a grade rests on is read again by many floors (the class view, a regrade, a
merge of manual scores, the exports, the similarity pass, Classroom) and by graders of other
versions. Each reader used to pick keys out of a dict with ``.get`` and its own defaults; a
misspelt key read as "missing" and a file of the wrong shape failed deep inside a report. Here the
shape is declared once, a bad file is refused where it is read (``path: field: what is wrong``),
and every reader gets attributes.

Round trips are exact: a document read and written again is the same JSON (the seal of a
result.json is a MAC over its JSON, and ``grader scores merge`` compares the bytes). So:

* numbers are :data:`Number` (an ``int`` stays an ``int``: pydantic's ``float`` would write
  ``10`` back as ``10.0``);
* :meth:`Document.to_json` writes the keys the document was given, no more (``exclude_unset``):
  an optional key absent from a file stays absent;
* unknown keys (a newer grader's, or a caller's ``extra``) are kept and written back after the
  known ones, so an older reader neither crashes on nor drops them.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Annotated, Self, TypeAlias

from pydantic import (BaseModel, ConfigDict, ModelWrapValidatorHandler, PlainValidator, PrivateAttr,
                      SerializerFunctionWrapHandler, ValidationError, model_serializer, model_validator)

from grader.contracts.values import JsonValue

__all__ = ["Document", "DocumentError", "KeptOrder", "Number", "explain"]

def _number(value: JsonValue) -> int | float:
    """One check, one message (a union would report ``.int`` and ``.float`` separately)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError("should be a finite number")
    return value


#: a JSON number, kept as the kind it was read as (see the module docstring)
Number: TypeAlias = Annotated[int | float, PlainValidator(_number)]


class DocumentError(ValueError):
    """A file that is not the document it should be; the message is ``where: field: what``.

    A ``ValueError``, so readers that skipped an unreadable file (``except (OSError,
    ValueError)``) still skip one of the wrong shape."""


class Document(BaseModel):
    """Base of every file model: unknown keys kept (see the module docstring), numbers finite."""

    model_config = ConfigDict(extra="allow", populate_by_name=True, allow_inf_nan=False)

    @classmethod
    def parse(cls, data: JsonValue, where: str) -> Self:
        """The document ``data`` (parsed JSON) is, or a :class:`DocumentError` naming ``where``."""
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            raise DocumentError(explain(exc, where)) from None

    @classmethod
    def parse_text(cls, text: str, where: str) -> Self:
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise DocumentError(f"cannot read {where}: {exc}") from None
        return cls.parse(data, where)

    @classmethod
    def read(cls, path: str | os.PathLike[str]) -> Self:
        """The document in file ``path``; OSError when it cannot be read, DocumentError when it
        is not this document."""
        return cls.parse_text(Path(path).read_text(encoding="utf-8"), str(path))

    def to_json(self) -> dict[str, JsonValue]:
        """The JSON object of this document: the keys it was given, in declared order, then
        unknown ones."""
        return self.model_dump(mode="json", by_alias=True, exclude_unset=True)


def explain(exc: ValidationError, where: str, most: int = 3) -> str:
    """``where: items[2].points: Input should be a valid number (got 'x')``: the first ``most``
    problems (``; `` between them), then how many more."""
    lines = []
    for error in exc.errors()[:most]:
        field = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in error["loc"]).lstrip(".")
        got = "" if error["type"] == "missing" else f" (got {error.get('input')!r:.60})"
        lines.append(f"{field or '(top)'}: {error['msg'].removeprefix('Value error, ')}{got}")
    more = exc.error_count() - most
    return f"{where}: " + "; ".join(lines) + (f" (and {more} more)" if more > 0 else "")


class KeptOrder(BaseModel):
    """A record that remembers the order of the keys it was made from and writes them back so: a
    note the pipeline makes (``{"requested", "used", "fallback"}``) keeps its order through
    scenario.json and into result.json, whose bytes the seal covers."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False, populate_by_name=True)

    _order: list[str] = PrivateAttr(default_factory=list)

    @model_validator(mode="wrap")
    @classmethod
    def _keep_order(cls, data: JsonValue, handler: ModelWrapValidatorHandler[Self]) -> Self:
        made = handler(data)
        if isinstance(data, dict):
            made._order = [str(k) for k in data]
        return made

    @model_serializer(mode="wrap")
    def _in_order(self, handler: SerializerFunctionWrapHandler) -> dict[str, JsonValue]:
        """Every dump (this record's own, and a document's that holds it) in the given order."""
        dumped: dict[str, JsonValue] = handler(self)
        first = {k: dumped[k] for k in self._order if k in dumped}
        return first | {k: v for k, v in dumped.items() if k not in first}

    def to_json(self) -> dict[str, JsonValue]:
        """The keys it was given, in the order it was given them."""
        return self.model_dump(mode="json", by_alias=True, exclude_unset=True)
