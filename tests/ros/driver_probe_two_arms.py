"""Drives a two-arm sim node through its drivers' actions, each arm's under its own namespace,
as a client of two real UR5s' drivers would, and prints what came back as JSON (run by
test_two_arm_drivers.py in its own process: rospy allows one node per process)."""

import json
import time

import numpy as np
import rospy
from actionlib_msgs.msg import GoalStatus
from probe_cell import CellListener
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from foldbot.ros import arm_joint_names, driver_actions
from foldbot.ros.control_msgs import msg
from foldbot.ros.drivers import OPEN_GAP_M
from foldbot.ros.goal_client import GoalClient
from foldbot.sim.robots import robot_class

rospy.init_node("driver_probe_two_arms")
cell = CellListener()
joints, history = cell.joints, cell.history
names = arm_joint_names(robot_class("ur5").ARM_JOINT_NAMES, 2)
fingers = arm_joint_names(robot_class("ur5").FINGER_JOINT_NAMES, 2)
arms = [GoalClient(a, msg.FollowJointTrajectoryAction) for a, _ in driver_actions(2)]
grippers = [GoalClient(g, msg.GripperCommandAction) for _, g in driver_actions(2)]
deadline = time.monotonic() + 240
for client in (*arms, *grippers):
    while not client.wait_for_server(rospy.Duration(0.2)):
        assert time.monotonic() < deadline, "no action servers"
while not all(n in joints for n in names[0] + names[1]) or cell.clock <= 0.0:
    assert time.monotonic() < deadline, "no /joint_states naming both arms, or no /clock"
    time.sleep(0.05)
out: dict = {"actions": driver_actions(2)}


def point(q, t):
    return JointTrajectoryPoint(positions=list(q), time_from_start=rospy.Duration.from_sec(t))


def goal(joint_names, points, stamp=0.0):
    trajectory = JointTrajectory(joint_names=joint_names, points=points)
    trajectory.header.stamp = rospy.Time.from_sec(stamp)
    return msg.FollowJointTrajectoryGoal(trajectory=trajectory)


# The left arm's driver sent the right arm's joints: refused, nothing moves.
arms[0].send_goal(goal(names[1], [point([joints[n] for n in names[1]], 1.0)]))
arms[0].wait_done("the left arm's goal of the right arm's joints", 60)
r = arms[0].get_result()
out["crossed"] = [arms[0].get_state(), r.error_code, r.error_string]
# Both arms, one goal each, stamped to start together 0.5 s from now: each turns its base.
q0 = [np.array([joints[n] for n in arm_names]) for arm_names in names]
start = cell.clock + 0.5
turn = np.array([0.15, 0.0, 0.0, 0.0, 0.0, 0.0])
for client, arm_names, q in zip(arms, names, q0, strict=True):
    client.send_goal(goal(arm_names, [point(q + turn, 1.0)], start))
    time.sleep(0.1)  # the second goal leaves later, and still starts with the first
for side, client in zip(("left", "right"), arms, strict=True):
    client.wait_done(f"the {side} arm's goal", 120)
time.sleep(0.3)
out["together"] = [[c.get_state(), c.get_result().error_code] for c in arms]
out["start"] = start
moved = []
for arm_names, q in zip(names, q0, strict=True):
    first = next(t for t, h in history if abs(h[arm_names[0]] - q[0]) > 1e-4 and t >= start - 1.0)
    moved.append(first)
out["first_moved"] = moved
out["turned"] = [float(joints[a[0]] - q[0]) for a, q in zip(names, q0, strict=True)]
# The left gripper closes on nothing above the table; the right one's jaws stay as they were.
f0 = {n: joints[n] for n in fingers[0] + fingers[1]}
close = msg.GripperCommandGoal()
close.command.position = 0.0
grippers[0].send_goal(close)
grippers[0].wait_done("the left gripper's close", 60)
time.sleep(0.3)
out["left_close"] = [grippers[0].get_state(), grippers[0].get_result().reached_goal]
out["fingers_moved"] = [max(abs(joints[n] - f0[n]) for n in arm_fingers) for arm_fingers in fingers]
# Two gripper goals at once, as a pair's grippers act: the right closes as the left opens.
f1 = {n: joints[n] for n in fingers[0] + fingers[1]}
opening = msg.GripperCommandGoal()
opening.command.position = OPEN_GAP_M
grippers[1].send_goal(close)
grippers[0].send_goal(opening)
for side, client in zip(("left", "right"), grippers, strict=True):
    client.wait_done(f"the {side} gripper's goal of the pair", 60)
time.sleep(0.3)
out["both"] = [client.get_state() for client in grippers]
out["both_moved"] = [max(abs(joints[n] - f1[n]) for n in arm_fingers) for arm_fingers in fingers]
out["succeeded"] = GoalStatus.SUCCEEDED
print("PROBE " + json.dumps(out), flush=True)
