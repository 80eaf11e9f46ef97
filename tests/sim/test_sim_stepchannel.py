"""Lockstep's step channel: the driver ticks a real simulator over a socket only it holds.

The simulator is started as a scenario starts it (``--lockstep --step-fd``, the descriptor passed
to it alone); its ``~/step_clock`` and ``~/step_world`` services still answer (the driver's probes
before the first tick go over them) but no longer tick, so no other node can move the clock. A
process started without the descriptor, or as student code, does not have it.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from grader.runner import ProcessSpec, RosGraph
from grader.sim import sim_argv
from grader.sim.clock import STEP_CLOCK_SERVICE, STEP_WORLD_SERVICE, TICK_NS
from grader.sim.stepchannel import STEP_CLOCK, STEP_WORLD, StepChannelError, StepClient, make_pair


def _times(answer: str) -> int:
    return int(answer.split()[0])


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_the_driver_ticks_over_its_channel_and_the_services_only_answer(ros_graph: RosGraph) -> None:
    from std_srvs.srv import SetBool, Trigger

    from grader.testing.ros import rclpy_node, spin_until

    ours, theirs = make_pair()
    assert not ours.get_inheritable() and not theirs.get_inheritable()
    sim = ros_graph.start(ProcessSpec("sim", sim_argv(lockstep=True, step_fd=theirs.fileno()),
                                      pass_fds=(theirs.fileno(),)))
    theirs.close()
    steps = StepClient(ours)
    assert [_times(steps.call(STEP_CLOCK, 30.0)) for _ in range(3)] == [TICK_NS, 2 * TICK_NS, 3 * TICK_NS]
    assert steps.call(STEP_WORLD, 5.0) == str(3 * TICK_NS)
    assert steps.call(STEP_WORLD, 5.0) == str(3 * TICK_NS)          # once per time
    with rclpy_node(ros_graph.domain_id) as (node, executor):
        clock = node.create_client(SetBool, f"/turtlesim/{STEP_CLOCK_SERVICE}")
        world = node.create_client(Trigger, f"/turtlesim/{STEP_WORLD_SERVICE}")
        for client, request in ((clock, SetBool.Request(data=True)), (world, Trigger.Request())):
            assert client.wait_for_service(timeout_sec=20)
            future = client.call_async(request)
            assert spin_until(executor, future.done, 10)
            assert _times(future.result().message) == 3 * TICK_NS        # answered, not ticked
    assert _times(steps.call(STEP_CLOCK, 5.0)) == 4 * TICK_NS
    with pytest.raises(StepChannelError, match="failed a step"):
        steps.call(b"?", 5.0)
    sim.stop()
    with pytest.raises(StepChannelError):
        steps.call(STEP_CLOCK, 5.0)
    steps.close()


def test_only_a_trusted_process_given_the_descriptor_has_it(tmp_path: Path) -> None:
    ours, theirs = make_pair()
    probe = ["-c", "import os, sys; os.fstat(int(sys.argv[1]))", str(theirs.fileno())]
    with RosGraph(tmp_path / "graph") as graph:
        given = graph.start(ProcessSpec("given", [sys.executable, *probe], pass_fds=(theirs.fileno(),)))
        other = graph.start(ProcessSpec("other", [sys.executable, *probe]))
        student = graph.start(ProcessSpec("student", [sys.executable, *probe], pass_fds=(theirs.fileno(),),
                                          untrusted=True))
        assert [p.wait(30) for p in (given, other, student)] == [0, 1, 1]
    ours.close()
    theirs.close()
