"""Executes Cartesian segments on the simulated arm: IK along the path, a time-optimal trajectory
within the joint velocity, acceleration and jerk limits (control.trajectory), joint position control
with velocity feed-forward every physics step, tracking monitoring."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pybullet as p
from scipy.spatial.transform import Rotation

from foldbot.control.trajectory import JointTrajectory, time_parametrize
from foldbot.errors import ConfigError, SimulationDivergedError, UnreachableTargetError
from foldbot.planning.motion import MotionConfig, Segment, line_path
from foldbot.sim.grasp import ClothGrasp
from foldbot.sim.layout import OBSTACLE_CLEARANCE
from foldbot.sim.robots import check_workspace_reach, rest_postures
from foldbot.sim.robots.base import Robot
from foldbot.sim.robots.base import gripper_down_quaternion as _down
from foldbot.types import GraspResult

TABLE_CLEARANCE = 0.0
"""An arm link closer to the table than this (m; 0 = touching) makes a waypoint infeasible."""
JOINT_MOVE_SAMPLES = 12
"""A joint-space move is checked against the table at this many points along its path."""
OBSTACLE_SAMPLE_RAD = 0.01
"""A joint-space move is checked against a layout's obstacles every this much turn of its
furthest-turning joint (about 9 mm of a UR5's reach)."""
KEEP_TURN_RAD = 0.05
"""A tool turned further than this from gripper down (a tilted spread grasp) is lifted as it is
held (ArmExecutor.lift_segment)."""


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
        model_table_id: int | None = None,
        speed_scale: float = 1.0,
        model_obstacle_ids: Mapping[str, int] | None = None,
    ) -> None:
        MotionConfig(speed_scale=speed_scale)  # ConfigError naming a bad scale
        self.world = world
        self.robot = robot
        self.grasp = grasp
        self.yaw = yaw
        self.model = robot if model is None else model
        """Where IK and FK are computed: a kinematic twin of `robot` in a world of its own keeps
        planning from touching the simulated arm (the ROS planner node plans the same way)."""
        self.speed_scale = float(speed_scale)
        """Fraction of full speed every motion runs at (MotionConfig.speed_scale): the joint
        limits scaled as time is (velocity ×s, acceleration ×s², jerk ×s³) and every TCP speed
        ×s, so a path keeps its shape in time, 1/s times as long."""
        self.model_table_id = world.table_id if model is None else model_table_id
        """The table in the model's world, which every planned waypoint must keep the arm clear
        of (None: not checked, for a twin in a world without one)."""
        obstacles = getattr(world, "obstacle_ids", {}) if model is None else model_obstacle_ids
        self.model_obstacle_ids: dict[str, int] = dict(obstacles or {})
        """The layout's obstacles in the model's world, by name: every planned waypoint keeps
        OBSTACLE_CLEARANCE from each (a twin's world builds them as the cell's does)."""
        self.carried: list[tuple[str, int, np.ndarray]] = []
        """Bodies fixed to the tool in the model's world (carry_body): name, body id, 4 × 4
        body → TCP."""

    def joint_path(
        self, points: np.ndarray, q_seed: np.ndarray, orientations: np.ndarray | None = None
    ) -> np.ndarray:
        """IK for every waypoint, each seeded by the previous solution (N × dof), the TCP at
        `orientations` (N × 4, x y z w) where given, else gripper down at the executor's yaw."""
        down = _down(self.yaw)
        out = []
        q = q_seed
        for i, pt in enumerate(points):
            quat = down if orientations is None else orientations[i]
            try:
                q = self.model.solve_ik(pt, quat, q_seed=q, tol=1e-3)
            except UnreachableTargetError as exc:
                raise UnreachableTargetError(f"waypoint {i} of the path: {exc}") from exc
            out.append(q)
        return np.asarray(out)

    def lift_segment(
        self, start: np.ndarray, quat: np.ndarray, height: float, speed: float
    ) -> Segment:
        """Straight up `height` (m) from the TCP at `start` (m) turned as `quat` (x y z w), at
        `speed` (m/s): gripper down at the executor's yaw, or, for a tool turned more than
        KEEP_TURN_RAD from that (a tilted spread grasp), as it is held. Righting a tilted tool
        on the way up would sweep the jaws through the cloth below, and the turn, made over the
        path's first centimetre, capped the speed of the whole lift (7.5 s for 8 cm)."""
        start, quat = np.asarray(start, dtype=float), np.asarray(quat, dtype=float)
        points = line_path(start, start + np.array([0.0, 0.0, height]))
        cos = min(1.0, abs(float(np.dot(quat, _down(self.yaw)))))
        held = None if 2.0 * math.acos(cos) <= KEEP_TURN_RAD else np.tile(quat, (len(points), 1))
        return Segment("lift", points, speed, orientations=held)

    def carry_body(self, name: str, body: int, T_tcp_body: np.ndarray) -> None:
        """Keep `body` (in the model's world: a calibration board's twin), fixed to the tool at
        `T_tcp_body` (4 × 4), OBSTACLE_CLEARANCE from the layout's obstacles at every planned
        waypoint, as the arm's own links are."""
        self.carried.append((name, int(body), np.asarray(T_tcp_body, dtype=float)))

    def _carried_near(self) -> tuple[str, str, float] | None:
        """In the model's current pose: the first carried body within OBSTACLE_CLEARANCE of an
        obstacle, as (its name, the obstacle's, the distance in m)."""
        m = self.model
        pos, quat = m.tcp_pose()
        T_world_tcp = np.eye(4)
        T_world_tcp[:3, :3] = Rotation.from_quat(quat).as_matrix()
        T_world_tcp[:3, 3] = pos
        for name, body, T_tcp_body in self.carried:
            T = T_world_tcp @ T_tcp_body
            p.resetBasePositionAndOrientation(
                body, T[:3, 3].tolist(), Rotation.from_matrix(T[:3, :3]).as_quat().tolist(),
                physicsClientId=m.client,
            )  # fmt: skip
            for obstacle, other in self.model_obstacle_ids.items():
                hits = p.getClosestPoints(body, other, OBSTACLE_CLEARANCE, physicsClientId=m.client)
                if hits:
                    return name, obstacle, float(min(h[8] for h in hits))
        return None

    def check_table_clearance(self, path: np.ndarray, table: bool = True) -> None:
        """Raise UnreachableTargetError when at some waypoint of the joint path (N × dof) an arm
        link (Robot.body_link_indices: not the base on its mount, nor the fingers, which close on
        cloth at the table) would touch the table, or any link, fingers included, would come
        within OBSTACLE_CLEARANCE of one of the layout's obstacles (only those: `table` false)."""
        table_id = self.model_table_id if table else None
        if table_id is None and not self.model_obstacle_ids:
            return
        m = self.model
        links = set(m.body_link_indices)
        every_link = links | set(m.finger_link_indices)
        for i, q in enumerate(np.asarray(path, dtype=float)):
            with m.posed(q):
                hit = (
                    None if table_id is None else m.nearest_within(table_id, TABLE_CLEARANCE, links)
                )
                near = [
                    (name, m.nearest_within(body, OBSTACLE_CLEARANCE, every_link))
                    for name, body in self.model_obstacle_ids.items()
                ]
                held = self._carried_near() if self.carried and self.model_obstacle_ids else None
            if held is not None:
                what, name, dist = held
                how = "would touch" if dist <= 0.0 else f"would come within {dist * 1000:.1f} mm of"
                raise UnreachableTargetError(
                    f"waypoint {i}: {what} held at the tool {how} obstacle {name!r} (at least "
                    f"{OBSTACLE_CLEARANCE * 1000:.0f} mm needed) at joints "
                    f"{np.round(q, 3).tolist()} rad"
                )
            for name, close in near:
                if close is not None:
                    link, _, dist = close
                    how = (
                        "would touch"
                        if dist <= 0.0
                        else f"would come within {dist * 1000:.1f} mm of"
                    )
                    raise UnreachableTargetError(
                        f"waypoint {i}: the arm's {m.link_name(link)} {how} obstacle {name!r} "
                        f"(at least {OBSTACLE_CLEARANCE * 1000:.0f} mm needed) at joints "
                        f"{np.round(q, 3).tolist()} rad"
                    )
            if hit is not None:
                link, _, dist = hit
                raise UnreachableTargetError(
                    f"waypoint {i}: the arm's {m.link_name(link)} would touch the table "
                    f"({dist * 1000:.1f} mm from it; at least {TABLE_CLEARANCE * 1000:.0f} mm "
                    f"needed) at joints {np.round(q, 3).tolist()} rad"
                )

    def check_postures(self, postures: Mapping[str, np.ndarray]) -> None:
        """ConfigError naming the posture (home, park: where the arm rests between motions) in
        which the arm would come within OBSTACLE_CLEARANCE of one of the layout's obstacles, so a
        layout whose obstacle stands where the arm rests is refused before anything moves."""
        for name, q in postures.items():
            try:
                self.check_table_clearance(np.asarray(q, dtype=float)[None], table=False)
            except UnreachableTargetError as exc:
                raise ConfigError(
                    f"the arm's {name} posture meets an obstacle of the layout: "
                    f"{str(exc).removeprefix('waypoint 0: ')}; move the obstacle, or the arm "
                    "(robot_base_xyz, home_xy)"
                ) from None

    def check_joint_move(self, q0: np.ndarray, q_target: np.ndarray, table: bool = True) -> None:
        """UnreachableTargetError where a straight joint-space move from `q0` to `q_target`
        would bring an arm link to the table (checked at JOINT_MOVE_SAMPLES points; not with
        `table` false) or within OBSTACLE_CLEARANCE of a layout's obstacle (checked every
        OBSTACLE_SAMPLE_RAD of the joint that turns furthest, a thin post not stepped over)."""
        q0, q_target = np.asarray(q0, dtype=float), np.asarray(q_target, dtype=float)
        samples = []
        if table:
            samples.append((JOINT_MOVE_SAMPLES, True))
        if self.model_obstacle_ids:
            turn = float(np.abs(q_target - q0).max())
            samples.append(
                (max(JOINT_MOVE_SAMPLES, math.ceil(turn / OBSTACLE_SAMPLE_RAD) + 1), False)
            )
        for n, with_table in samples:
            s = np.linspace(0.0, 1.0, n)[:, None]
            try:
                self.check_table_clearance(q0 + s * (q_target - q0), table=with_table)
            except UnreachableTargetError as exc:  # "waypoint i" is a point along the move
                i, _, why = str(exc).removeprefix("waypoint ").partition(": ")
                raise UnreachableTargetError(
                    f"at point {i} of {n} along the joint move: {why}"
                ) from exc

    def trajectory_for(self, path: np.ndarray, points: np.ndarray, speed: float) -> JointTrajectory:
        """Time-optimal trajectory along the joint path within the robot's joint velocity,
        acceleration and jerk limits, the TCP (its waypoints' arc length) at `speed` (m/s) or
        slower, both at the executor's speed scale, sampled at the physics step."""
        r = self.robot
        path = np.asarray(path, dtype=float)
        if not (np.isfinite(speed) and speed > 0.0):
            raise ConfigError(f"segment speed must be > 0 m/s, got {speed!r}")
        return time_parametrize(
            path,
            *self.joint_limits(),
            self.world.time_step,
            arc=_cartesian_arc(points),
            max_arc_speed=speed * self.speed_scale,
            position_limits=(r.lower_limits, r.upper_limits),
        )

    def joint_limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The robot's joint velocity, acceleration and jerk limits (rad/s, rad/s², rad/s³) at
        the executor's speed scale s: ×s, ×s², ×s³."""
        r, s = self.robot, self.speed_scale
        return (
            np.asarray(r.velocity_limits, dtype=float) * s,
            np.asarray(r.acceleration_limits, dtype=float) * s**2,
            np.asarray(r.jerk_limits, dtype=float) * s**3,
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
                path = self.joint_path(seg.points, q, seg.orientations)
                self.check_table_clearance(path)
            except UnreachableTargetError as exc:
                error = UnreachableTargetError(f"segment '{seg.name}': {exc}")
                error.segment = seg.name
                raise error from exc
            planned.append(
                PlannedSegment(seg, np.vstack([q, path]), np.vstack([start, seg.points]))
            )
            q, start = path[-1], seg.points[-1]
        return planned

    def joint_move_trajectory(self, q0: np.ndarray, q_target: np.ndarray) -> JointTrajectory:
        """Rest-to-rest joint-space move from `q0` to `q_target` under the joint limits."""
        return time_parametrize(
            np.vstack([q0, q_target]), *self.joint_limits(), self.world.time_step
        )

    def move_joints(self, q_target: np.ndarray, name: str = "joint_move") -> SegmentLog:
        """Move in joint space (no Cartesian path) to `q_target` under the joint limits: used to
        park the arm, where a straight TCP line could pass near a singularity."""
        return move_joints_together([(self, q_target)], name)[0]

    def start(self, segment: Segment | PlannedSegment) -> _Run:
        """Time-parametrise a segment (planning it first if needed) from where the arm really is
        (it may have drifted by the tracking error); step it with `_Run.command`."""
        planned = segment if isinstance(segment, PlannedSegment) else self.plan([segment])[0]
        path = np.array(planned.joint_path, dtype=float)
        path[0] = self.robot.joint_positions()
        traj = self.trajectory_for(path, planned.points, planned.segment.speed)
        return _Run(self, planned.segment, planned.points, traj, _cartesian_arc(planned.points))

    def run(self, segment: Segment | PlannedSegment) -> SegmentLog:
        """Move along the segment (planning it first if needed), then apply its gripper event."""
        return run_together([(self, segment)])[0]


@dataclass
class _Run:
    """One segment being executed: its trajectory, commanded sample by sample, and the largest
    TCP tracking error seen (checked every 8th step and at the end)."""

    executor: ArmExecutor
    segment: Segment
    points: np.ndarray
    traj: JointTrajectory
    cum: np.ndarray
    """Cumulative TCP path length at each waypoint (m): the Cartesian reference for monitoring."""
    max_err: float = 0.0

    @property
    def samples(self) -> int:
        """Physics steps the segment takes: its trajectory, then its dwell at the last sample."""
        dwell = round(self.segment.dwell / self.executor.world.time_step)
        return len(self.traj.times) + dwell

    def command(self, k: int) -> None:
        """Command sample k (held at the last sample, at rest, once the trajectory has ended)."""
        robot, last = self.executor.robot, len(self.traj.times) - 1
        if k <= last:
            robot.command_joint_positions(self.traj.positions[k], self.traj.velocities[k])
        else:
            robot.command_joint_positions(self.traj.positions[last], np.zeros(robot.dof))

    def monitor(self, k: int) -> None:
        """After the step that followed command(k): update the tracking error."""
        last = len(self.traj.times) - 1
        if k > last or not (k % 8 == 0 or k == last):
            return
        target = np.array(
            [np.interp(self.traj.arc[k], self.cum, self.points[:, j]) for j in range(3)]
        )
        err = float(np.linalg.norm(self.executor.robot.tcp_pose()[0] - target))
        self.max_err = max(self.max_err, err)

    def finish(self) -> SegmentLog:
        """The segment's log, after its gripper event (close → the grasp result)."""
        peaks = self.traj.peaks()
        log = SegmentLog(
            self.segment.name,
            self.traj.duration,
            self.max_err,
            peak_joint_velocity=peaks["velocity"],
            peak_joint_acceleration=peaks["acceleration"],
        )
        if self.segment.gripper == "close":
            log.grasp = self.executor.grasp.close()
        elif self.segment.gripper == "open":
            self.executor.grasp.open()
        return log


def run_together(steps: list[tuple[ArmExecutor, Segment | PlannedSegment]]) -> list[SegmentLog]:
    """Move every arm along its segment at once (one physics world, one clock: an arm whose
    trajectory ends first holds its last sample), then apply each segment's gripper event;
    returns one log per arm, in order."""
    if not steps:
        return []
    world = steps[0][0].world
    if any(ex.world is not world for ex, _ in steps):
        raise ValueError("arms stepped together must share one world")
    runs = [ex.start(step) for ex, step in steps]
    t0 = world.sim_time
    try:
        for k in range(1, max(r.samples for r in runs)):
            for r in runs:
                r.command(k)
            world.step()
            for r in runs:
                r.monitor(k)
        return [r.finish() for r in runs]
    except SimulationDivergedError as exc:
        raise _diverged_in(exc, runs, world.sim_time - t0) from exc


def _diverged_in(
    exc: SimulationDivergedError, runs: list[_Run], t: float
) -> SimulationDivergedError:
    """`exc` restated with the segment(s) the arms were running and how far into them (s), so a
    divergence record says in which motion (descend, lift, lay, …) the cloth blew up."""
    names = list(dict.fromkeys(r.segment.name for r in runs))
    error = SimulationDivergedError(f"{exc} (in segment {' + '.join(names)}, {t:.2f} s in)")
    error.segment = names[0]
    return error


def check_arm_fits(executor: ArmExecutor, robot: str, park: str) -> None:
    """ConfigError, before anything moves, where the arm (on `executor`'s planning model) cannot
    reach the workspace centre, or would rest (home, and its park pose by `park`) in one of the
    layout's obstacles: what every cell checks as it starts."""
    check_workspace_reach(executor.model, robot)
    executor.check_postures(rest_postures(executor.model, park))


def joint_move_trajectories(
    targets: list[tuple[ArmExecutor, np.ndarray]],
) -> list[JointTrajectory | None]:
    """Each arm's rest-to-rest joint-space trajectory from where it is to its target, None for
    an arm already there (what move_joints_together runs; apart, so a cell can say how long a
    move takes before it moves)."""
    trajs: list[JointTrajectory | None] = []
    for ex, q in targets:
        q = np.asarray(q, dtype=float)
        q0 = ex.robot.joint_positions()
        trajs.append(None if np.abs(q - q0).max() < 1e-4 else ex.joint_move_trajectory(q0, q))
    return trajs


def move_joints_together(
    targets: list[tuple[ArmExecutor, np.ndarray]],
    name: str = "joint_move",
    trajs: list[JointTrajectory | None] | None = None,
) -> list[SegmentLog]:
    """Rest-to-rest joint-space moves of every arm at once (one clock, as run_together); an arm
    already at its target does not move. `trajs`: joint_move_trajectories(targets), where the
    caller has them already."""
    if not targets:
        return []
    world = targets[0][0].world
    if trajs is None:
        trajs = joint_move_trajectories(targets)
    steps = max((len(t.times) for t in trajs if t is not None), default=0)
    for k in range(1, steps):
        for (ex, _), t in zip(targets, trajs, strict=True):
            if t is not None:
                i = min(k, len(t.times) - 1)
                v = t.velocities[i] if k < len(t.times) else np.zeros(ex.robot.dof)
                ex.robot.command_joint_positions(t.positions[i], v)
        world.step()
    logs = []
    for (ex, q), t in zip(targets, trajs, strict=True):
        if t is None:
            logs.append(SegmentLog(name, 0.0, 0.0))
            continue
        err = float(np.linalg.norm(ex.robot.tcp_pose()[0] - ex.robot.fk_tcp(q)[0]))
        logs.append(SegmentLog(name, t.duration, err))
    return logs
