"""Console lines as the student's nodes print them: the ROS console prefix split off, and the
lines of a Python traceback told apart from output. Plain text in, plain values out (no frames):
``grader.analyze._common`` reads the recorded lines with them."""

from __future__ import annotations

import re
from typing import Iterable

import numpy as np

_ROS_PREFIX = re.compile(
    r"^\s*\[(DEBUG|INFO|WARN|WARNING|ERROR|FATAL)\]\s*\[(\d+(?:\.\d+)?)\]\s*\[([^\]]*)\]:\s?(.*)$"
)


def split_ros_console(line: str) -> tuple[str | None, float | None, str]:
    """'[INFO] [1718.25] [simple_subscriber]: 0.5' -> ('simple_subscriber', 1718.25, '0.5')."""
    m = _ROS_PREFIX.match(line)
    if not m:
        return None, None, line
    try:
        ts = float(m.group(2))
    except ValueError:
        ts = None
    return m.group(3), ts, m.group(4)


def traceback_mask(texts: Iterable[str]) -> np.ndarray:
    """True for the lines of a Python traceback ("Traceback (most recent call last):", its
    indented frames and the exception line that ends it). What a crashing node prints is not its
    output: the line numbers of its frames would count as printed values (measured: the lab's
    template, stopped at --time-scale 4 while taking a /clock message, printed a traceback whose
    "argument '0'" matched one Box-Muller z of the 237 in its window)."""
    out, inside = [], False
    for line in texts:
        text = str(line)
        if text.startswith("Traceback (most recent call last):"):
            inside = True
            out.append(True)
        elif inside:
            out.append(True)
            inside = not text or text[0].isspace()      # the exception line ends it
        else:
            out.append(False)
    return np.array(out, dtype=bool)
