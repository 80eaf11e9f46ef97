"""The committed fixture bags, through the pytest plugin's ``bag_frames`` fixture."""

from __future__ import annotations

import numpy as np
import pytest

from baghelpers import assert_jazzy_v9_metadata


def test_circle_pose(bag_frames, fixture_bag) -> None:
    assert_jazzy_v9_metadata(fixture_bag("circle_pose"))
    frames = bag_frames("circle_pose")
    pose, cmd = frames["/turtle1/pose"], frames["/turtle1/cmd_vel"]
    span = pose.index[-1] - pose.index[0]
    assert 5.0 <= span <= 12.0
    assert (len(pose) - 1) / span == pytest.approx(62.5, abs=1.0)
    assert pose["pub_t"].notna().all() and (pose.index.values >= pose["pub_t"].values).all()
    assert set(cmd["linear.x"]) == {2.0} and set(cmd["angular.z"]) == {1.0}
    moving = pose[pose["linear_velocity"] > 0]
    assert len(moving) > 250
    # a circle of radius v/w = 2 m: the turtle's distance from its circle centre is constant
    cx, cy = moving["x"].mean(), moving["y"].mean()
    if moving.index[-1] - moving.index[0] > 2 * np.pi:  # a full turn: the mean is the centre
        r = np.hypot(moving["x"] - cx, moving["y"] - cy)
        assert r.median() == pytest.approx(2.0, abs=0.4)
    assert frames["/rosout"]["name"].eq("turtlesim").all()


def test_random_numbers(bag_frames) -> None:
    rn = bag_frames("random_numbers")["/random_numbers"]
    assert len(rn) == 1000 and (rn["data.len"] == 2).all()
    pairs = rn[["data[0]", "data[1]"]].to_numpy()
    assert ((pairs >= 0) & (pairs < 1)).all()
    assert pairs.mean() == pytest.approx(0.5, abs=0.05)
    assert (len(rn) - 1) / (rn.index[-1] - rn.index[0]) == pytest.approx(200, rel=0.05)


def test_frames_are_copies(bag_frames) -> None:
    a = bag_frames("random_numbers")["/random_numbers"]
    a["data[0]"] = -1.0
    assert (bag_frames("random_numbers")["/random_numbers"]["data[0]"] >= 0).all()


def test_unknown_fixture_names_the_known_ones(bag_frames) -> None:
    with pytest.raises(FileNotFoundError, match="circle_pose.*random_numbers"):
        bag_frames("nope")
