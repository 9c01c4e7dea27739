"""Executes Cartesian segments on the simulated arm: IK along the path, a minimum-jerk time law within
the joint velocity limits, joint position control every physics step, tracking monitoring."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldbot.errors import UnreachableTargetError
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
    max_tracking_error: float  # m, TCP
    grasp: GraspResult | None = None


@dataclass(frozen=True)
class PlannedSegment:
    """A segment with its IK solved: joint waypoints (N+1 × dof, from the start) and TCP points."""

    segment: Segment
    joint_path: np.ndarray
    points: np.ndarray


def min_jerk(tau: np.ndarray) -> np.ndarray:
    """Minimum-jerk time law s(τ) on τ ∈ [0, 1]: zero velocity and acceleration at both ends."""
    return 10 * tau**3 - 15 * tau**4 + 6 * tau**5


class ArmExecutor:
    """Drives a robot through Cartesian segments, gripper down at a fixed yaw."""

    def __init__(
        self,
        world,
        robot: Robot,
        grasp: ClothGrasp,
        yaw: float = 0.0,
    ) -> None:
        self.world = world
        self.robot = robot
        self.grasp = grasp
        self.yaw = yaw

    def joint_path(self, points: np.ndarray, q_seed: np.ndarray) -> np.ndarray:
        """IK for every waypoint, each seeded by the previous solution (N × dof)."""
        quat = _down(self.yaw)
        out = []
        q = q_seed
        for i, pt in enumerate(points):
            try:
                q = self.robot.solve_ik(pt, quat, q_seed=q, tol=1e-3)
            except UnreachableTargetError as exc:
                raise UnreachableTargetError(f"waypoint {i} of the path: {exc}") from exc
            out.append(q)
        return np.asarray(out)

    def duration_for(self, path: np.ndarray, points: np.ndarray, speed: float) -> float:
        """Segment time: the Cartesian speed, stretched so no joint exceeds its velocity limit under
        the minimum-jerk law (peak speed 1.875 × mean)."""
        length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
        joint_travel = np.abs(np.diff(path, axis=0)).sum(axis=0)
        t_cart = length / speed
        t_joint = float(np.max(1.875 * joint_travel / (0.8 * self.robot.velocity_limits)))
        return max(t_cart, t_joint, 0.2)

    def plan(
        self, segments: list[Segment], q_start: np.ndarray | None = None
    ) -> list[PlannedSegment]:
        """Solve IK for every waypoint of every segment before anything moves; an infeasible
        waypoint raises UnreachableTargetError naming the segment, the waypoint and the target."""
        q = self.robot.joint_positions() if q_start is None else np.asarray(q_start, dtype=float)
        start = self.robot.fk_tcp(q)[0]
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

    def run(self, segment: Segment | PlannedSegment) -> SegmentLog:
        """Move along the segment (planning it first if needed), then apply its gripper event."""
        planned = segment if isinstance(segment, PlannedSegment) else self.plan([segment])[0]
        segment, path, points = planned.segment, planned.joint_path, planned.points
        # Start from where the arm really is (it may have drifted by the tracking error).
        path = path.copy()
        path[0] = self.robot.joint_positions()
        duration = self.duration_for(path, points, segment.speed)
        dt = self.world.time_step
        n = max(1, round(duration / dt))
        # Path parameter u ∈ [0, 1] by Cartesian arc length; piecewise-linear in joint space.
        seg_len = np.linalg.norm(np.diff(points, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg_len)])
        cum = cum / cum[-1] if cum[-1] > 0 else np.linspace(0, 1, len(points))
        max_err = 0.0
        for k in range(1, n + 1):
            s = float(min_jerk(np.array(k / n)))
            q = np.array([np.interp(s, cum, path[:, j]) for j in range(path.shape[1])])
            self.robot.command_joint_positions(q)
            self.world.step()
            if k % 8 == 0 or k == n:
                target = np.array([np.interp(s, cum, points[:, j]) for j in range(3)])
                max_err = max(max_err, float(np.linalg.norm(self.robot.tcp_pose()[0] - target)))
        log = SegmentLog(segment.name, n * dt, max_err)
        if segment.gripper == "close":
            log.grasp = self.grasp.close()
        elif segment.gripper == "open":
            self.grasp.open()
        return log
