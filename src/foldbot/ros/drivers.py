"""The arm and gripper as a real cell's ROS 1 drivers present them, both sides of it.

`SimDrivers` makes the sim node serve what ur_robot_driver and a gripper driver serve: a
control_msgs/FollowJointTrajectory action (joint names in any order, path and goal tolerances,
feedback with the commanded, measured and error joints, the result's error codes) and a
control_msgs/GripperCommand action (position = the jaws' gap in m, max_effort the most each
finger pushes with, in N, ≤ 0 no limit; the result says whether the jaws stalled on something,
and the effort used). `ActionArm` is the task node's side: it sends those goals and reads
the cell back the way it would on a real arm, from /joint_states and the camera stream, so the
same task node drives a real UR5 by remapping these names onto its drivers'. A two-arm cell has
a pair of drivers per arm, each under its arm's namespace (foldbot.ros.driver_actions), and
moves both arms together by stamping both goals with one start time, as ros_control's
trajectory controller takes a goal's header stamp.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import actionlib
import numpy as np
import rospy
from actionlib_msgs.msg import GoalStatus
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectoryPoint

from foldbot.control.trajectory import commands_at_steps, thin_samples
from foldbot.errors import FoldbotError
from foldbot.ros import TOPICS, convert, driver_actions
from foldbot.ros.control_msgs import msg as control_msgs
from foldbot.ros.goal_client import GoalClient
from foldbot.ros.node_args import SLIP_FINGER_TRAVEL

DRIVER_PERIOD_S = 0.02
"""Least spacing of a trajectory goal's points (about 45 Hz at the 1/360 s step): the planner's
samples, thinned; the driver splines between them (points carry positions and velocities)."""
GONE_GRACE_S = 0.5
"""How long a driver found gone is given for the cell's report of why to arrive."""
SERVER_WAIT_S = 60.0
"""Longest wall time the task node waits for the drivers' action servers."""
LATE_START_S = 0.05
"""A goal that reaches the sim's driver this long (s) after its stamped start is logged (it
starts on arrival): two arms' goals meant to start together would not."""
CLOSE_BELOW = 0.5
"""A GripperCommand position under this fraction of the jaws' largest gap closes them (a grasp:
the sim's jaws close fully and hold what lies between them); from there up, the jaws open to
the gap asked for, at most their largest."""
OPEN_GAP_M = 0.085
"""The gap the task node commands to open the jaws (a Robotiq 2F-85's full stroke); a driver
clamps it to its own gripper's largest, as the sim node does."""


def closing_travel(fingers: np.ndarray, held: np.ndarray, closing: np.ndarray | None) -> float:
    """How far the fingers have moved on from where the jaws held (`held`), counted the way
    they close: `closing` is each finger's closing direction (+1, −1; 0 or None: not known,
    either way counts). A slip closes the fingers further; cloth bunching between them pushes
    them open, which is no slip."""
    delta = np.asarray(fingers, dtype=float) - np.asarray(held, dtype=float)
    if closing is None:
        return float(np.abs(delta).max())
    along = np.where(closing != 0, delta * closing, np.abs(delta))
    return float(max(along.max(), 0.0))


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

    def __init__(self, goal, arm: int = 0) -> None:
        self.goal = goal
        self.arm = arm
        self.done = threading.Event()
        self.succeeded = False
        self.preempted = False
        """Ended by its client's cancel (the arm stopped where it was)."""
        self.result = None
        self.text = ""


