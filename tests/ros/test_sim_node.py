"""The sim node's command parsing: which arms a trajectory moves, which gripper a command names."""

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
