"""The arm and gripper as a real cell's ROS 1 drivers present them, both sides of it.

`SimDrivers` makes the sim node serve what ur_robot_driver and a gripper driver serve: a
control_msgs/FollowJointTrajectory action (joint names in any order, path and goal tolerances,
feedback with the commanded, measured and error joints, the result's error codes) and a
control_msgs/GripperCommand action (position = the jaws' gap in m; the result says whether the
jaws stalled on something). `ActionArm` is the task node's side: it sends those goals and reads
the cell back the way it would on a real arm, from /joint_states and the camera stream, so the
same task node drives a real UR5 by remapping these names onto its drivers'.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from types import SimpleNamespace

import actionlib
import numpy as np
import rospy
from actionlib_msgs.msg import GoalStatus
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectoryPoint

from foldbot.control.trajectory import thin_samples
from foldbot.errors import FoldbotError
from foldbot.ros import TOPICS, convert
from foldbot.ros.control_msgs import msg as control_msgs

DRIVER_PERIOD_S = 0.02
"""Least spacing of a trajectory goal's points (about 45 Hz at the 1/360 s step): the planner's
samples, thinned; the driver splines between them (points carry positions and velocities)."""
GONE_GRACE_S = 0.5
"""How long a driver found gone is given for the cell's report of why to arrive."""
SERVER_WAIT_S = 60.0
"""Longest wall time the task node waits for the drivers' action servers."""
CLOSE_BELOW = 0.5
"""A GripperCommand position under this fraction of the jaws' largest gap closes them."""
OPEN_GAP_M = 0.085
"""The gap the task node commands to open the jaws (a Robotiq 2F-85's full stroke); a driver
clamps it to its own gripper's largest, as the sim node does."""
_STATUS_NAMES = {v: k for k, v in vars(GoalStatus).items() if k.isupper() and isinstance(v, int)}


def tolerances(given, joint_names: list[str]) -> np.ndarray:
    """Per-joint position tolerances (rad) from control_msgs/JointTolerance entries, in
    `joint_names` order: 0 (unset, no default here) and −1 (erased) mean none (inf)."""
    tol = np.full(len(joint_names), np.inf)
    for entry in given:
        if entry.name not in joint_names:
            raise FoldbotError(
                f"a tolerance names joint {entry.name!r}; the trajectory's joints: {joint_names}"
            )
        if entry.position > 0:
            tol[joint_names.index(entry.name)] = entry.position
    return tol


class _PathToleranceViolated(Exception):
    pass


class _Handover:
    """A goal taken by an action server's thread, executed on the sim node's main thread (every
    PyBullet call happens there)."""

    def __init__(self, goal) -> None:
        self.goal = goal
        self.done = threading.Event()
        self.succeeded = False
        self.result = None
        self.text = ""