class _Motion:
    """A FollowJointTrajectory goal under way on one arm, stepped with every other arm's on the
    cell's one clock: waiting for its start stamp, then moving (its commands at each physics
    step), then settling into its goal tolerance."""

    def __init__(self, handover: _Handover, start: float, times, pos, vel, splined: bool,
                 path_tol: np.ndarray, goal_tol: np.ndarray, goal_time_s: float) -> None:  # fmt: skip
        self.handover = handover
        self.start = start
        self.times, self.pos, self.vel, self.splined = times, pos, vel, splined
        self.path_tol, self.goal_tol, self.goal_time_s = path_tol, goal_tol, goal_time_s
        self.q_cmd = self.v_cmd = np.zeros((0, pos.shape[1]))
        self.slip_hook = None  # the injected slip's step hook while this motion carries cloth
        self.k = -1  # −1: waiting for its start; then the next step's index
        self.check: set[int] = set()
        self.deadline = 0.0  # when settling must end (simulated s)


class SimDrivers:
    """The sim node's arm and gripper drivers, a pair per arm (one arm: their own names; two:
    each under its arm's namespace, foldbot.ros.driver_actions). Goals on both arms run at once
    on the cell's clock, each from its own start stamp, as two arms' drivers run them; a
    gripper goal waits until no arm moves (the simulated jaws take the cell's physics steps)."""

    def __init__(self, node) -> None:
        self.node = node
        self.trajectories: list[actionlib.SimpleActionServer] = []
        self.grippers: list[actionlib.SimpleActionServer] = []
        for arm, (follow_name, grip_name) in enumerate(driver_actions(len(node.executors))):
            follow = actionlib.SimpleActionServer(
                follow_name, control_msgs.FollowJointTrajectoryAction, auto_start=False,
                execute_cb=lambda goal, a=arm: self._hand_over("follow", a, goal),
            )  # fmt: skip
            grip = actionlib.SimpleActionServer(
                grip_name, control_msgs.GripperCommandAction, auto_start=False,
                execute_cb=lambda goal, a=arm: self._hand_over("grip", a, goal),
            )  # fmt: skip
            self.trajectories.append(follow)
            self.grippers.append(grip)
        self.motions: dict[int, _Motion] = {}
        """Each moving arm's goal under way."""
        self.grips: list[_Handover] = []
        """Gripper goals waiting for the arms to stop, in the order they came."""

    def start(self) -> None:
        for server in (*self.trajectories, *self.grippers):
            server.start()

    def _hand_over(self, kind: str, arm: int, goal) -> None:
        server = (self.trajectories if kind == "follow" else self.grippers)[arm]
        handover = _Handover(goal, arm)
        self.node.commands.put((kind, handover))
        cancelled = False
        while not handover.done.wait(0.02):
            if rospy.is_shutdown():
                return
            if not cancelled and server.is_preempt_requested():
                cancelled = True  # the client cancelled it: the cell stops it (cancel)
                self.node.commands.put(("cancel", handover))
        if handover.preempted:
            server.set_preempted(handover.result, handover.text)
        elif handover.succeeded:
            server.set_succeeded(handover.result, handover.text)
        else:
            server.set_aborted(handover.result, handover.text)

    @property
    def busy(self) -> bool:
        """Whether a goal is under way or waiting (the cell steps for it, not at rest)."""
        return bool(self.motions or self.grips)

    def accept(self, kind: str, handover: _Handover) -> bool:
        """Take a handed-over goal: a trajectory starts moving its arm (or is refused, its
        goal ended at once); a gripper goal acts now if no arm moves, else once none does.
        False when the cell diverged (reported; the node stops)."""
        if kind == "follow":
            return self._guarded(lambda: self._begin_follow(handover), handover)
        if kind == "grip":
            self.grips.append(handover)
            return self.run_grips() if not self.motions else True
        if kind == "cancel":
            self._cancel(handover)
            return self.run_grips() if not self.motions else True
        raise FoldbotError(f"unknown driver goal {kind!r}")

    def _cancel(self, handover: _Handover) -> None:
        """A goal its client cancelled, as a driver takes a cancel: a motion under way (or
        waiting for its start) stops the arm where it is, a gripper goal not yet begun is
        dropped; either ends preempted. A goal already ended stays as it ended."""
        if handover.done.is_set():
            return
        for arm, m in list(self.motions.items()):
            if m.handover is handover:
                robot = self.node.executors[arm].robot
                robot.command_joint_positions(robot.joint_positions())  # stop where it is
                self._end(arm, control_msgs.FollowJointTrajectoryResult.SUCCESSFUL,
                          "cancelled: the arm stopped where it was", preempted=True)  # fmt: skip
                return
        if handover in self.grips:
            self.grips.remove(handover)
            grasp = self.node.executors[handover.arm].grasp
            handover.result = control_msgs.GripperCommandResult(position=grasp.jaw_gap())
            handover.text, handover.preempted = "cancelled before the jaws moved", True
            handover.done.set()

    def _guarded(self, run: Callable[[], None], taken: _Handover | None = None) -> bool:
        """Run `run`; a divergence (or any cell error) on the way aborts every goal under way
        or waiting (and `taken`, the goal being taken) with it, the node reports it (and,
        diverged, stops: False)."""
        try:
            run()
        except FoldbotError as exc:
            handovers = [m.handover for m in self.motions.values()] + self.grips
            if taken is not None and taken not in handovers:
                handovers.append(taken)
            for handover in handovers:
                result = control_msgs.FollowJointTrajectoryResult
                handover.result = (
                    result(error_code=result.INVALID_GOAL, error_string=str(exc))
                    if isinstance(handover.goal, control_msgs.FollowJointTrajectoryGoal)
                    else control_msgs.GripperCommandResult()
                )
                handover.text = f"{type(exc).__name__}: {exc}"
                handover.done.set()
            for m in self.motions.values():
                if m.slip_hook is not None:
                    self.node.world.remove_step_hook(m.slip_hook)
            self.motions.clear()
            self.grips.clear()
            self.node.fail("driver goal", exc)
            return type(exc).__name__ != "SimulationDivergedError"
        return True

    def step(self) -> bool:
        """One physics step of every arm's goal under way (a motion's start, its commands, its
        checks and its end), then the waiting gripper goals once no arm moves. False when the
        cell diverged."""
        return self._guarded(self._step) and self.run_grips()

    def run_grips(self) -> bool:
        """The waiting gripper goals, in turn, when no arm moves."""
        while self.grips and not self.motions:
            handover = self.grips[0]
            if not self._guarded(lambda h=handover: self._grip(h)):
                return False
            if self.grips and self.grips[0] is handover:
                self.grips.pop(0)
                handover.done.set()
        return True

    # ------------------------------------------------------------------ FollowJointTrajectory
    def _begin_follow(self, handover: _Handover) -> None:
        R = control_msgs.FollowJointTrajectoryResult
        goal, node, arm = handover.goal, self.node, handover.arm
        names, arm_names = list(goal.trajectory.joint_names), node.arm_joints[arm]

        def refuse(code: int, text: str) -> None:
            handover.result, handover.text = R(error_code=code, error_string=text), text
            handover.done.set()

        if sorted(names) != sorted(arm_names):
            return refuse(
                R.INVALID_JOINTS, f"joint_names {names} must be this arm's joints {arm_names}"
            )
        if arm in self.motions:  # a driver runs one goal at a time (its server queues them)
            return refuse(R.INVALID_GOAL, "this arm already follows a trajectory")
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
        # ros_control's controller splines points that carry velocities (cubic), else lerps.
        splined = all(len(pt.velocities) == len(names) for pt in goal.trajectory.points)
        splined = splined and bool(np.all(np.diff(times) > 0))
        self.motions[arm] = _Motion(
            handover, goal.trajectory.header.stamp.to_sec(), times, pos, vel, splined,
            path_tol, goal_tol, goal.goal_time_tolerance.to_sec(),
        )  # fmt: skip
        self._start_due()

    def _start_due(self) -> None:
        """Start the motions whose start stamp the clock has reached (a start in the future:
        the cell runs on until then; one in the past starts now)."""
        node = self.node
        for arm, m in list(self.motions.items()):
            if m.k >= 0 or m.start > node.world.sim_time:
                continue
            late = node.world.sim_time - m.start
            if m.start > 0.0 and late > LATE_START_S:
                rospy.logwarn(
                    "arm %d's goal arrived %.3f s after the start it is stamped with; it "
                    "starts now", arm, late,
                )  # fmt: skip
            times, pos, vel = m.times, m.pos, m.vel
            if times[0] > 0.0:  # the first point later than now: go there from where the arm is
                robot = node.executors[arm].robot
                times = np.concatenate([[0.0], times])
                pos = np.vstack([robot.joint_positions(), pos])
                vel = np.vstack([np.zeros(pos.shape[1]), vel])
            m.q_cmd, m.v_cmd = commands_at_steps(times, pos, vel, node.world.time_step, m.splined)
            n = len(m.q_cmd)
            m.check = set(range(7, n, 8)) | ({n - 1} if n else set())
            m.pos = pos
            m.k = 0
            ex = node.executors[arm]
            m.slip_hook = node.slip_hook([(ex, slice(0, pos.shape[1]))], m.q_cmd)
            if n == 0:
                self._settling(arm, m)

    def _step(self) -> None:
        node = self.node
        self._start_due()
        moving = {a: m for a, m in self.motions.items() if 0 <= m.k < len(m.q_cmd)}
        for arm, m in moving.items():
            node.executors[arm].robot.command_joint_positions(m.q_cmd[m.k], m.v_cmd[m.k])
        node.world.step()
        for arm, m in list(self.motions.items()):
            if arm in moving:
                k, m.k = m.k, m.k + 1
                if k in m.check and not self._checked(arm, m, k):
                    continue
                if m.k == len(m.q_cmd):
                    self._settling(arm, m)
            elif m.k >= 0:
                self._settle_check(arm, m)

    def _checked(self, arm: int, m: _Motion, k: int) -> bool:
        """Feedback at a tracking check, and the path tolerances: a joint off its command by
        more stops the arm where it is and aborts the goal (False)."""
        node = self.node
        robot, arm_names = node.executors[arm].robot, node.arm_joints[arm]
        t, q_cmd, q = (k + 1) * node.world.time_step, m.q_cmd[k], robot.joint_positions()
        feedback = control_msgs.FollowJointTrajectoryFeedback(joint_names=arm_names)
        feedback.header = convert.header(node.world.sim_time, "")
        feedback.desired = JointTrajectoryPoint(
            positions=q_cmd.tolist(), time_from_start=rospy.Duration.from_sec(t)
        )
        feedback.actual = JointTrajectoryPoint(positions=q.tolist())
        feedback.error = JointTrajectoryPoint(positions=(q_cmd - q).tolist())
        self.trajectories[arm].publish_feedback(feedback)
        off = np.abs(q_cmd - q) - m.path_tol
        if (off > 0).any():
            j = int(np.argmax(off))
            robot.command_joint_positions(robot.joint_positions())  # stop where it is
            self._end(
                arm,
                control_msgs.FollowJointTrajectoryResult.PATH_TOLERANCE_VIOLATED,
                f"{arm_names[j]} was {abs(q_cmd[j] - q[j]):.4f} rad off its command at "
                f"t = {t:.3f} s (path tolerance {m.path_tol[j]:g} rad)",
            )
            return False
        return True

    def _settling(self, arm: int, m: _Motion) -> None:
        """The last command sent: the arm has goal_time_tolerance to come within its goal
        tolerance (checked now, then after each step)."""
        m.deadline = self.node.world.sim_time + m.goal_time_s
        self._settle_check(arm, m)

    def _settle_check(self, arm: int, m: _Motion) -> None:
        robot = self.node.executors[arm].robot
        off = np.abs(robot.joint_positions() - m.pos[-1]) - m.goal_tol
        if (off <= 0).all():
            self._end(arm, control_msgs.FollowJointTrajectoryResult.SUCCESSFUL, "")
        elif self.node.world.sim_time >= m.deadline:
            j = int(np.argmax(off))
            self._end(
                arm,
                control_msgs.FollowJointTrajectoryResult.GOAL_TOLERANCE_VIOLATED,
                f"{self.node.arm_joints[arm][j]} ended {off[j] + m.goal_tol[j]:.4f} rad from "
                f"its goal (goal tolerance {m.goal_tol[j]:g} rad)",
            )

    def _end(self, arm: int, code: int, text: str, preempted: bool = False) -> None:
        motion = self.motions.pop(arm)
        if motion.slip_hook is not None:
            self.node.world.remove_step_hook(motion.slip_hook)
        handover = motion.handover
        handover.preempted = preempted
        handover.succeeded = code == control_msgs.FollowJointTrajectoryResult.SUCCESSFUL
        handover.result = control_msgs.FollowJointTrajectoryResult(
            error_code=code, error_string=text
        )
        handover.text = text
        handover.done.set()

    # ------------------------------------------------------------------ GripperCommand
    def _grip(self, handover: _Handover) -> None:
        node = self.node
        executor = node.executors[handover.arm]
        robot, grasp = executor.robot, executor.grasp
        position = handover.goal.command.position
        effort = handover.goal.command.max_effort
        result = control_msgs.GripperCommandResult
        if not (np.isfinite(position) and position >= 0.0):
            handover.result = result(position=grasp.jaw_gap())
            handover.text = f"command.position must be a gap ≥ 0 m, got {position!r}"
            return
        if not np.isfinite(effort):
            handover.result = result(position=grasp.jaw_gap())
            handover.text = (
                f"command.max_effort must be a force in N (≤ 0: no limit), got {effort!r}"
            )
            return
        # The fingers push with max_effort where it is under the model's own force (≤ 0: no
        # limit, as control_msgs defines it), as a gripper driver limits its motor.
        force = robot.FINGER_FORCE if effort <= 0.0 else min(float(effort), robot.FINGER_FORCE)
        if position < CLOSE_BELOW * robot.max_opening:
            g = grasp.close(force=force)
            node.pub["grasp"].publish(
                convert.string_msg(
                    {
                        "success": g.success,
                        "vertex_ids": list(g.vertex_ids),
                        "reason": g.reason,
                        "arm": handover.arm,
                    }
                )
            )
            # Jaws that stop on the cloth have stalled on it, as a real gripper reports a held
            # object; closed on nothing, they reach the commanded gap.
            handover.result = result(
                position=grasp.jaw_gap(),
                effort=force,
                stalled=g.success,
                reached_goal=not g.success,
            )
            handover.text = g.reason
        else:
            # To the gap asked for, up to the jaws' largest (a driver clamps to its stroke).
            grasp.open(min(float(position), robot.max_opening), force=force)
            handover.result = result(position=grasp.jaw_gap(), effort=force, reached_goal=True)
        handover.succeeded = True


