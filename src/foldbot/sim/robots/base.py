"""The abstract simulated robot: an arm with a parallel-jaw gripper, loaded into a PyBullet client.

Frames and conventions (SI units, world frame unless stated):
- The robot base is mounted at ``layout.robot_base_xyz`` with its x axis along +x world (towards
  the table), z up.
- The end effector is the TCP ("tool centre point"), a fixed link centred between the fingertips.
  TCP axes: z = approach direction (out of the flange, through the fingers), y = finger closing
  axis, x = y × z.
- "Gripper down" (``gripper_down_quaternion``) means TCP z along −z world and, at yaw 0, the
  fingers closing along world y (TCP x along −x world).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Collection, Iterator, Sequence
from contextlib import contextmanager
from typing import ClassVar

import numpy as np
import pybullet as p

from foldbot.errors import ConfigError, UnreachableTargetError
from foldbot.sim.layout import CellLayout

HOME_HEIGHT_ABOVE_TABLE = 0.25
"""Height of the TCP above the table top in the home pose (m)."""
OUT_OF_VIEW_TCP_FROM_BASE = (0.25, 0.0, 0.30)
"""The out-of-view park: the TCP this far (m) ahead of the robot base along x, sideways along y,
and above the table top. From the cell's camera the arm is then out of view, where at home, over
the workspace centre, it hides the near edge of a large cloth."""


def gripper_down_quaternion(yaw: float = 0.0) -> np.ndarray:
    """TCP orientation (x, y, z, w) pointing straight down, turned by `yaw` (rad) about world z.

    At yaw = 0 the fingers close along world y; the closing axis is (−sin yaw, cos yaw, 0).
    This is Rz(yaw)·Ry(π).
    """
    if not math.isfinite(yaw):
        raise ConfigError(f"yaw must be finite, got {yaw!r}")
    return np.array([-math.sin(yaw / 2), math.cos(yaw / 2), 0.0, 0.0])


def _frozen(values: Sequence[float] | np.ndarray) -> np.ndarray:
    arr = np.array(values, dtype=float)
    arr.setflags(write=False)
    return arr


def _rotation(quat_xyzw: Sequence[float]) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(list(quat_xyzw))).reshape(3, 3)


def _orientation_error(r_current: np.ndarray, r_target: np.ndarray) -> np.ndarray:
    """Rotation vector (world frame, rad) taking r_current to r_target."""
    r = r_target @ r_current.T
    c = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2.0
    s = np.linalg.norm(v)
    angle = math.atan2(s, c)
    if s < 1e-9:
        if c > 0:
            return v  # small angle: sin ≈ angle
        # angle ≈ π: axis from the symmetric part.
        b = (r + np.eye(3)) / 2.0
        axis = b[:, int(np.argmax(np.diag(b)))]
        return axis / np.linalg.norm(axis) * math.pi
    return v / s * angle


class Robot(abc.ABC):
    """A fixed-base arm with a two-finger parallel gripper in a PyBullet world.

    Subclasses name the URDF, its joints and links and their physical limits; everything else
    (state, control, FK/IK, gripper) lives here. Construction loads the robot, puts the arm in
    ``home_q`` and opens the gripper fully.
    """

    name: ClassVar[str]
    """Registry name ("ur5", "ur5e", "panda")."""
    ARM_JOINT_NAMES: ClassVar[tuple[str, ...]]
    FINGER_JOINT_NAMES: ClassVar[tuple[str, str]]
    """(left, right); each finger joint is prismatic, 0 = closed, positive = opening."""
    FINGER_LINK_NAMES: ClassVar[tuple[str, str]]
    TCP_LINK_NAME: ClassVar[str]
    LOWER_LIMITS: ClassVar[tuple[float, ...]]
    UPPER_LIMITS: ClassVar[tuple[float, ...]]
    VELOCITY_LIMITS: ClassVar[tuple[float, ...]]
    """rad/s."""
    ACCELERATION_LIMITS: ClassVar[tuple[float, ...]]
    """rad/s²."""
    JERK_LIMITS: ClassVar[tuple[float, ...]]
    """rad/s³."""
    EFFORT_LIMITS: ClassVar[tuple[float, ...]]
    """N·m, the force limit of the position motors."""
    HOME_SEED: ClassVar[tuple[float, ...]]
    """Nominal gripper-down, elbow-up posture; seeds the IK for ``home_q``."""
    CLOSED_GAP: ClassVar[float]
    """Gap between the finger inner faces with both finger joints at 0 (m)."""
    FINGER_GAP_OFFSET: ClassVar[float] = 0.0
    """Measured gap = (left − right finger link origin)·(TCP y) − this (m)."""
    FINGER_FORCE: ClassVar[float]
    """Force limit of each finger's position motor (N)."""
    FINGER_MAX_VELOCITY: ClassVar[float]
    """Speed limit of each finger (m/s)."""
    FINGER_LATERAL_FRICTION: ClassVar[float] = 1.5
    JAW_WIDTH: ClassVar[float]
    """Extent of the finger pads across the closing axis, along TCP x (m)."""
    JAW_DEPTH: ClassVar[float]
    """Length of the finger pads along the approach axis (TCP z) (m)."""
    TIP_BELOW_TCP: ClassVar[float]
    """Fingertips lie this far beyond the TCP along the approach axis (TCP z) (m)."""
    POSITION_GAIN: ClassVar[float] = 0.3
    """PyBullet position-motor gain (dimensionless, per step) of the arm joints."""
    VELOCITY_GAIN: ClassVar[float] = 1.0
    IK_ORIENTATION_TOL: ClassVar[float] = 5e-3
    """Largest orientation error (rad) an IK solution may keep."""

    def __init__(self, client: int, layout: CellLayout) -> None:
        """Load the robot into PyBullet client `client`, mounted as `layout` says."""
        self.client = int(client)
        self.layout = layout
        self.body_id: int = self._load(tuple(float(v) for v in layout.robot_base_xyz))
        by_joint: dict[str, int] = {}
        by_link: dict[str, int] = {}
        for j in range(p.getNumJoints(self.body_id, physicsClientId=self.client)):
            info = p.getJointInfo(self.body_id, j, physicsClientId=self.client)
            by_joint[info[1].decode()] = j
            by_link[info[12].decode()] = j
        try:
            self.arm_joint_indices: tuple[int, ...] = tuple(
                by_joint[n] for n in self.ARM_JOINT_NAMES
            )
            self.finger_joint_indices: tuple[int, int] = (
                by_joint[self.FINGER_JOINT_NAMES[0]],
                by_joint[self.FINGER_JOINT_NAMES[1]],
            )
            self.finger_link_indices: tuple[int, int] = (
                by_link[self.FINGER_LINK_NAMES[0]],
                by_link[self.FINGER_LINK_NAMES[1]],
            )
            self.tcp_link_index: int = by_link[self.TCP_LINK_NAME]
        except KeyError as exc:  # pragma: no cover - a broken URDF
            raise ConfigError(f"{self.name}: URDF lacks joint or link {exc}") from exc
        self._link_by_name = by_link
        # Movable joints in PyBullet's DOF order (IK and Jacobians are indexed by these).
        self._movable = tuple(
            j
            for j in range(p.getNumJoints(self.body_id, physicsClientId=self.client))
            if p.getJointInfo(self.body_id, j, physicsClientId=self.client)[2] != p.JOINT_FIXED
        )
        self._arm_dof = [self._movable.index(j) for j in self.arm_joint_indices]
        self._finger_dof = [self._movable.index(j) for j in self.finger_joint_indices]
        self.lower_limits = _frozen(self.LOWER_LIMITS)
        """Arm joint lower position limits (rad)."""
        self.upper_limits = _frozen(self.UPPER_LIMITS)
        """Arm joint upper position limits (rad)."""
        self.velocity_limits = _frozen(self.VELOCITY_LIMITS)
        """Arm joint speed limits (rad/s)."""
        self.acceleration_limits = _frozen(self.ACCELERATION_LIMITS)
        """Arm joint acceleration limits for planning (rad/s²)."""
        self.jerk_limits = _frozen(self.JERK_LIMITS)
        """Arm joint jerk limits for planning (rad/s³)."""
        self.effort_limits = _frozen(self.EFFORT_LIMITS)
        """Arm joint torque limits (N·m), used as the position motors' force limits."""
        self.finger_stroke = float(
            p.getJointInfo(self.body_id, self.finger_joint_indices[0], physicsClientId=self.client)[
                9
            ]
        )
        for link in self.finger_link_indices:
            p.changeDynamics(
                self.body_id,
                link,
                lateralFriction=self.FINGER_LATERAL_FRICTION,
                physicsClientId=self.client,
            )
        # Home: gripper down over the workspace centre, HOME_HEIGHT_ABOVE_TABLE above the table.
        cx, cy = layout.workspace_center_xy if layout.home_xy is None else layout.home_xy
        self.home_q: np.ndarray = _frozen(self.HOME_SEED)
        """Gripper-down posture with the TCP HOME_HEIGHT_ABOVE_TABLE over the workspace centre."""
        self.reset_joints(self.home_q)
        self._home_tcp_position = self.tcp_pose()[0]
        self.home_q = _frozen(
            self.solve_ik(
                [cx, cy, layout.table_height + HOME_HEIGHT_ABOVE_TABLE], q_seed=self.home_q
            )
        )
        self.reset_joints(self.home_q)
        self._home_tcp_position = self.tcp_pose()[0]
        bx, by, _ = layout.robot_base_xyz
        dx, dy, dz = OUT_OF_VIEW_TCP_FROM_BASE
        self.out_of_view_q: np.ndarray = _frozen(
            self.solve_ik([bx + dx, by + dy, layout.table_height + dz], q_seed=self.home_q)
        )
        """Gripper-down posture out of the camera's view (OUT_OF_VIEW_TCP_FROM_BASE): a park
        pose where the arm hides nothing from the camera."""
        self.reset_gripper(self.max_opening)

    # ------------------------------------------------------------------ subclass hooks
    @abc.abstractmethod
    def _load(self, base_xyz: tuple[float, float, float]) -> int:
        """Load the URDF with a fixed base at `base_xyz` (identity orientation); return body id."""

    # ------------------------------------------------------------------ properties
    @property
    def dof(self) -> int:
        """Number of arm joints."""
        return len(self.arm_joint_indices)

    @property
    def max_opening(self) -> float:
        """Largest gap between the finger inner faces (m)."""
        return self.CLOSED_GAP + 2.0 * self.finger_stroke

    def link_index(self, link_name: str) -> int:
        """PyBullet link index of the URDF link `link_name`."""
        try:
            return self._link_by_name[link_name]
        except KeyError:
            raise ConfigError(
                f"{self.name} has no link {link_name!r}; links: {sorted(self._link_by_name)}"
            ) from None

    # ------------------------------------------------------------------ validation helpers
    def _check_q(self, q: Sequence[float] | np.ndarray, what: str = "q") -> np.ndarray:
        arr = np.asarray(q, dtype=float).reshape(-1)
        if arr.shape != (self.dof,):
            raise ConfigError(f"{what} must have {self.dof} joint values, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ConfigError(f"{what} must be finite, got {arr.tolist()}")
        return arr

    def _check_within_limits(self, q: np.ndarray, what: str = "q") -> None:
        bad = (q < self.lower_limits - 1e-9) | (q > self.upper_limits + 1e-9)
        if np.any(bad):
            j = int(np.argmax(bad))
            raise ConfigError(
                f"{what}[{j}] = {q[j]:.6g} rad is outside the {self.name} joint limits "
                f"[{self.lower_limits[j]:.6g}, {self.upper_limits[j]:.6g}]"
            )

    # ------------------------------------------------------------------ state
    def joint_positions(self) -> np.ndarray:
        """Measured arm joint angles (rad)."""
        states = p.getJointStates(self.body_id, self.arm_joint_indices, physicsClientId=self.client)
        return np.array([s[0] for s in states])

    def joint_velocities(self) -> np.ndarray:
        """Measured arm joint velocities (rad/s)."""
        states = p.getJointStates(self.body_id, self.arm_joint_indices, physicsClientId=self.client)
        return np.array([s[1] for s in states])

    def finger_positions(self) -> np.ndarray:
        """Measured finger joint positions (m), (left, right); 0 = closed."""
        states = p.getJointStates(
            self.body_id, self.finger_joint_indices, physicsClientId=self.client
        )
        return np.array([s[0] for s in states])

    def reset_joints(self, q: Sequence[float] | np.ndarray) -> None:
        """Teleport the arm to `q` (rad) at rest and hold it there (motor targets = `q`)."""
        q = self._check_q(q)
        self._check_within_limits(q)
        for j, v in zip(self.arm_joint_indices, q, strict=True):
            p.resetJointState(self.body_id, j, float(v), 0.0, physicsClientId=self.client)
        self.command_joint_positions(q)

    def command_joint_positions(
        self,
        q: Sequence[float] | np.ndarray,
        velocities: Sequence[float] | np.ndarray | None = None,
    ) -> None:
        """Servo the arm towards `q` (rad), optional feed-forward `velocities` (rad/s).

        POSITION_CONTROL with the arm's torque limits as motor forces and its velocity limits as
        the motors' maxVelocity. Takes effect on the next stepSimulation. ConfigError when `q` is
        not finite or outside the joint limits.
        """
        q = self._check_q(q)
        self._check_within_limits(q)
        v = np.zeros(self.dof) if velocities is None else self._check_q(velocities, "velocities")
        for k, j in enumerate(self.arm_joint_indices):
            p.setJointMotorControl2(
                self.body_id,
                j,
                p.POSITION_CONTROL,
                targetPosition=float(q[k]),
                targetVelocity=float(
                    np.clip(v[k], -self.velocity_limits[k], self.velocity_limits[k])
                ),
                force=float(self.effort_limits[k]),
                positionGain=self.POSITION_GAIN,
                velocityGain=self.VELOCITY_GAIN,
                maxVelocity=float(self.velocity_limits[k]),
                physicsClientId=self.client,
            )

    def _link_pose(self, link: int) -> tuple[np.ndarray, np.ndarray]:
        s = p.getLinkState(
            self.body_id, link, computeForwardKinematics=True, physicsClientId=self.client
        )
        return np.array(s[4]), np.array(s[5])

    def tcp_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """TCP position (m) and orientation quaternion (x, y, z, w), world frame."""
        return self._link_pose(self.tcp_link_index)

    @contextmanager
    def _preserved_state(self) -> Iterator[None]:
        """Restore every joint's position and velocity on exit."""
        joints = self._movable
        saved = p.getJointStates(self.body_id, joints, physicsClientId=self.client)
        try:
            yield
        finally:
            for j, s in zip(joints, saved, strict=True):
                p.resetJointState(self.body_id, j, s[0], s[1], physicsClientId=self.client)

    @contextmanager
    def posed(self, q: Sequence[float] | np.ndarray) -> Iterator[None]:
        """Put the arm at angles `q` for a check (e.g. clearance), restoring the state on exit."""
        q = self._check_q(q)
        with self._preserved_state():
            self._set_arm(q)
            yield

    @property
    def body_link_indices(self) -> tuple[int, ...]:
        """The arm's links that must keep clear of the table and of other arms: every link but
        the base (mounted on the table) and the fingers (they close on cloth at the table)."""
        fingers = set(self.finger_link_indices)
        return tuple(
            j
            for j in range(p.getNumJoints(self.body_id, physicsClientId=self.client))
            if j not in fingers
        )

    def nearest_within(
        self, other_body: int, distance: float, links: Collection[int] | None = None
    ) -> tuple[int, int, float] | None:
        """In the current pose, the closest pair of points between this arm (only its `links`, if
        given) and body `other_body` when within `distance` (m): (own link, other's link, distance
        in m); None when nothing is that close."""
        hits = p.getClosestPoints(self.body_id, other_body, distance, physicsClientId=self.client)
        if links is not None:
            hits = [h for h in hits if h[3] in links]
        if not hits:
            return None
        h = min(hits, key=lambda c: c[8])
        return int(h[3]), int(h[4]), float(h[8])

    def link_name(self, link: int) -> str:
        """The URDF name of link index `link` (-1: the base)."""
        if link < 0:
            return "base"
        return p.getJointInfo(self.body_id, link, physicsClientId=self.client)[12].decode()

    def _set_arm(self, q: np.ndarray) -> None:
        for j, v in zip(self.arm_joint_indices, q, strict=True):
            p.resetJointState(self.body_id, j, float(v), 0.0, physicsClientId=self.client)

    def fk_tcp(self, q: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """TCP pose (position, quaternion xyzw) at arm angles `q`, leaving the state untouched."""
        with self.posed(q):
            return self.tcp_pose()

    # ------------------------------------------------------------------ inverse kinematics
    def _jacobian(self, q_all: list[float]) -> np.ndarray:
        """6×dof world-frame Jacobian of the TCP origin (arm columns) at full DOF vector q_all."""
        # calculateJacobian's point is relative to the link's centre-of-mass frame.
        s = p.getLinkState(self.body_id, self.tcp_link_index, physicsClientId=self.client)
        local = -_rotation(s[3]).T @ np.array(s[2])
        zeros = [0.0] * len(q_all)
        jl, ja = p.calculateJacobian(
            self.body_id,
            self.tcp_link_index,
            local.tolist(),
            q_all,
            zeros,
            zeros,
            physicsClientId=self.client,
        )
        j = np.vstack([np.array(jl), np.array(ja)])
        return j[:, self._arm_dof]

    def _refine(
        self, q0: np.ndarray, target_pos: np.ndarray, target_rot: np.ndarray, iterations: int = 150
    ) -> tuple[np.ndarray, float, float]:
        """Damped least squares (Levenberg–Marquardt) from q0; returns (q, pos_err, rot_err)."""
        lo, hi = self.lower_limits, self.upper_limits
        q = np.clip(q0, lo, hi)
        q_all = [0.0] * len(self._movable)
        for d, f in zip(self._finger_dof, self.finger_positions(), strict=True):
            q_all[d] = float(f)

        def residual(qq: np.ndarray) -> np.ndarray:
            self._set_arm(qq)
            pos, orn = self.tcp_pose()
            return np.concatenate(
                [target_pos - pos, _orientation_error(_rotation(orn), target_rot)]
            )

        e = residual(q)
        cost = float(e @ e)
        lam = 1e-3
        for _ in range(iterations):
            if np.linalg.norm(e[:3]) < 1e-6 and np.linalg.norm(e[3:]) < 1e-6:
                break
            for k, d in enumerate(self._arm_dof):
                q_all[d] = float(q[k])
            jac = self._jacobian(q_all)
            improved = False
            for _try in range(8):
                # Active set: joints at a limit that the step would push further are frozen.
                free = np.ones(self.dof, dtype=bool)
                for _ in range(self.dof):
                    jf = jac[:, free]
                    dq = np.zeros(self.dof)
                    dq[free] = np.linalg.solve(jf.T @ jf + lam * np.eye(int(free.sum())), jf.T @ e)
                    blocked = free & (
                        ((q <= lo + 1e-9) & (dq < 0.0)) | ((q >= hi - 1e-9) & (dq > 0.0))
                    )
                    if not blocked.any():
                        break
                    free &= ~blocked
                    if not free.any():
                        break
                n = np.linalg.norm(dq)
                if n > 0.5:
                    dq *= 0.5 / n
                q_new = np.clip(q + dq, lo, hi)
                e_new = residual(q_new)
                cost_new = float(e_new @ e_new)
                if cost_new < cost:
                    q, e, cost = q_new, e_new, cost_new
                    lam = max(lam / 3.0, 1e-9)
                    improved = True
                    break
                lam *= 10.0
            if not improved:
                break
        return q, float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))

    def _ik_seeds(
        self, target_pos: np.ndarray, target_quat: np.ndarray, q_seed: np.ndarray
    ) -> Iterator[np.ndarray]:
        """Seeds in order: the given one, PyBullet's IK from it, home turned towards the target
        (and PyBullet's IK from there), then a few fixed pseudo-random postures."""
        yield q_seed
        yield self._pybullet_ik(target_pos, target_quat, q_seed)
        base = np.asarray(self.layout.robot_base_xyz, dtype=float)
        turned = self.home_q.copy()
        ref = self._home_tcp_position
        turned[0] += math.atan2(target_pos[1] - base[1], target_pos[0] - base[0]) - math.atan2(
            ref[1] - base[1], ref[0] - base[0]
        )
        turned = np.clip(turned, self.lower_limits, self.upper_limits)
        yield turned
        yield self._pybullet_ik(target_pos, target_quat, turned)
        rng = np.random.default_rng(0)
        lo = np.maximum(self.lower_limits, -math.pi)
        hi = np.minimum(self.upper_limits, math.pi)
        for _ in range(4):
            yield rng.uniform(lo, hi)

    def _pybullet_ik(
        self, target_pos: np.ndarray, target_quat: np.ndarray, rest: np.ndarray
    ) -> np.ndarray:
        """PyBullet's null-space IK started (and resting) at `rest`; arm angles only."""
        n = len(self._movable)
        lower, upper, ranges, rest_all = [0.0] * n, [0.0] * n, [1.0] * n, [0.0] * n
        fingers = self.finger_positions()
        for k, d in enumerate(self._arm_dof):
            lower[d], upper[d] = float(self.lower_limits[k]), float(self.upper_limits[k])
            ranges[d] = float(self.upper_limits[k] - self.lower_limits[k])
            rest_all[d] = float(rest[k])
        for f, d in zip(fingers, self._finger_dof, strict=True):
            lower[d], upper[d], ranges[d], rest_all[d] = float(f), float(f) + 1e-6, 1e-6, float(f)
        self._set_arm(rest)
        sol = p.calculateInverseKinematics(
            self.body_id,
            self.tcp_link_index,
            target_pos.tolist(),
            target_quat.tolist(),
            lowerLimits=lower,
            upperLimits=upper,
            jointRanges=ranges,
            restPoses=rest_all,
            maxNumIterations=200,
            residualThreshold=1e-5,
            physicsClientId=self.client,
        )
        return np.clip(
            np.array([sol[d] for d in self._arm_dof]), self.lower_limits, self.upper_limits
        )

    def solve_ik(
        self,
        position: Sequence[float] | np.ndarray,
        orientation_xyzw: Sequence[float] | np.ndarray | None = None,
        q_seed: Sequence[float] | np.ndarray | None = None,
        tol: float = 1e-3,
    ) -> np.ndarray:
        """Arm angles (rad) putting the TCP at `position` (m, world) with `orientation_xyzw`.

        Orientation defaults to ``gripper_down_quaternion(0.0)``; the seed defaults to the current
        joint state. Solutions are searched near the seed first (PyBullet IK plus damped-least-
        squares refinement on PyBullet's Jacobian), within the joint limits. The robot's joint
        state is left exactly as it was. Raises UnreachableTargetError when no solution is within
        `tol` metres and IK_ORIENTATION_TOL radians, ConfigError for non-finite input.
        """
        pos = np.asarray(position, dtype=float).reshape(-1)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise ConfigError(f"IK target position must be 3 finite numbers, got {position!r}")
        quat = gripper_down_quaternion() if orientation_xyzw is None else orientation_xyzw
        quat = np.asarray(quat, dtype=float).reshape(-1)
        if quat.shape != (4,) or not np.all(np.isfinite(quat)) or np.linalg.norm(quat) < 1e-9:
            raise ConfigError(
                f"IK target orientation must be a finite non-zero quaternion (x, y, z, w), "
                f"got {orientation_xyzw!r}"
            )
        if not (math.isfinite(tol) and tol > 0):
            raise ConfigError(f"IK tolerance must be a positive number of metres, got {tol!r}")
        quat = quat / np.linalg.norm(quat)
        target_rot = _rotation(quat)
        best: tuple[np.ndarray, float, float] | None = None
        with self._preserved_state():
            seed = self.joint_positions() if q_seed is None else self._check_q(q_seed, "q_seed")
            for s in self._ik_seeds(pos, quat, np.clip(seed, self.lower_limits, self.upper_limits)):
                q, ep, er = self._refine(s, pos, target_rot)
                if best is None or ep + 0.1 * er < best[1] + 0.1 * best[2]:
                    best = (q, ep, er)
                if ep <= tol and er <= self.IK_ORIENTATION_TOL:
                    break
        assert best is not None
        q, ep, er = best
        within = bool(
            np.all(q >= self.lower_limits - 1e-9) and np.all(q <= self.upper_limits + 1e-9)
        )
        if ep > tol or er > self.IK_ORIENTATION_TOL or not within:
            raise UnreachableTargetError(
                f"{self.name}: no IK solution for target position {pos.round(4).tolist()} m, "
                f"orientation {quat.round(4).tolist()} (xyzw): best residual {ep * 1000:.1f} mm, "
                f"{er:.3g} rad (tolerance {tol * 1000:.1f} mm, {self.IK_ORIENTATION_TOL} rad)"
            )
        return q

    # ------------------------------------------------------------------ gripper
    def finger_target(self, width_m: float) -> float:
        """Each finger joint's position (m) for a gap of `width_m` between the pads (clipped to
        the stroke); ConfigError outside [0, max_opening]."""
        if not math.isfinite(width_m) or width_m < 0.0 or width_m > self.max_opening + 1e-9:
            raise ConfigError(
                f"gripper opening {width_m!r} m is outside [0, {self.max_opening:.4g}] m "
                f"for {self.name}"
            )
        return float(np.clip((width_m - self.CLOSED_GAP) / 2.0, 0.0, self.finger_stroke))

    def set_gripper_opening(self, width_m: float, force: float | None = None) -> None:
        """Servo the fingers to a gap of `width_m` (m), each pushing with at most `force` (N;
        None: FINGER_FORCE, the model's); 0 closes fully.

        Widths below CLOSED_GAP close the joints completely (the gap then stays CLOSED_GAP).
        Takes effect as the simulation steps.
        """
        force = self.FINGER_FORCE if force is None else float(force)
        if not (math.isfinite(force) and force > 0.0):
            raise ConfigError(f"finger force must be > 0 N, got {force!r}")
        target = self.finger_target(float(width_m))
        for j in self.finger_joint_indices:
            p.setJointMotorControl2(
                self.body_id,
                j,
                p.POSITION_CONTROL,
                targetPosition=target,
                force=force,
                maxVelocity=self.FINGER_MAX_VELOCITY,
                physicsClientId=self.client,
            )

    def reset_gripper(self, width_m: float) -> None:
        """Teleport the fingers to a gap of `width_m` (m) and hold it there."""
        target = self.finger_target(float(width_m))
        for j in self.finger_joint_indices:
            p.resetJointState(self.body_id, j, target, 0.0, physicsClientId=self.client)
        self.set_gripper_opening(width_m)

    def gripper_opening(self) -> float:
        """Measured gap between the finger inner faces (m), from the finger links' poses."""
        left, _ = self._link_pose(self.finger_link_indices[0])
        right, _ = self._link_pose(self.finger_link_indices[1])
        _, tcp_q = self.tcp_pose()
        y_axis = _rotation(tcp_q)[:, 1]
        return float((left - right) @ y_axis - self.FINGER_GAP_OFFSET)
