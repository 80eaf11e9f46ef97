"""The grader's caches: build areas, the support packages' builds and scenario recordings.

Where they live (``default_cache_dir``), what makes an entry's key (``code``: the grader files
that make it; ``environment``: the ROS 2, Python and build tools), how entries are held and
marked used (``locks``), and how the cache is listed, pruned and kept under its size cap
(``store``, ``grader cache``). The layout under the cache folder:

* ``<digest>/``: a build area (``build.py``), with ``<digest>.lock`` and ``<digest>.use``;
* ``packages/<key>.json``: a support package some build area holds, built (``package_cache.py``);
* ``recordings/<key>/``: a scenario's recording (``grader.grading.reuse``), with ``<key>.lock``;
* ``last_batch.json``: the hit counts of the last batch that ended.
"""

from __future__ import annotations

import os
from pathlib import Path


def default_cache_dir() -> Path:
    """``$GRADER_CACHE/builds``, else ``$XDG_CACHE_HOME/grader/builds`` or ``~/.cache/grader/builds``."""
    base = os.environ.get("GRADER_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "grader")
    return Path(base) / "builds"
