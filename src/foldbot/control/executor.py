"""Executes Cartesian segments on the simulated arm: IK along the path, a minimum-jerk time law within
the joint velocity limits, joint position control every physics step, tracking monitoring."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

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


@dataclass
class ExecutionLog:
    segments: list[SegmentLog] = field(default_factory=list)


def min_jerk(tau: np.ndarray) -> np.ndarray:
    """Minimum-jerk time law s(τ) on τ ∈ [0, 1]: zero velocity and acceleration at both ends."""
    return 10 * tau**3 - 15 * tau**4 + 6 * tau**5


class ArmExecutor:
    """Drives a robot through segments; calls `on_step(world)` after every physics step."""

    def __init__(
        self,
        world,
        robot: Robot,
        grasp: ClothGrasp,
        yaw: float = 0.0,
        on_step: Callable[[object], None] | None = None,
    ) -> None:
        self.world = world
        self.robot = robot
        self.grasp = grasp
        self.yaw = yaw
        self.on_step = on_step

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

    def run(self, segment: Segment) -> SegmentLog:
        """Move along the segment, then apply its gripper event."""
        q0 = self.robot.joint_positions()
        path = self.joint_path(segment.points, q0)
        path = np.vstack([q0, path])
        points = np.vstack([self.robot.tcp_pose()[0], segment.points])
        duration = self.duration_for(path, points, segment.speed)
        dt = self.world.time_step
        n = max(1, round(duration / dt))
        # Path parameter u ∈ [0, N−1] indexes waypoints; piecewise-linear in joint space between.
        seg_len = np.linalg.norm(np.diff(points, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg_len)])
        cum = cum / cum[-1] if cum[-1] > 0 else np.linspace(0, 1, len(points))
        max_err = 0.0
        for k in range(1, n + 1):
            s = float(min_jerk(np.array(k / n)))
            q = np.array([np.interp(s, cum, path[:, j]) for j in range(path.shape[1])])
            self.robot.command_joint_positions(q)
            self.world.step()
            if self.on_step:
                self.on_step(self.world)
            if k % 8 == 0 or k == n:
                target = np.array([np.interp(s, cum, points[:, j]) for j in range(3)])
                max_err = max(max_err, float(np.linalg.norm(self.robot.tcp_pose()[0] - target)))
        log = SegmentLog(segment.name, n * dt, max_err)
        if segment.gripper == "close":
            log.grasp = self.grasp.close()
        elif segment.gripper == "open":
            self.grasp.open()
        return log
