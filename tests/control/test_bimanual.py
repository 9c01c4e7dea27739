"""Two arms keep clear of each other (foldbot.control.bimanual), on two real UR5s in one
PyBullet world."""

import numpy as np
import pytest

from foldbot import errors
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


def _reach_across_and_own_side(world, left, right):
    """The left arm's plans to reach across, under the right arm's parked gripper, and to a
    point on its own side (both 5 cm above the table)."""
    z = world.layout.table_height + 0.05
    target = right.robot.tcp_pose()[0].copy()
    target[2] = z
    a0 = left.robot.tcp_pose()[0]
    reach = left.plan([Segment("reach", line_path(a0, target), 0.25)])
    own = left.plan([Segment("own", line_path(a0, np.array([0.45, 0.2, z])), 0.25)])
    return reach, own


def test_arms_that_would_meet_are_refused_before_moving(two_arms):
    from foldbot.control.bimanual import check_arms_clear
    from foldbot.errors import ArmsWouldCollideError

    world, (left, right) = two_arms
    reach, own = _reach_across_and_own_side(world, left, right)
    q_right = right.robot.joint_positions()
    with pytest.raises(ArmsWouldCollideError, match="segment 'reach'") as e:
        check_arms_clear([(left, reach), (right, _still(right, q_right, reach))])
    assert e.value.segment == "reach"
    # Reaching on its own side keeps clear.
    check_arms_clear([(left, own), (right, _still(right, q_right, own))])
    assert world.steps == 0, "checking moves nothing"


