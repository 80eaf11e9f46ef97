"""grader: record-and-replay grading for ROS 2 Jazzy turtlesim labs.

Layers, in the order data flows through them once:
``build`` (workspace) -> ``run`` (scenario: sim + recorder + student nodes + driver) -> ``bag``
-> ``analyze`` (pure functions on DataFrames) -> ``score`` (rubric) -> ``report``.

This module must stay importable with the standard library only: ``grader.bootstrap`` runs
before any dependency exists.
"""

__version__ = "0.1.0"

