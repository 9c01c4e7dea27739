"""Drives a sim node through its drivers' actions as a client of a real UR5's would, and prints
what came back as JSON (run by test_drivers.py in its own process: rospy allows one node per
process)."""

import json
import time

import numpy as np
import rospy
from actionlib_msgs.msg import GoalStatus
from probe_cell import CellListener
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from foldbot.ros import TOPICS
from foldbot.ros.control_msgs import msg
from foldbot.ros.goal_client import GoalClient
from foldbot.sim.robots import robot_class

rospy.init_node("driver_probe")
cell = CellListener()
joints, history = cell.joints, cell.history
arm = GoalClient(TOPICS["trajectory_action"], msg.FollowJointTrajectoryAction)
gripper = GoalClient(TOPICS["gripper_action"], msg.GripperCommandAction)
deadline = time.monotonic() + 240
while not (
    arm.wait_for_server(rospy.Duration(0.2)) and gripper.wait_for_server(rospy.Duration(0.2))
):
    assert time.monotonic() < deadline, "no action servers"
while not joints:
    assert time.monotonic() < deadline, "no /joint_states"
    time.sleep(0.05)
names = list(robot_class("ur5").ARM_JOINT_NAMES)
out: dict = {}


def follow(joint_names, points, **goal_fields):
    feedback = []
    goal = msg.FollowJointTrajectoryGoal(
        trajectory=JointTrajectory(joint_names=joint_names, points=points), **goal_fields
    )
    arm.send_goal(goal, feedback_cb=feedback.append)
    arm.wait_done("the trajectory goal", 120)
    result = arm.get_result()
    return arm.get_state(), result.error_code, result.error_string, len(feedback)


def point(q, t):
    return JointTrajectoryPoint(positions=list(q), time_from_start=rospy.Duration.from_sec(t))


q0 = np.array([joints[n] for n in names])
out["bad_joints"] = follow(["elbow_joint"], [point([0.0], 1.0)])
# Joints in another order than the driver's, the first point a second from now.
target = q0 + np.array([0.15, 0.0, 0.0, 0.0, 0.0, 0.0])
order = names[::-1]
out["move"] = follow(order, [point([target[names.index(n)] for n in order], 1.0)])
time.sleep(0.2)
out["moved_to"] = float(np.abs(np.array([joints[n] for n in names]) - target).max())
tight = [msg.JointTolerance(name=n, position=1e-7) for n in names]
out["tight_path"] = follow(names, [point(q0, 1.0)], path_tolerance=tight)
w0, c0 = time.monotonic(), cell.clock
time.sleep(2.0)
out["rate"] = (cell.clock - c0) / (time.monotonic() - w0)
fingers = list(robot_class("ur5").FINGER_JOINT_NAMES)


def jaws_at_rest() -> float:
    """Wait for the fingers to stop (a gripper goal ends after its settling time, the fingers a
    few millimetres short of their gap and still moving); their gap (m): 2 mm closed."""
    deadline = time.monotonic() + 60
    while True:
        f_then = [joints[n] for n in fingers]
        time.sleep(0.2)
        if np.abs(np.array([joints[n] for n in fingers]) - f_then).max() < 1e-5:
            return 0.002 + sum(joints[n] for n in fingers)
        assert time.monotonic() < deadline, "the jaws never came to rest"


for name, position, effort in (
    ("close", 0.0, 0.0), ("part", 0.06, 0.0), ("open", 0.085, 0.0), ("bad", -1.0, 0.0),
    ("soft_close", 0.0, 15.0), ("hard_open", 0.085, 500.0), ("bad_effort", 0.0, float("nan")),
):  # fmt: skip
    goal = msg.GripperCommandGoal()
    goal.command.position = position
    goal.command.max_effort = effort
    gripper.send_goal(goal)
    gripper.wait_done(f"the gripper goal {name!r}", 60)
    r = gripper.get_result()
    out[name] = [gripper.get_state(), r.stalled, r.reached_goal, gripper.get_goal_status_text()]
    if not name.startswith("bad"):
        out[name].append(jaws_at_rest())
        out[name].append(r.effort)
# A gripper goal sent while the arm moves waits for the motion's end (one goal at a time).
q1 = np.array([joints[n] for n in names])
away = q1 + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.2])
arm.send_goal(msg.FollowJointTrajectoryGoal(trajectory=JointTrajectory(
    joint_names=names, points=[point(q1, 0.0), point(away, 1.0)])))  # fmt: skip
# The close leaves once the arm is seen moving (a fixed wait raced the goal's arrival on a
# loaded machine: the close then came first and ran at once, as it should).
deadline = time.monotonic() + 60
while abs(joints[names[-1]] - q1[-1]) < 1e-3:
    assert time.monotonic() < deadline, "the arm never moved"
    time.sleep(0.005)
sent = cell.clock
close = msg.GripperCommandGoal()
close.command.position = 0.0
gripper.send_goal(close)
arm.wait_done("the trajectory goal ahead of the gripper's", 60)
gripper.wait_done("the gripper goal sent while the arm moved", 60)
time.sleep(0.3)
after = [(t, h) for t, h in history if t >= sent]
f0 = np.array([after[0][1][n] for n in fingers])
arrived = next(
    t for t, h in after if np.abs([h[n] - a for n, a in zip(names, away, strict=True)]).max() < 1e-3
)
jaws = next(t for t, h in after if np.abs(np.array([h[n] for n in fingers]) - f0).max() > 1e-3)
out["ahead"] = [sent, arrived, jaws, gripper.get_state()]
# A goal cancelled mid-motion stops the arm where it is and ends preempted, as a driver does.
q2 = np.array([joints[n] for n in names])
far = q2 + np.array([0.0, 0.0, 0.0, 0.0, 0.0, -0.6])
arm.send_goal(msg.FollowJointTrajectoryGoal(trajectory=JointTrajectory(
    joint_names=names, points=[point(q2, 0.0), point(far, 3.0)])))  # fmt: skip
deadline = time.monotonic() + 60
while abs(joints[names[-1]] - q2[-1]) < 0.05:
    assert time.monotonic() < deadline, "the arm never moved"
    time.sleep(0.005)
arm.cancel_goal()
arm.wait_done("the cancelled trajectory goal", 60)
time.sleep(0.5)
stopped = joints[names[-1]]
time.sleep(0.5)
out["cancel"] = [arm.get_state(), arm.get_goal_status_text(), abs(stopped - far[-1]),
                 abs(joints[names[-1]] - stopped)]  # fmt: skip
out["succeeded"] = GoalStatus.SUCCEEDED
out["preempted"] = GoalStatus.PREEMPTED
print("PROBE " + json.dumps(out), flush=True)
