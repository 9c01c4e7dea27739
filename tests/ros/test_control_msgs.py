"""control_msgs' FollowJointTrajectory and GripperCommand, generated where Debian's ROS lacks the
package: the same MD5 sums as control_msgs 1.5 (ROS Noetic), so a real driver takes them."""

import io

import pytest
from ros_helpers import requires_ros

pytestmark = requires_ros

NOETIC_MD5 = {
    "FollowJointTrajectoryGoal": "69636787b6ecbde4d61d711979bc7ecb",
    "FollowJointTrajectoryActionGoal": "cff5c1d533bf2f82dd0138d57f4304bb",
    "FollowJointTrajectoryResult": "493383b18409bfb604b4e26c676401d2",
    "FollowJointTrajectoryActionResult": "c4fb3b000dc9da4fd99699380efcc5d9",
    "FollowJointTrajectoryFeedback": "10817c60c2486ef6b33e97dcd87f4474",
    "FollowJointTrajectoryActionFeedback": "d8920dc4eae9fc107e00999cce4be641",
    "FollowJointTrajectoryAction": "bc4f9b743838566551c0390c65f1a248",
    "JointTolerance": "f544fe9c16cf04547e135dd6063ff5be",
    "GripperCommandGoal": "86fd82f4ddc48a4cb6856cfa69217e43",
    "GripperCommandResult": "e4cbff56d3562bcf113da5a5adeef91f",
    "GripperCommandAction": "950b2a6ebe831f5d4f4ceaba3d8be01e",
}
"""As published by control_msgs 1.5's generated code (C++, Lisp, rosserial alike)."""


@pytest.mark.parametrize("name", sorted(NOETIC_MD5))
def test_generated_classes_have_the_real_packages_md5(name):
    from foldbot.ros import control_msgs

    cls = getattr(control_msgs.generate(), name)
    assert cls._type == f"control_msgs/{name}"
    assert cls._md5sum == NOETIC_MD5[name]


def test_a_goal_travels_intact():
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    from foldbot.ros.control_msgs import msg

    goal = msg.FollowJointTrajectoryGoal(
        trajectory=JointTrajectory(
            joint_names=["a", "b"],
            points=[JointTrajectoryPoint(positions=[0.1, -0.2], velocities=[0.0, 0.5])],
        ),
        path_tolerance=[msg.JointTolerance(name="a", position=0.05)],
    )
    buf = io.BytesIO()
    goal.serialize(buf)
    back = msg.FollowJointTrajectoryGoal().deserialize(buf.getvalue())
    assert list(back.trajectory.joint_names) == ["a", "b"]
    assert list(back.trajectory.points[0].velocities) == [0.0, 0.5]
    assert back.path_tolerance[0].name == "a" and back.path_tolerance[0].position == 0.05
    R = msg.FollowJointTrajectoryResult
    assert (R.SUCCESSFUL, R.INVALID_JOINTS, R.PATH_TOLERANCE_VIOLATED) == (0, -2, -4)


def test_each_action_expands_to_seven_messages():
    from foldbot.ros.control_msgs import definitions

    names = [n for n in definitions() if n.startswith("control_msgs/FollowJointTrajectory")]
    assert len(names) == 7
    assert definitions()["control_msgs/GripperCommandActionGoal"].splitlines() == [
        "Header header",
        "actionlib_msgs/GoalID goal_id",
        "control_msgs/GripperCommandGoal goal",
    ]
