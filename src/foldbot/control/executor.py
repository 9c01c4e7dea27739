"""Executes Cartesian segments on the simulated arm: IK along the path, a time-optimal trajectory
within the joint velocity, acceleration and jerk limits (control.trajectory), joint position control
with velocity feed-forward every physics step, tracking monitoring."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldbot.control.trajectory import JointTrajectory, time_parametrize
from foldbot.errors import ConfigError, UnreachableTargetError
from foldbot.planning.motion import Segment
from foldbot.sim.grasp import ClothGrasp
from foldbot.sim.robots.base import Robot
from foldbot.sim.robots.base import gripper_down_quaternion as _down
from foldbot.types import GraspResult


@dataclass
class SegmentLog:
    """What happened while one segment ran."""

    name: str
    duration: float
    """Time the arm moved (s), gripper event not included."""
    max_tracking_error: float  # m, TCP
    grasp: GraspResult | None = None
    peak_joint_velocity: float = 0.0
    """Largest planned |joint velocity| (rad/s)."""
    peak_joint_acceleration: float = 0.0
    """Largest planned |joint acceleration| (rad/s²)."""


@dataclass(frozen=True)
class PlannedSegment:
    """A segment with its IK solved: joint waypoints (N+1 × dof, from the start) and TCP points."""

    segment: Segment
    joint_path: np.ndarray
    points: np.ndarray


def _cartesian_arc(points: np.ndarray) -> np.ndarray:
    """Cumulative TCP path length (m) at each waypoint."""
    legs = np.linalg.norm(np.diff(np.asarray(points, dtype=float), axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(legs)])


class ArmExecutor:
    """Drives a robot through Cartesian segments, gripper down at a fixed yaw."""

    def __init__(
        self,
        world,
        robot: Robot,
        grasp: ClothGrasp,
        yaw: float = 0.0,
        model: Robot | None = None,
    ) -> None:
        self.world = world
        self.robot = robot
        self.grasp = grasp
        self.yaw = yaw
        self.model = robot if model is None else model
        """Where IK and FK are computed: a kinematic twin of `robot` in a world of its own keeps
        planning from touching the simulated arm (the ROS planner node plans the same way)."""

    def joint_path(self, points: np.ndarray, q_seed: np.ndarray) -> np.ndarray:
        """IK for every waypoint, each seeded by the previous solution (N × dof)."""
        quat = _down(self.yaw)
        out = []
        q = q_seed
        for i, pt in enumerate(points):
            try:
                q = self.model.solve_ik(pt, quat, q_seed=q, tol=1e-3)
            except UnreachableTargetError as exc:
                raise UnreachableTargetError(f"waypoint {i} of the path: {exc}") from exc
            out.append(q)
        return np.asarray(out)

    def trajectory_for(self, path: np.ndarray, points: np.ndarray, speed: float) -> JointTrajectory:
        """Time-optimal trajectory along the joint path within the robot's joint velocity,
        acceleration and jerk limits, the TCP (its waypoints' arc length) at `speed` (m/s) or
        slower, sampled at the physics step."""
        r = self.robot
        path = np.asarray(path, dtype=float)
        if not (np.isfinite(speed) and speed > 0.0):
            raise ConfigError(f"segment speed must be > 0 m/s, got {speed!r}")
        return time_parametrize(
            path,
            r.velocity_limits,
            r.acceleration_limits,
            r.jerk_limits,
            self.world.time_step,
            arc=_cartesian_arc(points),
            max_arc_speed=speed,
            position_limits=(r.lower_limits, r.upper_limits),
        )

    def duration_for(self, path: np.ndarray, points: np.ndarray, speed: float) -> float:
        """Segment time (s) under the joint velocity, acceleration and jerk limits, the TCP at
        ≈ `speed` (m/s) or slower."""
        return self.trajectory_for(path, points, speed).duration

    def plan(
        self, segments: list[Segment], q_start: np.ndarray | None = None
    ) -> list[PlannedSegment]:
        """Solve IK for every waypoint of every segment before anything moves; an infeasible
        waypoint raises UnreachableTargetError naming the segment, the waypoint and the target."""
        q = self.robot.joint_positions() if q_start is None else np.asarray(q_start, dtype=float)
        if self.model is not self.robot:
            self.model.reset_joints(q)  # the twin starts where the arm is
        start = self.model.fk_tcp(q)[0]
        planned = []
        for seg in segments:
            try:
                path = self.joint_path(seg.points, q)
            except UnreachableTargetError as exc:
                raise UnreachableTargetError(f"segment '{seg.name}': {exc}") from exc
            planned.append(
                PlannedSegment(seg, np.vstack([q, path]), np.vstack([start, seg.points]))
            )
            q, start = path[-1], seg.points[-1]
        return planned

    def joint_move_trajectory(self, q0: np.ndarray, q_target: np.ndarray) -> JointTrajectory:
        """Rest-to-rest joint-space move from `q0` to `q_target` under the joint limits."""
        r = self.robot
        return time_parametrize(
            np.vstack([q0, q_target]),
            r.velocity_limits,
            r.acceleration_limits,
            r.jerk_limits,
            self.world.time_step,
        )

    def move_joints(self, q_target: np.ndarray, name: str = "joint_move") -> SegmentLog:
        """Move in joint space (no Cartesian path) to `q_target` under the joint limits: used to
        park the arm, where a straight TCP line could pass near a singularity."""
        q_target = np.asarray(q_target, dtype=float)
        q0 = self.robot.joint_positions()
        if np.abs(q_target - q0).max() < 1e-4:
            return SegmentLog(name, 0.0, 0.0)
        r = self.robot
        traj = self.joint_move_trajectory(q0, q_target)
        for k in range(1, len(traj.times)):
            r.command_joint_positions(traj.positions[k], traj.velocities[k])
            self.world.step()
        err = float(np.linalg.norm(r.tcp_pose()[0] - r.fk_tcp(q_target)[0]))
        return SegmentLog(name, traj.duration, err)

    def run(self, segment: Segment | PlannedSegment) -> SegmentLog:
        """Move along the segment (planning it first if needed), then apply its gripper event."""
        planned = segment if isinstance(segment, PlannedSegment) else self.plan([segment])[0]
        segment, path, points = planned.segment, planned.joint_path, planned.points
        # Start from where the arm really is (it may have drifted by the tracking error).
        path = np.array(path, dtype=float)
        path[0] = self.robot.joint_positions()
        traj = self.trajectory_for(path, points, segment.speed)
        # Cartesian reference for monitoring: the TCP waypoints at the trajectory's path coordinate.
        cum = _cartesian_arc(points)
        last = len(traj.times) - 1
        max_err = 0.0
        for k in range(1, last + 1):
            self.robot.command_joint_positions(traj.positions[k], traj.velocities[k])
            self.world.step()
            if k % 8 == 0 or k == last:
                target = np.array([np.interp(traj.arc[k], cum, points[:, j]) for j in range(3)])
                max_err = max(max_err, float(np.linalg.norm(self.robot.tcp_pose()[0] - target)))
        peaks = traj.peaks()
        log = SegmentLog(
            segment.name,
            traj.duration,
            max_err,
            peak_joint_velocity=peaks["velocity"],
            peak_joint_acceleration=peaks["acceleration"],
        )
        if segment.gripper == "close":
            log.grasp = self.grasp.close()
        elif segment.gripper == "open":
            self.grasp.open()
        return log