class SimDrivers:
    """The sim node's arm and gripper drivers (one arm)."""

    def __init__(self, node) -> None:
        self.node = node
        self.trajectory = actionlib.SimpleActionServer(
            TOPICS["trajectory_action"],
            control_msgs.FollowJointTrajectoryAction,
            execute_cb=lambda goal: self._hand_over("follow", goal, self.trajectory),
            auto_start=False,
        )
        self.gripper = actionlib.SimpleActionServer(
            TOPICS["gripper_action"],
            control_msgs.GripperCommandAction,
            execute_cb=lambda goal: self._hand_over("grip", goal, self.gripper),
            auto_start=False,
        )

    def start(self) -> None:
        self.trajectory.start()
        self.gripper.start()

    def _hand_over(self, kind: str, goal, server: actionlib.SimpleActionServer) -> None:
        handover = _Handover(goal)
        self.node.commands.put((kind, handover))
        while not handover.done.wait(0.1):
            if rospy.is_shutdown():
                return
        if handover.succeeded:
            server.set_succeeded(handover.result, handover.text)
        else:
            server.set_aborted(handover.result, handover.text)

    def execute(self, kind: str, handover: _Handover) -> bool:
        """Run a handed-over goal; False when the cell diverged (reported; the node stops)."""
        try:
            if kind == "follow":
                self._follow(handover)
            elif kind == "grip":
                self._grip(handover)
            else:
                raise FoldbotError(f"unknown driver goal {kind!r}")
        except FoldbotError as exc:
            # A divergence mid-goal: the goal aborts with it, and the node reports it and stops.
            result = control_msgs.FollowJointTrajectoryResult
            handover.result = (
                result(error_code=result.INVALID_GOAL, error_string=str(exc))
                if kind == "follow"
                else control_msgs.GripperCommandResult()
            )
            handover.text = f"{type(exc).__name__}: {exc}"
            handover.done.set()
            self.node.fail(kind, exc)
            return type(exc).__name__ != "SimulationDivergedError"
        handover.done.set()
        return True

    # ------------------------------------------------------------------ FollowJointTrajectory
    def _follow(self, handover: _Handover) -> None:
        R = control_msgs.FollowJointTrajectoryResult
        goal, node = handover.goal, self.node
        robot = node.executors[0].robot
        names, arm_names = list(goal.trajectory.joint_names), node.arm_joints[0]

        def refuse(code: int, text: str) -> None:
            handover.result, handover.text = R(error_code=code, error_string=text), text

        if sorted(names) != sorted(arm_names):
            return refuse(
                R.INVALID_JOINTS, f"joint_names {names} must be this arm's joints {arm_names}"
            )
        try:
            times, pos, vel = convert.trajectory_arrays(goal.trajectory)
            path_tol = tolerances(goal.path_tolerance, arm_names)
            goal_tol = tolerances(goal.goal_tolerance, arm_names)
        except FoldbotError as exc:
            return refuse(R.INVALID_GOAL, str(exc))
        order = [names.index(n) for n in arm_names]
        pos, vel = pos[:, order], vel[:, order]
        if not (np.isfinite(pos).all() and np.isfinite(vel).all() and np.isfinite(times).all()):
            return refuse(R.INVALID_GOAL, "trajectory points must be finite")
        start = goal.trajectory.header.stamp.to_sec()
        while start > node.world.sim_time:  # a start in the future: the cell runs on until then
            node.world.step()
        if times[0] > 0.0:  # the first point later than now: go there from where the arm is
            times = np.concatenate([[0.0], times])
            pos = np.vstack([robot.joint_positions(), pos])
            vel = np.vstack([np.zeros(len(arm_names)), vel])
        feedback = control_msgs.FollowJointTrajectoryFeedback(joint_names=arm_names)

        def on_check(_k: int, t: float, q_cmd: np.ndarray, q: np.ndarray) -> None:
            feedback.header = convert.header(node.world.sim_time, "")
            feedback.desired = JointTrajectoryPoint(
                positions=q_cmd.tolist(), time_from_start=rospy.Duration.from_sec(t)
            )
            feedback.actual = JointTrajectoryPoint(positions=q.tolist())
            feedback.error = JointTrajectoryPoint(positions=(q_cmd - q).tolist())
            self.trajectory.publish_feedback(feedback)
            off = np.abs(q_cmd - q) - path_tol
            if (off > 0).any():
                j = int(np.argmax(off))
                raise _PathToleranceViolated(
                    f"{arm_names[j]} was {abs(q_cmd[j] - q[j]):.4f} rad off its command at "
                    f"t = {t:.3f} s (path tolerance {path_tol[j]:g} rad)"
                )

        # ros_control's controller splines points that carry velocities (cubic), else lerps.
        splined = all(len(pt.velocities) == len(names) for pt in goal.trajectory.points)
        splined = splined and bool(np.all(np.diff(times) > 0))
        try:
            node.execute_trajectory(
                SimpleNamespace(joint_names=arm_names), on_check, (times, pos, vel), splined
            )
        except _PathToleranceViolated as exc:
            robot.command_joint_positions(robot.joint_positions())  # stop where it is
            return refuse(R.PATH_TOLERANCE_VIOLATED, str(exc))
        deadline = node.world.sim_time + goal.goal_time_tolerance.to_sec()
        while True:
            off = np.abs(robot.joint_positions() - pos[-1]) - goal_tol
            if (off <= 0).all():
                break
            if node.world.sim_time >= deadline:
                j = int(np.argmax(off))
                return refuse(
                    R.GOAL_TOLERANCE_VIOLATED,
                    f"{arm_names[j]} ended {off[j] + goal_tol[j]:.4f} rad from its goal "
                    f"(goal tolerance {goal_tol[j]:g} rad)",
                )
            node.world.step()
        handover.succeeded = True
        handover.result = R(error_code=R.SUCCESSFUL, error_string="")

    # ------------------------------------------------------------------ GripperCommand
    def _grip(self, handover: _Handover) -> None:
        node = self.node
        robot, grasp = node.executors[0].robot, node.executors[0].grasp
        position = handover.goal.command.position
        result = control_msgs.GripperCommandResult
        if not (np.isfinite(position) and position >= 0.0):
            handover.result = result(position=robot.gripper_opening())
            handover.text = f"command.position must be a gap ≥ 0 m, got {position!r}"
            return
        if position < CLOSE_BELOW * robot.max_opening:
            g = grasp.close()
            node.pub["grasp"].publish(
                convert.string_msg(
                    {
                        "success": g.success,
                        "vertex_ids": list(g.vertex_ids),
                        "reason": g.reason,
                        "arm": 0,
                    }
                )
            )
            # Jaws that stop on the cloth have stalled on it, as a real gripper reports a held
            # object; closed on nothing, they reach the commanded gap.
            handover.result = result(
                position=robot.gripper_opening(), stalled=g.success, reached_goal=not g.success
            )
            handover.text = g.reason
        else:
            grasp.open()
            handover.result = result(position=robot.gripper_opening(), reached_goal=True)
        handover.succeeded = True