def _gripper_goal(close: bool, effort: float = 0.0):
    """A GripperCommand goal: a zero gap closes, OPEN_GAP_M opens; `effort` its max_effort (N;
    0: no limit, as control_msgs defines it)."""
    goal = control_msgs.GripperCommandGoal()
    goal.command.position = 0.0 if close else OPEN_GAP_M
    goal.command.max_effort = float(effort)
    return goal


class _Following:
    """A trajectory goal sent: its feedback as it comes (time from the start, commanded and
    measured joints)."""

    def __init__(self, duration: float) -> None:
        self.duration = duration
        self.stamps: list[float] = []
        self.desired: list[list[float]] = []
        self.actual: list[list[float]] = []

    def on_feedback(self, fb) -> None:
        self.stamps.append(fb.desired.time_from_start.to_sec())
        self.desired.append(list(fb.desired.positions))
        self.actual.append(list(fb.actual.positions))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.array(self.stamps), np.array(self.desired), np.array(self.actual)


class ActionArm:
    """The task node's side of one arm's drivers: its trajectory and gripper actions."""

    def __init__(
        self,
        arm_joints: list[str],
        failure: Callable[[], None],
        actions: tuple[str, str] = (TOPICS["trajectory_action"], TOPICS["gripper_action"]),
        finger_joints: list[str] | None = None,
        slip_travel: float = SLIP_FINGER_TRAVEL,
        gripper_effort: float = 0.0,
    ) -> None:
        """`failure()` raises when the cell has reported an error (the sim node's divergence),
        so no wait outlasts a cell that has stopped. `actions`: the arm's FollowJointTrajectory
        and GripperCommand action names (foldbot.ros.driver_actions). `finger_joints`: the
        gripper's joints on /joint_states, watched for a slip (watch_hold); none or absent
        there, no slip is seen. `slip_travel`: how far one may move on the way it closes (in its
        own units), with no gripper goal sent since the jaws stalled on cloth, before the hold
        counts as lost:
        a gripper under position control closes on once what it held has slipped out.
        `gripper_effort`: the max_effort (N) its gripper goals carry (0: no limit)."""
        self.arm_joints = arm_joints
        self.failure = failure
        self.actions = actions
        self.finger_joints = list(finger_joints or [])
        self.slip_travel = slip_travel
        self.gripper_effort = gripper_effort
        """The max_effort (N) every gripper goal carries (0: no limit)."""
        self.joints: np.ndarray | None = None
        self.joints_stamp = -1.0
        self.fingers: np.ndarray | None = None
        """The finger joints from the newest /joint_states that names them."""
        self.holding = False
        """Whether the last gripper goal closed the jaws and they stalled on something."""
        self._hold_ref: np.ndarray | None = None
        """The fingers where the jaws hold (watch_hold), while a slip is watched for."""
        self._open_ref: np.ndarray | None = None
        """The fingers when the last closing gripper goal was sent (where they closed from)."""
        self._closing_dir: np.ndarray | None = None
        """Each finger's closing direction (+1, −1, 0: it did not move), from where it closed
        from to where it held; None where not known."""
        self.lost: tuple[float, float] | None = None
        """(stamp, travel) of the /joint_states that showed the hold lost (take_lost)."""
        self._lock = threading.Lock()
        self.trajectory = GoalClient(actions[0], control_msgs.FollowJointTrajectoryAction)
        self.gripper = GoalClient(actions[1], control_msgs.GripperCommandAction)
        self._closing = False
        """Whether the last gripper goal sent closed the jaws."""
        self._served = False
        """Whether both servers have been found (from then on, one that goes away is an error)."""
        rospy.Subscriber(TOPICS["joint_states"], JointState, self._on_joints, queue_size=10)

    def _on_joints(self, msg: JointState) -> None:
        names = list(msg.name)
        fingers = None
        if self.finger_joints and all(n in names for n in self.finger_joints):
            fingers = np.array([msg.position[names.index(n)] for n in self.finger_joints])
        if all(n in names for n in self.arm_joints):
            q = np.array([msg.position[names.index(n)] for n in self.arm_joints])
            with self._lock:
                self.joints, self.joints_stamp = q, msg.header.stamp.to_sec()
                if fingers is not None:
                    self.fingers = fingers
                    self._check_hold(fingers, self.joints_stamp)

    def _check_hold(self, fingers: np.ndarray, stamp: float) -> None:
        """A slip, where one is watched for: the fingers moved on from where the jaws held."""
        if self._hold_ref is None or self.lost is not None:
            return
        travel = closing_travel(fingers, self._hold_ref, self._closing_dir)
        if travel > self.slip_travel:
            self.lost = (stamp, travel)

    def watch_hold(self, since: float, timeout_s: float) -> None:
        """Where the jaws hold cloth (the last gripper goal closed them and they stalled on it)
        and /joint_states names the fingers: take the fingers from the first /joint_states
        stamped at or after `since` (s, the cell's clock) as where they hold, and from then on
        watch for them moving on the way they closed (a slip; take_lost; pushed open by cloth
        bunching between them is none). A gripper goal sent ends the watch."""
        with self._lock:
            self._hold_ref, self.lost = None, None
        if not self.holding or not self.finger_joints:
            return
        self.joints_after(since, timeout_s)
        with self._lock:
            if self.fingers is not None:
                self._hold_ref = self.fingers.copy()
                self._closing_dir = None
                if self._open_ref is not None:
                    moved = self._hold_ref - self._open_ref
                    self._closing_dir = np.where(np.abs(moved) > 1e-6, np.sign(moved), 0.0)

    def take_lost(self) -> tuple[float, float] | None:
        """(stamp, travel) where the watched hold was seen lost, or None; ends the watch (the
        jaws hold nothing after a slip)."""
        with self._lock:
            lost, self.lost, self._hold_ref = self.lost, None, None
        if lost is not None:
            self.holding = False
        return lost

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
        for client, name in zip((self.trajectory, self.gripper), self.actions, strict=True):
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
        for client, name in zip((self.trajectory, self.gripper), self.actions, strict=True):
            while not client.wait_for_server(rospy.Duration(0.2)):
                self.failure()
                if time.monotonic() > deadline or rospy.is_shutdown():
                    raise FoldbotError(f"no action server on {name} within {timeout_s:g} s")
        while self.joints is None:
            self.failure()
            if time.monotonic() > deadline or rospy.is_shutdown():
                raise FoldbotError(
                    f"no {TOPICS['joint_states']} naming {self.arm_joints} within {timeout_s:g} s"
                )
            time.sleep(0.02)
        if self.finger_joints and self.fingers is None:
            rospy.logwarn(
                "%s names no finger joints %s: a slip is not seen (the jaws' hold is taken "
                "from the gripper's result alone)", TOPICS["joint_states"], self.finger_joints,
            )  # fmt: skip
        self._served = True

    def _wait(
        self, client: GoalClient, what: str, timeout_s: float,
        meanwhile: Callable[[], None] | None = None,
    ) -> None:  # fmt: skip
        deadline = time.monotonic() + timeout_s
        # Done once the result has come (the goal's status may say SUCCEEDED before it), timed
        # on the wall clock: a cell that stops also stops its clock.
        while not client.done:
            self.failure()
            self.check_servers()
            if meanwhile is not None:
                meanwhile()
            if time.monotonic() > deadline or rospy.is_shutdown():
                client.cancel_goal()
                raise FoldbotError(f"{what}: no result within {timeout_s:.0f} s")
            time.sleep(0.005)
        self.failure()

    def send(
        self, joint_names: list[str], times: np.ndarray, positions: np.ndarray,
        velocities: np.ndarray, start: float = 0.0,
    ) -> _Following:  # fmt: skip
        """Send a trajectory goal, starting at the cell's time `start` (s; 0: on arrival);
        returns where its feedback collects (`finish` waits for its result)."""
        keep = thin_samples(times, DRIVER_PERIOD_S, velocities)  # the driver splines them
        goal = control_msgs.FollowJointTrajectoryGoal(
            trajectory=convert.trajectory_msg(
                joint_names, times[keep], positions[keep], velocities[keep], start, ""
            )
        )
        following = _Following(float(times[-1]))
        self.trajectory.send_goal(goal, feedback_cb=following.on_feedback)
        return following

    def finish(
        self, following: _Following, what: str, timeout_s: float,
        meanwhile: Callable[[], None] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
        """Wait for a sent trajectory's result; its feedback (`_Following.arrays`). A goal the
        driver aborts or rejects raises, with its error code and text."""
        self._wait(self.trajectory, what, timeout_s, meanwhile)
        self._trajectory_succeeded(what)
        return following.arrays()

    def follow(
        self, joint_names: list[str], times: np.ndarray, positions: np.ndarray,
        velocities: np.ndarray, what: str, timeout_s: float,
        then_grip: bool | None = None, lead_s: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[bool, str] | None]:  # fmt: skip
        """Follow a trajectory (starting now); returns the feedback's times from the start, its
        commanded and measured joints, and with `then_grip` (True: close, False: open) the
        gripper's outcome as `grip` gives it. That gripper goal is sent `lead_s` before the
        trajectory's end by its feedback (or at its result), so the jaws act as the arm arrives
        rather than a round trip later. A hold seen lost on the way (watch_hold) does not stop
        the motion (stopped there, the fold recovered worse: docs/experiments.md, "A slip seen
        on the fingers"). A goal the driver aborts or rejects raises, with its error code and
        text (a gripper goal already sent is cancelled)."""
        following = self.send(joint_names, times, positions, velocities)
        gripping = [then_grip is None]  # whether the gripper goal has gone

        def grip_when_due() -> None:
            due = float(times[-1]) - lead_s
            if not gripping[0] and (
                (following.stamps and following.stamps[-1] >= due) or self.trajectory.done
            ):
                self.send_grip(bool(then_grip))
                gripping[0] = True

        try:
            stamps, desired, actual = self.finish(following, what, timeout_s, grip_when_due)
        except FoldbotError:
            if then_grip is not None and gripping[0]:  # no jaws acting on a failed motion
                self.gripper.cancel_goal()
            raise
        gripped = None
        if then_grip is not None:
            grip_when_due()  # sent already, unless no feedback came near the end
            gripped = self.grip_result(f"{what}: gripper", timeout_s)
        return stamps, desired, actual, gripped

    def _reported_cause(self) -> None:
        """A goal the driver ended: give the cell's own report of why (the sim node's
        divergence, on another topic than the goal's result) GONE_GRACE_S to arrive, and raise
        it if it does; a real cell sends none."""
        deadline = time.monotonic() + GONE_GRACE_S
        while time.monotonic() < deadline:
            self.failure()
            time.sleep(0.02)

    def _trajectory_succeeded(self, what: str) -> None:
        """Raise, with the driver's error code and text, unless the last goal succeeded."""
        result = self.trajectory.get_result()
        state = self.trajectory.get_state()
        if state != GoalStatus.SUCCEEDED or result is None or result.error_code != 0:
            self._reported_cause()
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
        self.send_grip(close)
        return self.grip_result(what, timeout_s)

    def send_grip(self, close: bool) -> None:
        """Send the gripper goal that closes or opens the jaws, not waiting for it (grip_result
        does): several arms' grippers then act at once. It ends any watch for a slip."""
        with self._lock:
            self._hold_ref = None
            self._open_ref = self.fingers.copy() if close and self.fingers is not None else None
        self.holding = False
        self._closing = close
        self.gripper.send_goal(_gripper_goal(close, self.gripper_effort))

    def grip_result(self, what: str, timeout_s: float) -> tuple[bool, str]:
        """The gripper goal's outcome (send_grip's), waited for: (whether the jaws stalled on
        something, the driver's text); FoldbotError where the driver did not succeed."""
        self._wait(self.gripper, what, timeout_s)
        result = self.gripper.get_result()
        if self.gripper.get_state() != GoalStatus.SUCCEEDED or result is None:
            self._reported_cause()
            raise FoldbotError(
                f"{what}: the gripper driver ended the goal: {self.gripper.get_goal_status_text()}"
            )
        self.holding = bool(self._closing and result.stalled)
        return bool(result.stalled), self.gripper.get_goal_status_text()
