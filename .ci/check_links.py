#!/usr/bin/env python3
"""Fail when a tracked symbolic link points outside the repository.

A committed link such as ``fixtures/.../rootdir -> /`` makes every build from a clone walk the
whole machine (setuptools lists the source tree following links: ``pip wheel .`` ran for over
13 minutes in ``/proc`` instead of ~11 s); a link to ``/etc/passwd`` ships a file of the building
machine. Hostile-link fixtures are made at test time instead (fixtures/faults/make_archives.py).

Reads the links from git's index (``git ls-files -s``, mode 120000) and their targets from the
objects, so it needs no checkout of them. Usage: ``.ci/check_links.py [REPO]``; exit 1 and one
line per link that leaves the repository (absolute, or ``..`` past its root).
"""

from __future__ import annotations

import posixpath
import subprocess
import sys
from pathlib import Path


def escaping_links(repo: Path) -> list[str]:
    listing = subprocess.run(["git", "-C", str(repo), "ls-files", "-s", "-z"], capture_output=True,
                             check=True).stdout.decode(errors="surrogateescape")
    bad = []
    for entry in filter(None, listing.split("\0")):
        meta, path = entry.split("\t", 1)
        mode, sha = meta.split()[:2]
        if mode != "120000":
            continue
        target = subprocess.run(["git", "-C", str(repo), "cat-file", "blob", sha], capture_output=True,
                                check=True).stdout.decode(errors="surrogateescape")
        inside = posixpath.normpath(posixpath.join(posixpath.dirname(path), target))
        if target.startswith("/") or inside == ".." or inside.startswith("../"):
            bad.append(f"{path} -> {target}: a tracked link that leaves the repository; make it at "
                       "test time instead (see fixtures/faults/make_archives.py)")
    return bad


def main(argv: list[str]) -> int:
    repo = Path(argv[0]) if argv else Path(__file__).resolve().parents[1]
    bad = escaping_links(repo)
    for line in bad:
        print(line, file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
