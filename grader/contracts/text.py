"""Text fields of the models (rubric, scenario, contract) and their error words, shared by the
models that declare them and the loader that reports them."""

from __future__ import annotations

import difflib
from typing import Iterable

from pydantic import Field
from pydantic.fields import FieldInfo

#: pattern -> what it means in words: the loader says "expected a ROS name like /turtle1/pose",
#: not the regular expression
PATTERN_WHAT: dict[str, str] = {}


def pattern_text(pattern: str, what: str) -> FieldInfo:
    """The constraint of a text field of this language (``Annotated[str, pattern_text(...)]``),
    whose pattern the loader's error message replaces by ``what``."""
    PATTERN_WHAT[pattern] = what
    info: FieldInfo = Field(pattern=pattern, description=what)
    return info


def suggest(word: str, candidates: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for a near miss, else an empty string."""
    close = difflib.get_close_matches(str(word), [str(c) for c in candidates], n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""
