"""The sim node as a real cell's drivers (`--arm-interface actions`): FollowJointTrajectory and
GripperCommand goals from a client that knows nothing of foldbot but the joint names, the way
ur_robot_driver and a gripper driver answer them."""

from types import SimpleNamespace

import pytest
from ros_helpers import probe_drivers, requires_ros

from foldbot.errors import FoldbotError

pytestmark = requires_ros


def test_tolerances_follow_control_msgs_conventions():
    from foldbot.ros.drivers import tolerances

    def tol(name, position):
        return SimpleNamespace(name=name, position=position)

    got = tolerances([tol("b", 0.1), tol("a", -1.0), tol("c", 0.0)], ["a", "b", "c"])
    assert got.tolist() == [float("inf"), 0.1, float("inf")]  # −1 erased, 0 unset: no limit
    with pytest.raises(FoldbotError, match="names joint 'x'"):
        tolerances([tol("x", 0.1)], ["a", "b"])


def test_gripper_goals_close_to_nothing_open_wide_and_carry_the_effort_asked_for():
    from foldbot.ros.drivers import OPEN_GAP_M, _gripper_goal

    close, opened = _gripper_goal(True), _gripper_goal(False)
    assert (close.command.position, close.command.max_effort) == (0.0, 0.0)  # 0: no limit
    assert (opened.command.position, opened.command.max_effort) == (OPEN_GAP_M, 0.0)
    assert _gripper_goal(True, 40.0).command.max_effort == 40.0


def test_a_slip_is_the_fingers_closing_on_not_cloth_pushing_them_open():
    import numpy as np

    from foldbot.ros.drivers import closing_travel

    held = np.array([0.010, -0.010])  # two fingers closed on cloth from ±0.04
    closing = np.array([-1.0, 1.0])  # the first closes toward −, the second toward +
    # Closing on by 3 mm (the cloth slipped out): 3 mm of travel.
    assert closing_travel(held + [-0.003, 0.003], held, closing) == pytest.approx(0.003)
    assert closing_travel(held + [-0.003, 0.0], held, closing) == pytest.approx(0.003)
    # Pushed open by 3 mm (cloth bunching between the pads): none.
    assert closing_travel(held + [0.003, -0.003], held, closing) == 0.0
    # One pushed open, the other closing on 1 mm: the closing one counts.
    assert closing_travel(held + [0.003, 0.001], held, closing) == pytest.approx(0.001)
    # A direction not known (a finger that did not move as it closed, or none recorded): either
    # way counts, as it did before directions were known.
    assert closing_travel(held + [0.003, 0.0], held, np.array([0.0, 1.0])) == pytest.approx(0.003)
    assert closing_travel(held + [0.003, -0.002], held, None) == pytest.approx(0.003)


@pytest.mark.slow
def test_the_sim_node_answers_as_a_real_arms_drivers(tmp_path):
    out = probe_drivers(tmp_path, "driver_probe.py")
    ok = out["succeeded"]
    # A joint the arm does not have: refused with INVALID_JOINTS, nothing moves.
    state, code, text, _ = out["bad_joints"]
    assert state != ok and code == -2 and "must be this arm's joints" in text
    # Joints in another order, the first point a second away: followed, with feedback, to the
    # point asked for.
    state, code, _, feedback = out["move"]
    assert (state, code) == (ok, 0) and feedback > 10
    assert out["moved_to"] < 0.01
    # A path tolerance no real arm holds: aborted with PATH_TOLERANCE_VIOLATED, naming the joint.
    state, code, text, _ = out["tight_path"]
    assert state != ok and code == -4 and "path tolerance" in text
    # The cell runs on by itself (its clock advances), never faster than the real-time factor
    # asked for (2); slower on a loaded machine.
    assert 0 < out["rate"] < 2.3
    # The jaws closed on nothing above the table: no stall, the goal reached; open likewise.
    assert out["close"][:3] == [ok, False, True]
    assert out["open"][:3] == [ok, False, True]
    # The jaws come to the gap asked for: shut, 60 mm, and their largest (80 mm) for 85 mm.
    assert out["close"][4] == pytest.approx(0.002, abs=1e-3)
    assert out["part"][:3] == [ok, False, True] and out["part"][4] == pytest.approx(0.06, abs=2e-3)
    assert out["open"][4] == pytest.approx(0.08, abs=2e-3)
    # max_effort: no limit (0) pushes with the fingers' own 40 N; a smaller one with it, a
    # larger one with the fingers' 40 N; NaN is refused by name.
    assert out["close"][5] == out["open"][5] == 40.0
    assert out["soft_close"][:3] == [ok, False, True] and out["soft_close"][5] == 15.0
    assert out["soft_close"][4] == pytest.approx(0.002, abs=1e-3)  # shut all the same
    assert out["hard_open"][5] == 40.0
    assert (
        out["bad_effort"][0] != ok
        and "command.max_effort must be a force" in (out["bad_effort"][3])
    )
    assert out["bad"][0] != ok and "must be a gap" in out["bad"][3]
    # A close sent while the arm moves (as the task node sends it, --gripper-lead) starts as
    # the motion ends, not before and not a round trip later (/joint_states every 0.02 s).
    sent, arrived, jaws, state = out["ahead"]
    assert state == ok and sent < arrived - 0.1
    assert arrived - 0.03 <= jaws <= arrived + 0.05, (arrived, jaws)
    # A cancel stops the arm short of its goal, where it stays; the goal ends preempted.
    state, text, short_of_goal, drift = out["cancel"]
    assert state == out["preempted"] and "stopped where it was" in text
    assert short_of_goal > 0.1 and drift < 1e-3, out["cancel"]
