"""Each package's outcome as colcon itself recorded it, read from colcon's ``events.log``.

colcon's ``event_log`` handler (colcon-output, part of every colcon install) writes one line per
event to ``<log-base>/latest_build/events.log``: ``JobQueued`` with the package's recursive
workspace dependencies, ``JobStarted``, ``JobEnded`` with the build's return code, and
``JobSkipped`` for a package whose dependency failed. That is colcon's own per-package result,
so the build status never has to be guessed from which install folders exist (colcon creates
``install/<pkg>/share/colcon-core/packages/<pkg>`` for failed CMake packages too). colcon offers
no reader for this file and writing an event handler of our own would need an installed entry
point, so the few line shapes we need are matched here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

_EVENT = re.compile(r"^\[[0-9.]+\] \((?P<job>[^)]*)\) "
                    r"(?P<kind>JobQueued|JobStarted|JobEnded|JobSkipped): (?P<data>.*)$")
_RC = re.compile(r"'rc': (?P<rc>.*)\}\s*$")
_QUOTED = re.compile(r"'([^'/]+)'")


@dataclass
class JobOutcome:
    """What colcon did with one package."""

    queued: bool = False
    started: bool = False
    rc: str | None = None              # repr of colcon's return code once the job ended ("0" = ok)
    skipped: bool = False              # colcon skipped it because a dependency failed
    dependencies: list[str] = field(default_factory=list)   # recursive, workspace packages only

    @property
    def succeeded(self) -> bool:
        return self.rc == "0"


def read_events(events_log: Path, packages: Iterable[str]) -> dict[str, JobOutcome]:
    """Outcome of each of ``packages`` (absent from the log: never queued, all fields empty)."""
    names = set(packages)
    out = {n: JobOutcome() for n in names}
    if not events_log.is_file():
        return out
    with open(events_log, errors="replace") as fh:
        for line in fh:
            m = _EVENT.match(line)
            if not m or m["job"] not in names:
                continue
            job, kind, data = out[m["job"]], m["kind"], m["data"]
            if kind == "JobQueued":
                job.queued = True
                deps = data.partition("'dependencies':")[2]
                job.dependencies = sorted({d for d in _QUOTED.findall(deps) if d in names})
            elif kind == "JobStarted":
                job.started = True
            elif kind == "JobEnded":
                rc = _RC.search(data)
                job.rc = rc["rc"].strip() if rc else "?"
            else:
                job.skipped = True
    return out
