"""The recorder as a thread of the scenario process: the same bag as the recorder process,
nothing lost at a light rate (batched wakes) or in a burst (drained at once)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from baghelpers import finish, loadgen, wait_for
from grader.bag.conformance import check_bag
from grader.bag.frames import load_frames
from grader.bag.recorder_thread import RecorderThread

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_in_process_recorder_keeps_every_message_with_dds_receive_times(graph, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    rec = RecorderThread(bag, ["/slow", "/burst"], domain_id=graph.domain_id)
    rec.start(30)
    # 40 Hz: well under the 20 wakes a second of a light load, so messages wait for a batch
    slow = loadgen(graph, "slow", "turtlesim/msg/Pose", ["/slow"], rate=40, count=80)
    # 5000 messages at 5 kHz: more per 50 ms than a light batch, drained without waiting
    burst = loadgen(graph, "burst", "turtlesim/msg/Pose", ["/burst"], rate=5000, count=5000)
    for gen in (slow, burst):
        assert wait_for(lambda g=gen: "READY" in g.output(), 30)
    finish(slow)
    finish(burst)
    assert rec.stop() == 80 + 5000

    frames = load_frames(bag)
    for topic, n in (("/slow", 80), ("/burst", 5000)):
        assert frames[topic]["x"].tolist() == [float(i) for i in range(n)], topic
    slow_f = frames["/slow"]
    latency = slow_f.index.to_numpy() - slow_f["pub_t"].to_numpy()
    # receive times are the DDS layer's, not when the batch was drained (up to 50 ms later)
    assert np.median(latency) < 0.01, f"median receive latency {np.median(latency) * 1e3:.1f} ms"
    intervals = np.diff(slow_f.index.to_numpy())
    assert np.median(intervals) == pytest.approx(1 / 40, abs=0.004)
    assert check_bag(bag) == []