def test_arms_are_checked_at_the_instants_they_pass_through(two_arms):
    """A slow arm passing, mid-way, where a fast arm has already arrived and waits is refused: the
    fast arm holds its end while the slow one passes (the instant the executor will run), which
    pairing the two paths by their fraction done would miss (the fast arm then still far away)."""
    from foldbot.control.bimanual import check_arms_clear, step_timelines
    from foldbot.errors import ArmsWouldCollideError

    world, (left, right) = two_arms
    meet = np.array([0.45, 0.0, world.layout.table_height + 0.15])
    a0, b0 = left.robot.tcp_pose()[0], right.robot.tcp_pose()[0]
    there_and_back = np.vstack([line_path(a0, meet), line_path(meet, a0)[1:]])
    slow = left.plan([Segment("pass", there_and_back, 0.05)])
    fast = right.plan([Segment("pass", line_path(b0, meet), 1.0)])
    (slow_line,), (fast_line,) = step_timelines(left, slow), step_timelines(right, fast)
    assert len(slow_line) > 4 * len(fast_line), "one physics step per sample; the slow arm is slow"
    np.testing.assert_allclose(fast_line[-1], fast[0].joint_path[-1], atol=1e-6)
    # At the same fraction of their paths the arms are far apart: the slow arm reaches the meeting
    # point half-way, when the fast one is half-way too.
    half = right.model.fk_tcp(fast[0].joint_path[len(fast[0].joint_path) // 2])[0]
    assert np.linalg.norm(half - meet) > 0.1
    with pytest.raises(ArmsWouldCollideError, match=r"segment .pass.*overlap by"):
        check_arms_clear([(left, slow), (right, fast)])
    assert world.steps == 0, "checking moves nothing"


def test_an_arm_standing_still_is_one_configuration(two_arms):
    from foldbot.control.bimanual import step_timelines

    _world, (left, _right) = two_arms
    q = left.robot.joint_positions()
    target = left.robot.tcp_pose()[0] + [0.0, 0.0, -0.1]
    move = left.plan([Segment("down", line_path(left.robot.tcp_pose()[0], target), 0.2)])
    (still,) = step_timelines(left, _still(left, q, move))
    np.testing.assert_allclose(still, q[None, :])


def test_one_arm_must_clear_the_other_where_it_stands(two_arms):
    from foldbot.control.bimanual import check_clear_of_still_arms
    from foldbot.errors import UnreachableTargetError

    world, (left, right) = two_arms
    reach, own = _reach_across_and_own_side(world, left, right)
    still = [(right, right.robot.joint_positions())]
    # Named as an unreachable action of that arm, so a cell gives it to another arm.
    with pytest.raises(UnreachableTargetError, match=r"arm 0: segment 'reach'") as e:
        check_clear_of_still_arms(0, (left, reach), still)
    assert errors.failed_segment(e.value) == "reach", "named through the error it was raised from"
    check_clear_of_still_arms(0, (left, own), still)


def test_a_dwell_is_checked_as_time_standing_at_the_segment_end(two_arms):
    from foldbot.control.bimanual import step_timelines

    world, (left, _right) = two_arms
    a0 = left.robot.tcp_pose()[0]
    seg = Segment("hang", line_path(a0, a0 + [0.0, 0.0, 0.05]), 0.25)
    (moving,) = left.plan([seg])
    (dwelling,) = left.plan([Segment("hang", seg.points, 0.25, dwell=0.5)])
    (plain,), (held,) = step_timelines(left, [moving]), step_timelines(left, [dwelling])
    extra = round(0.5 / world.time_step)
    assert len(held) == len(plain) + extra
    assert np.array_equal(held[: len(plain)], plain)
    assert np.array_equal(held[len(plain) :], np.repeat(plain[-1:], extra, axis=0))


def _spread_pair(world, tilt: float):
    """Both arms' parts of a spread of two corners 10 cm apart, near the workspace's far side
    (the +y corner to the +y arm), each tool tilted `tilt` away from the other arm."""
    from foldbot.planning.spread import SpreadAction

    z = world.layout.table_height
    grasps = [np.array([0.572, 0.0685, z + 0.01]), np.array([0.548, -0.0285, z + 0.01])]
    return [
        SpreadAction(
            grasp=g,
            hold=np.array([0.6, side * 0.15, z + 0.35]),
            touch=np.array([0.6, side * 0.15, z + 0.305]),
            release=np.array([0.3, side * 0.15, z + 0.02]),
            tilt=side * tilt,
        )
        for side, g in zip((1.0, -1.0), grasps, strict=True)
    ]


def test_tools_tilted_apart_let_two_arms_take_corners_close_together(two_arms):
    """Gripper down, the wrists over two corners 10 cm apart meet on the way in; with each tool
    tilted 20° away from the other arm they keep clear, the TCP on the same points."""
    import pybullet as p

    from foldbot.control.bimanual import check_arms_clear
    from foldbot.errors import ArmsWouldCollideError
    from foldbot.planning.motion import MotionConfig
    from foldbot.planning.spread import spread_segments

    world, executors = two_arms

    def plan(tilt):
        out = []
        for ex, action in zip(executors, _spread_pair(world, tilt), strict=True):
            segments = spread_segments(action, ex.robot.tcp_pose()[0], MotionConfig())
            out.append((ex, ex.plan(segments)))
        return out

    with pytest.raises(ArmsWouldCollideError, match="segment 'approach'"):
        check_arms_clear(plan(0.0))
    tilted = plan(0.35)
    check_arms_clear(tilted)
    for (ex, steps), action in zip(tilted, _spread_pair(world, 0.35), strict=True):
        at_grasp = {s.segment.name: s for s in steps}["descend"].joint_path[-1]
        pos, quat = ex.model.fk_tcp(at_grasp)
        np.testing.assert_allclose(
            pos, action.grasp + [0, 0, MotionConfig().grasp_depth], atol=1e-3
        )
        tool_z = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)[:, 2]
        lean = -np.sign(action.tilt) * tool_z[1]  # the wrist leans away from the other arm
        assert lean == pytest.approx(np.sin(0.35), abs=0.01)
        held = {s.segment.name: s for s in steps}["spread"].joint_path[-1]
        tool_z = np.array(p.getMatrixFromQuaternion(ex.model.fk_tcp(held)[1])).reshape(3, 3)[:, 2]
        np.testing.assert_allclose(tool_z, [0, 0, -1], atol=0.01)  # gripper down at the hold
    assert world.steps == 0, "planning moves nothing"


def test_tools_leaning_apart_take_two_corners_lying_along_x(two_arms):
    """Two corners 11 cm apart along x: both forearms reach for the same y from either side and
    meet gripper down and tilted along ±y; leaning each wrist away from the other corner along
    the line between them (planning.spread's lean "apart") keeps them clear."""
    import math

    import pybullet as p

    from foldbot.control.bimanual import check_arms_clear
    from foldbot.errors import ArmsWouldCollideError
    from foldbot.planning.motion import MotionConfig
    from foldbot.planning.spread import SpreadAction, spread_segments

    world, executors = two_arms
    z = world.layout.table_height
    grasps = [np.array([0.505, 0.001, z + 0.01]), np.array([0.615, -0.001, z + 0.01])]

    def plan(tilt: float, apart: bool):
        out = []
        for k, (ex, side) in enumerate(zip(executors, (1.0, -1.0), strict=True)):
            away = grasps[k][:2] - grasps[1 - k][:2]
            lean = (
                {"tilt": tilt, "tilt_heading": math.atan2(away[1], away[0])}
                if apart
                else {"tilt": side * tilt}
            )
            action = SpreadAction(
                grasp=grasps[k],
                hold=np.array([0.6, side * 0.15, z + 0.35]),
                touch=np.array([0.6, side * 0.15, z + 0.305]),
                release=np.array([0.3, side * 0.15, z + 0.02]),
                **lean,
            )
            segments = spread_segments(action, ex.robot.tcp_pose()[0], MotionConfig())
            out.append((ex, ex.plan(segments), action))
        return out

    for tilt, apart in ((0.0, False), (0.35, False)):
        with pytest.raises(ArmsWouldCollideError, match="segment 'approach'"):
            check_arms_clear([(ex, steps) for ex, steps, _ in plan(tilt, apart)])
    leaning = plan(0.35, True)
    check_arms_clear([(ex, steps) for ex, steps, _ in leaning])
    for ex, steps, action in leaning:
        at_grasp = {s.segment.name: s for s in steps}["descend"].joint_path[-1]
        pos, quat = ex.model.fk_tcp(at_grasp)
        np.testing.assert_allclose(
            pos, action.grasp + [0, 0, MotionConfig().grasp_depth], atol=1e-3
        )
        tool_z = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)[:, 2]
        # The wrist leans along x, away from the other corner: the tool points back towards it.
        other = next(a for _, _, a in leaning if a is not action)
        assert -tool_z[0] * np.sign(action.grasp[0] - other.grasp[0]) == pytest.approx(
            math.sin(0.35), abs=0.01
        )
    assert world.steps == 0, "planning moves nothing"
