"""How fast scenarios run unless the user says otherwise.

Every scenario a rubric does not pin to real time (``real_time: true``) runs on simulated time,
``DEFAULT_TIME_SCALE`` times faster than real time, when the static scan of the nodes it runs
finds no wall-clock pacing and the run-time watchdog sees every expected rate kept
(:mod:`grader.grading.timescale`); the others run at 1x, and the result says why. Lockstep
scenarios tick as fast as their processes handle each tick, at any setting.

4x is the speed the Lab 3 fixtures were graded at side by side with 1x, per item identical
(``benchmarks/bench_timescale.py --fixtures``); at 8x a 30 Hz ROS timer fires every 4 ms of
wall time and the simulator ticks every 2 ms, which the busiest fixtures' nodes do not keep up
with on a loaded 2-core machine (the watchdog then sends the scenario back to 1x: slower in all).
``--time-scale 1`` grades in real time, as before this default; a grader given fewer than
``MIN_CPUS_FOR_DEFAULT`` CPUs (a small container) runs at 1x unless told otherwise.
"""

#: scenarios run this many times faster than real time by default (``--time-scale``) ...
DEFAULT_TIME_SCALE = 4.0
#: ... where the grader is given at least this many CPUs (cores, affinity and cgroup quota), and
#: at 1x below: at K x every process wakes K times as often per wall second. In Gradescope's
#: default container (0.5 CPU, 768 MB) every 4x recording of the Lab 3 reference starved (the
#: simulator waited 0.72-0.94 s per second for a CPU) and went again at 1x, which only cost time
MIN_CPUS_FOR_DEFAULT = 2.0
#: the fastest ``--time-scale`` taken (``grader sim`` and the grading commands): beyond this a
#: 16 ms tick lasts under 1 ms of wall time: no Python node keeps up
MAX_TIME_SCALE = 16.0


def default_time_scale(cpus: float) -> float:
    """The speed scenarios run at when the user does not say, for a grader given ``cpus``."""
    return DEFAULT_TIME_SCALE if cpus >= MIN_CPUS_FOR_DEFAULT - 1e-9 else 1.0
