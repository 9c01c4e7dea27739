"""Two arms on one clock (foldbot.control.bimanual), on two real UR5s in one PyBullet world."""

import numpy as np
import pytest

from foldbot.control.bimanual import move_joints_together, run_together
from foldbot.control.executor import ArmExecutor
from foldbot.planning.motion import Segment, line_path
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimWorld


@pytest.fixture
def two_arms():
    with SimWorld() as world:
        arms = [make_robot("ur5", world.client, lay) for lay in world.layout.arm_layouts(2)]
        yield world, [ArmExecutor(world, arm, grasp=None) for arm in arms]


def test_both_arms_move_at_once_and_the_shorter_move_waits(two_arms):
    world, (left, right) = two_arms
    z = world.layout.table_height + 0.1
    a0, b0 = left.robot.tcp_pose()[0], right.robot.tcp_pose()[0]
    a1 = np.array([0.50, 0.15, z])  # a long move
    b1 = b0 + [0.0, 0.0, -0.05]  # a short one
    steps = [
        (left, left.plan([Segment("long", line_path(a0, a1), 0.25)])[0]),
        (right, right.plan([Segment("short", line_path(b0, b1), 0.25)])[0]),
    ]
    long_samples = len(left.start(steps[0][1]).traj.times)
    logs = run_together(steps)
    # One clock: the world stepped as long as the longer move, not the sum of both.
    assert world.steps == long_samples - 1
    assert np.linalg.norm(left.robot.tcp_pose()[0] - a1) < 0.01
    assert np.linalg.norm(right.robot.tcp_pose()[0] - b1) < 0.01
    assert [log.name for log in logs] == ["long", "short"]
    assert all(log.max_tracking_error < 0.02 for log in logs)
    assert logs[0].duration > logs[1].duration


def test_both_arms_park_together(two_arms):
    world, arms = two_arms
    targets = [(ex, ex.robot.out_of_view_q) for ex in arms]
    logs = move_joints_together(targets, "park")
    for ex in arms:
        assert np.abs(ex.robot.joint_positions() - ex.robot.out_of_view_q).max() < 0.02
    assert world.steps == round(max(log.duration for log in logs) / world.time_step)
    # Already there: nothing moves.
    before = world.steps
    move_joints_together(targets, "park")
    assert world.steps == before


def test_arms_in_different_worlds_are_refused(two_arms):
    _world, (left, _right) = two_arms
    with SimWorld() as other:
        stranger = ArmExecutor(other, make_robot("ur5", other.client, other.layout), grasp=None)
        a0 = left.robot.tcp_pose()[0]
        s0 = stranger.robot.tcp_pose()[0]
        steps = [
            (left, left.plan([Segment("a", line_path(a0, a0 + [0, 0, 0.02]), 0.25)])[0]),
            (stranger, stranger.plan([Segment("b", line_path(s0, s0 + [0, 0, 0.02]), 0.25)])[0]),
        ]
        with pytest.raises(ValueError, match="share one world"):
            run_together(steps)


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
