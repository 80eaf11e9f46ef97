"""``python -m grader.sim [--canvas-out FILE] [--holonomic] [--background R G B]
[--ros-args ...]``: run the reference turtlesim node until SIGINT/SIGTERM."""

from __future__ import annotations

import sys

from grader.sim.cli import main

if __name__ == "__main__":
    sys.exit(main())
