"""Two arms keep clear of each other (foldbot.control.bimanual), on two real UR5s in one
PyBullet world."""

import numpy as np
import pytest

from foldbot.control.executor import ArmExecutor
from foldbot.planning.motion import Segment, line_path
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimWorld


@pytest.fixture
def two_arms():
    with SimWorld() as world:
        arms = [make_robot("ur5", world.client, lay) for lay in world.layout.arm_layouts(2)]
        yield world, [ArmExecutor(world, arm, grasp=None) for arm in arms]


def _still(executor, q, like):
    """A plan that holds the arm at `q` through the same segments as `like`."""
    from dataclasses import replace

    return [replace(s, joint_path=np.asarray(q)[None, :]) for s in like]


def test_arms_that_would_meet_are_refused_before_moving(two_arms):
    from foldbot.control.bimanual import check_arms_clear
    from foldbot.errors import ArmsWouldCollideError

    world, (left, right) = two_arms
    z = world.layout.table_height + 0.05
    # The left arm reaches across to right under the right arm's parked gripper.
    target = right.robot.tcp_pose()[0].copy()
    target[2] = z
    a0 = left.robot.tcp_pose()[0]
    reach = left.plan([Segment("reach", line_path(a0, target), 0.25)])
    q_right = right.robot.joint_positions()
    with pytest.raises(ArmsWouldCollideError, match="segment 'reach'"):
        check_arms_clear([(left, reach), (right, _still(right, q_right, reach))])
    # Reaching on its own side keeps clear.
    own = left.plan([Segment("own", line_path(a0, np.array([0.45, 0.2, z])), 0.25)])
    check_arms_clear([(left, own), (right, _still(right, q_right, own))])
    assert world.steps == 0, "checking moves nothing"
