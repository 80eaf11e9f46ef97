"""turtlesim's world, as every package states it (bounds of goals and placements, wall contact,
the figures' axes, the analyzers' default bounds)."""

from __future__ import annotations

#: width = height of turtlesim's world in metres: the simulator computes (500 - 1) / 45 in float32
#: (``grader.sim.physics.W``); this is that value to the micrometre, as people read it and as
#: bounds compare with it (tests/sim keeps the two within 1e-6 m).
WORLD_SIZE_M = 11.088889
