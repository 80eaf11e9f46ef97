"""Sandboxes for student code: every student process, build and launch-file load.

Student code is hostile: it may write outside its folder, read what it must not, reach the
network, fork and detach, flood, eat memory. Each protection uses what Linux and the field
provide, and each is probed at start (``grader doctor`` lists them):

* filesystem (bubblewrap): a read-only view of the system, the Python interpreter, the ROS
  installs on the environment's ``AMENT_PREFIX_PATH``/``CMAKE_PREFIX_PATH`` (a sourced ROS
  wherever it lives) and the build's install tree; one size-capped scratch tmpfs; nothing of
  the outputs, bags, rubric, fixtures, other submissions, build cache or grader sources
  (:mod:`.jail`);
* network and processes (``unshare``): each scenario runs in its own network namespace (a
  loopback shared by its simulator, recorder, driver and students only) and PID namespace, and
  each student process in a PID namespace of its own, so nothing it starts outlives it
  (:mod:`.scenario`, :mod:`.enter`);
* limits (cgroups): memory, process count and CPU of a scenario's student processes together,
  reported by name when hit, and a kill of everything in the group at the end (:mod:`.cgroups`);
  stdout/stderr logs capped per stream (:mod:`.capture`);
* identity and environment: an unprivileged uid when the grader is root, and only the ROS
  variables plus the rubric's ``env:`` (:mod:`.jail`).

API (all the runner, scenario, build and launch code use):

* ``probe()`` / ``protections()`` / ``summary()``: what is active on this machine;
* ``ScenarioSandbox``: per scenario (parent side): ``argv()``, ``env()``, ``report()``;
* ``ProcessSpec(untrusted=True)`` in a ``RosGraph``: a student process in the scenario's jail;
* ``run_jailed(argv, ...)``: a one-shot command (colcon build, launch-file loading) in a jail.

``GRADER_SANDBOX=off`` turns it all off (today's isolation, with a warning in every result);
``GRADER_SANDBOX=require`` refuses to grade unless every protection is active.
"""

from grader.sandbox.probe import Capabilities, Protection, probe, protections
from grader.sandbox.scenario import ScenarioSandbox, SandboxPolicy, sandbox_mode, summary

__all__ = ["Capabilities", "Protection", "probe", "protections", "ScenarioSandbox", "SandboxPolicy",
           "sandbox_mode", "summary"]
