"""The sim node's command parsing (which arms a trajectory moves, which gripper a command names)
and its pacing at a real-time factor."""

import pytest
from ros_helpers import requires_ros

from foldbot.errors import FoldbotError

pytestmark = requires_ros

JOINTS = ("shoulder_pan_joint", "elbow_joint")


def test_a_trajectory_moves_the_arms_its_joint_names_name():
    from foldbot.ros import arm_joint_names
    from foldbot.ros.sim_node import trajectory_arms

    one = arm_joint_names(JOINTS, 1)
    assert trajectory_arms(list(JOINTS), one) == [0]
    two = arm_joint_names(JOINTS, 2)
    assert trajectory_arms(["left_shoulder_pan_joint", "left_elbow_joint"], two) == [0]
    assert trajectory_arms(["right_shoulder_pan_joint", "right_elbow_joint"], two) == [1]
    assert trajectory_arms([*two[0], *two[1]], two) == [0, 1]
    for bad in ([*two[1], *two[0]], two[0][:1], list(JOINTS), [*two[0], "extra"]):
        with pytest.raises(FoldbotError, match="must be an arm's joints"):
            trajectory_arms(bad, two)


def test_a_gripper_command_names_its_arm():
    from foldbot.ros.sim_node import gripper_command

    assert gripper_command("close", 1) == ("close", 0)
    assert gripper_command("open 1", 2) == ("open", 1)
    for bad, arms in (("close 1", 1), ("grab", 2), ("open -1", 2), ("open 0 1", 2), ("", 1)):
        with pytest.raises(FoldbotError, match=r"allowed: open, close.*0–"):
            gripper_command(bad, arms)


def test_a_paced_clock_that_falls_behind_goes_on_from_there_rather_than_racing():
    # SimNode._pace on a cell at twice real time: a step on time sleeps to the wall clock; one
    # that came 1 s late (a stall) moves the pace origin there, so the next steps are paced
    # from it instead of running unpaced until the clock has caught up.
    import time
    from types import SimpleNamespace

    from foldbot.ros.sim_node import PACE_SLACK_S, SimNode

    now = time.monotonic()
    cell = SimpleNamespace(real_time_factor=2.0, _pace_origin=(10.0, now))
    t0 = time.monotonic()
    SimNode._pace(cell, 10.1)  # 0.05 s of wall time ahead of the wall clock: sleeps it out
    assert time.monotonic() - t0 >= 0.04
    assert cell._pace_origin == (10.0, now)
    cell._pace_origin = (10.0, time.monotonic() - 1.0)  # the clock is 1 s of wall time behind
    before = time.monotonic()
    SimNode._pace(cell, 10.2)
    after = time.monotonic()
    sim0, wall0 = cell._pace_origin
    assert sim0 == 10.2 and before <= wall0 <= after  # moved to the step's own wall time
    t0 = time.monotonic()
    SimNode._pace(cell, 10.3)  # paced from there: 0.05 s of wall time
    assert 0.04 <= time.monotonic() - t0 < 0.5
    assert PACE_SLACK_S < 0.1  # a step's jitter is still made up
