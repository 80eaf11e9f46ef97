"""The one error class of ``grader.scores``: every problem found in a CSV, listed at once."""

from __future__ import annotations

from typing import Sequence

from grader.errors import GraderError


class ScoresError(GraderError):
    """A TA's score sheet or a roster that cannot be used as it is.

    ``problems`` holds one line per problem (``line 4, q1: 9 is over the maximum of 8 points``),
    all of them, so a TA fixes the file once instead of once per run. The message starts with
    the file and a count and says that nothing was changed.
    """

    def __init__(self, source: str, problems: Sequence[str], *, changed_nothing: bool = True) -> None:
        self.source = source
        self.problems = list(problems)
        count = f"{len(self.problems)} problem" + ("s" if len(self.problems) != 1 else "")
        tail = "; nothing was changed" if changed_nothing else ""
        super().__init__(f"{source}: {count}{tail}:\n  " + "\n  ".join(self.problems))
