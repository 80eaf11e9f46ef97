"""A recorded bag, for ``grader bag info|repair|verify``: what it holds (:func:`bag_info`, and the
``ros2 bag info``-like text of it, :func:`format_info`), a bag whose recorder was killed made
readable again (:func:`repair_bag`, :class:`RepairReport`), and whether rosbags, ``mcap`` +
mcap-ros2-support and the grader's reader read it alike (:func:`verify`, :class:`Conformance`).

This module loads the bag readers, numpy and mcap (147 ms CPU in a fresh interpreter): the
commands import it inside the function that needs it. Reading a bag as the analyzers see it is
:func:`grader.api.read_frames`.
"""

from __future__ import annotations

from grader.bag.conformance import Conformance, verify
from grader.bag.info import bag_info, format_info
from grader.bag.repair import RepairReport, repair_bag

__all__ = ["Conformance", "RepairReport", "bag_info", "format_info", "repair_bag", "verify"]