def _gripper_goal(close: bool):
    """A GripperCommand goal: a zero gap closes, OPEN_GAP_M opens."""
    goal = control_msgs.GripperCommandGoal()
    goal.command.position = 0.0 if close else OPEN_GAP_M
    return goal


class ActionArm:
    """The task node's arm and gripper through their drivers' actions (one arm)."""

    def __init__(self, arm_joints: list[str], failure: Callable[[], None]) -> None:
        """`failure()` raises when the cell has reported an error (the sim node's divergence),
        so no wait outlasts a cell that has stopped."""
        self.arm_joints = arm_joints
        self.failure = failure
        self.joints: np.ndarray | None = None
        self.joints_stamp = -1.0
        self._lock = threading.Lock()
        self.trajectory = actionlib.SimpleActionClient(
            TOPICS["trajectory_action"], control_msgs.FollowJointTrajectoryAction
        )
        self.gripper = actionlib.SimpleActionClient(
            TOPICS["gripper_action"], control_msgs.GripperCommandAction
        )
        self._served = False
        """Whether both servers have been found (from then on, one that goes away is an error)."""
        rospy.Subscriber(TOPICS["joint_states"], JointState, self._on_joints, queue_size=10)

    def _on_joints(self, msg: JointState) -> None:
        names = list(msg.name)
        if all(n in names for n in self.arm_joints):
            q = np.array([msg.position[names.index(n)] for n in self.arm_joints])
            with self._lock:
                self.joints, self.joints_stamp = q, msg.header.stamp.to_sec()

    def joint_positions(self) -> np.ndarray:
        """The arm's newest measured joints (/joint_states)."""
        with self._lock:
            if self.joints is None:
                raise FoldbotError(f"no {TOPICS['joint_states']} naming {self.arm_joints}")
            return self.joints.copy()

    def check_servers(self) -> None:
        """Raise when a driver found before has gone away (its node died: no goal would ever
        be answered, nor /joint_states stamped again)."""
        if not self._served:
            return
        for client, name in (
            (self.trajectory, TOPICS["trajectory_action"]),
            (self.gripper, TOPICS["gripper_action"]),
        ):
            if client.action_client.pub_goal.get_num_connections() == 0:
                time.sleep(GONE_GRACE_S)  # the cell's own report of why, should one be on its way
                self.failure()
                raise FoldbotError(f"the driver went away: nothing serves {name} any more")

    def joints_after(self, t: float, timeout_s: float) -> np.ndarray:
        """The arm's joints from the first /joint_states stamped at or after `t` (s)."""
        deadline = time.monotonic() + timeout_s
        while self.joints_stamp < t:
            self.failure()
            self.check_servers()
            if time.monotonic() > deadline or rospy.is_shutdown():
                raise FoldbotError(
                    f"no {TOPICS['joint_states']} stamped after t = {t:.3f} s within "
                    f"{timeout_s:.0f} s"
                )
            time.sleep(0.002)
        return self.joint_positions()

    def wait_for_servers(self, timeout_s: float = SERVER_WAIT_S) -> None:
        """Wait for both action servers and the first joint state, naming what did not come."""
        deadline = time.monotonic() + timeout_s
        for client, name in (
            (self.trajectory, TOPICS["trajectory_action"]),
            (self.gripper, TOPICS["gripper_action"]),
        ):
            while not client.wait_for_server(rospy.Duration(0.2)):
                self.failure()
                if time.monotonic() > deadline or rospy.is_shutdown():
                    raise FoldbotError(f"no action server on {name} within {timeout_s:g} s")
        while self.joints is None:
            self.failure()
            if time.monotonic() > deadline or rospy.is_shutdown():
                raise FoldbotError(f"no {TOPICS['joint_states']} within {timeout_s:g} s")
            time.sleep(0.02)
        self._served = True

    def _wait(
        self, client: actionlib.SimpleActionClient, what: str, timeout_s: float,
        meanwhile: Callable[[], None] | None = None,
    ) -> None:  # fmt: skip
        deadline = time.monotonic() + timeout_s
        # Done once the result has come (the goal's status may say SUCCEEDED before it), timed
        # on the wall clock: a cell that stops also stops its clock.
        while client.simple_state != actionlib.SimpleGoalState.DONE:
            self.failure()
            self.check_servers()
            if meanwhile is not None:
                meanwhile()
            if time.monotonic() > deadline or rospy.is_shutdown():
                client.cancel_goal()
                raise FoldbotError(f"{what}: no result within {timeout_s:.0f} s")
            time.sleep(0.005)
        self.failure()

    def follow(
        self, joint_names: list[str], times: np.ndarray, positions: np.ndarray,
        velocities: np.ndarray, what: str, timeout_s: float,
        then_grip: bool | None = None, lead_s: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[bool, str] | None]:  # fmt: skip
        """Follow a trajectory (starting now); returns the feedback's times from the start, its
        commanded and measured joints, and with `then_grip` (True: close, False: open) the
        gripper's outcome as `grip` gives it. That gripper goal is sent `lead_s` before the
        trajectory's end by its feedback (or at its result), so the jaws act as the arm arrives
        rather than a round trip later. A goal the driver aborts or rejects raises, with its
        error code and text (a gripper goal already sent is cancelled)."""
        keep = thin_samples(times, DRIVER_PERIOD_S, velocities)  # the driver splines them
        goal = control_msgs.FollowJointTrajectoryGoal(
            trajectory=convert.trajectory_msg(
                joint_names, times[keep], positions[keep], velocities[keep], 0.0, ""
            )
        )
        stamps: list[float] = []
        desired: list[list[float]] = []
        actual: list[list[float]] = []

        def on_feedback(fb) -> None:
            stamps.append(fb.desired.time_from_start.to_sec())
            desired.append(list(fb.desired.positions))
            actual.append(list(fb.actual.positions))

        gripping = [then_grip is None]  # whether the gripper goal has gone

        def grip_when_due() -> None:
            due = float(times[-1]) - lead_s
            if not gripping[0] and (
                (stamps and stamps[-1] >= due)
                or self.trajectory.simple_state == actionlib.SimpleGoalState.DONE
            ):
                self.gripper.send_goal(_gripper_goal(bool(then_grip)))
                gripping[0] = True

        self.trajectory.send_goal(goal, feedback_cb=on_feedback)
        try:
            self._wait(self.trajectory, what, timeout_s, grip_when_due)
            self._trajectory_succeeded(what)
        except FoldbotError:
            if then_grip is not None and gripping[0]:  # no jaws acting on a failed motion
                self.gripper.cancel_goal()
            raise
        gripped = None
        if then_grip is not None:
            grip_when_due()  # sent already, unless no feedback came near the end
            gripped = self._grip_result(f"{what}: gripper", timeout_s)
        return np.array(stamps), np.array(desired), np.array(actual), gripped

    def _trajectory_succeeded(self, what: str) -> None:
        """Raise, with the driver's error code and text, unless the last goal succeeded."""
        result = self.trajectory.get_result()
        state = self.trajectory.get_state()
        if state != GoalStatus.SUCCEEDED or result is None or result.error_code != 0:
            code = None if result is None else result.error_code
            text = (result.error_string if result is not None else "") or (
                self.trajectory.get_goal_status_text()
            )
            raise FoldbotError(
                f"{what}: the trajectory driver ended the goal "
                f"({_STATUS_NAMES.get(state, state)}, error_code {code}): {text}"
            )

    def grip(self, close: bool, what: str, timeout_s: float) -> tuple[bool, str]:
        """Close (to a zero gap) or open (OPEN_GAP_M) the gripper; returns (whether the jaws
        stalled on something, the driver's text)."""
        self.gripper.send_goal(_gripper_goal(close))
        return self._grip_result(what, timeout_s)

    def _grip_result(self, what: str, timeout_s: float) -> tuple[bool, str]:
        self._wait(self.gripper, what, timeout_s)
        result = self.gripper.get_result()
        if self.gripper.get_state() != GoalStatus.SUCCEEDED or result is None:
            raise FoldbotError(
                f"{what}: the gripper driver ended the goal: {self.gripper.get_goal_status_text()}"
            )
        return bool(result.stalled), self.gripper.get_goal_status_text()
