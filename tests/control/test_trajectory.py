"""Jerk-limited time parametrisation (control.trajectory) and the executor that runs it on a UR5."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from foldbot.control.executor import ArmExecutor, PlannedSegment
from foldbot.control.trajectory import (
    OVERSHOOT,
    JointTrajectory,
    hermite_resample,
    thin_samples,
    time_parametrize,
)
from foldbot.errors import ConfigError
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.planning.motion import MotionConfig, Segment, carry_arc, line_path
from foldbot.sim.cloth import ClothConfig, SoftCloth, settle
from foldbot.sim.grasp import ClothGrasp
from foldbot.sim.robots import make_robot
from foldbot.sim.robots.base import Robot
from foldbot.sim.world import SimWorld

DT = 1.0 / 360.0
UR5_VEL, UR5_ACC, UR5_JERK = np.full(6, 3.15), np.full(6, 8.0), np.full(6, 50.0)


def _finite_differences(traj: JointTrajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-joint max |Δq/dt|, |Δ²q/dt²|, |Δ³q/dt³| of the sampled positions."""
    p, dt = traj.positions, traj.dt
    out = []
    for order in (1, 2, 3):
        d = np.diff(p, order, axis=0) / dt**order
        out.append(np.abs(d).max(axis=0) if len(d) else np.zeros(p.shape[1]))
    return out[0], out[1], out[2]


def _assert_within_limits(traj: JointTrajectory, vel, acc, jerk) -> None:
    tol = 1.0 + 1e-6
    assert np.all(np.abs(traj.velocities) <= vel * tol)
    assert np.all(np.abs(traj.accelerations) <= acc * tol)
    v, a, j = _finite_differences(traj)
    assert np.all(v <= vel * tol), (v, vel)
    assert np.all(a <= acc * tol), (a, acc)
    assert np.all(j <= jerk * tol), (j, jerk)


def _polyline_distance(x: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Distance of every row of x to the polyline through pts."""
    a, ab = pts[:-1], np.diff(pts, axis=0)
    rel = x[:, None, :] - a[None]
    t = np.clip((rel * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0.0, 1.0)
    return np.linalg.norm(rel - t[..., None] * ab[None], axis=-1).min(axis=1)


def _random_path(rng: np.random.Generator, kind: str) -> np.ndarray:
    if kind == "corners":  # a random walk: sharp corners at every waypoint
        n = int(rng.integers(2, 8))
        return np.cumsum(rng.normal(0.0, 0.3, (n, 6)), axis=0)
    # a smooth curve densely sampled, like an IK path along a Cartesian line or arc
    t = np.linspace(0.0, 1.0, int(rng.integers(5, 60)))[:, None]
    a, f, ph = rng.normal(0, 0.5, (1, 6)), rng.uniform(0.5, 2.0, (1, 6)), rng.uniform(0, 6, (1, 6))
    return a * np.sin(f * t * np.pi + ph) + rng.normal(0, 0.3, (1, 6)) * t


@pytest.mark.parametrize("seed", range(8))
def test_limits_never_exceeded_on_random_paths(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for kind in ("smooth", "corners"):
        path = _random_path(rng, kind)
        vel = rng.uniform(0.5, 3.5, 6)
        acc = rng.uniform(2.0, 15.0, 6)
        jerk = rng.uniform(20.0, 200.0, 6)
        scale = float(rng.choice([1.0, rng.uniform(0.1, 1.0)]))
        traj = time_parametrize(path, vel, acc, jerk, DT, speed_scale=scale)
        _assert_within_limits(traj, vel * scale, acc, jerk)
        assert np.allclose(np.diff(traj.times), DT)
        # Never outside the range each joint's waypoints span (so never outside joint limits).
        assert np.all(traj.positions >= path.min(axis=0) - OVERSHOOT - 1e-12)
        assert np.all(traj.positions <= path.max(axis=0) + OVERSHOOT + 1e-12)


def test_starts_and_ends_at_rest_at_the_exact_endpoints() -> None:
    path = np.cumsum(np.random.default_rng(3).normal(0, 0.2, (12, 6)), axis=0)
    traj = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    assert np.array_equal(traj.positions[0], path[0])
    assert np.array_equal(traj.positions[-1], path[-1])
    for state in (traj.velocities, traj.accelerations):
        assert np.array_equal(state[0], np.zeros(6)) and np.array_equal(state[-1], np.zeros(6))
    # At rest also by finite differences: jerk-limited start and stop.
    assert np.abs(traj.positions[1] - traj.positions[0]).max() < 50.0 * DT**3
    assert np.abs(traj.positions[-1] - traj.positions[-2]).max() < 50.0 * DT**3
    assert traj.times[0] == 0.0 and traj.duration == pytest.approx(DT * (len(traj.times) - 1))


def test_smooth_path_passes_through_its_waypoints() -> None:
    """A densely sampled smooth path is followed as the cubic spline through its waypoints."""
    t = np.linspace(0, 1, 30)[:, None]
    path = np.hstack([np.sin(2 * t), np.cos(3 * t), t**2, 0.5 * t, np.sin(t), -t])
    traj = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    # Sub-millirad from the polyline (the chord sag of a curve sampled every ~0.1 rad).
    assert _polyline_distance(traj.positions, path).max() < 2e-3
    # Every waypoint is visited: some sample passes within one step of travel of it.
    step = np.abs(traj.velocities).max() * DT
    gaps = np.linalg.norm(traj.positions[:, None] - path[None], axis=-1).min(axis=0)
    assert gaps.max() <= step


def test_sharp_corner_is_cut_by_a_bounded_amount() -> None:
    path = np.zeros((3, 6))
    path[1, 0] = 1.0
    path[2, :2] = 1.0  # a 90° corner at waypoint 1
    traj = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    assert _polyline_distance(traj.positions, path).max() < 0.02  # rad
    assert np.all(traj.positions >= -1e-12) and np.all(traj.positions <= 1.0 + 1e-12)
    _assert_within_limits(traj, UR5_VEL, UR5_ACC, UR5_JERK)


def test_a_path_that_turns_back_comes_to_rest_at_the_turn() -> None:
    """Out and back along one line (a lift and a lowering at one place): the arm stops at the
    far end, and each way takes as long as it would alone, rather than the whole path crawling
    under the bounds the kink's curvature sets (control.trajectory, CUSP_COS)."""
    out = np.linspace(0.0, 1.0, 20)[:, None] * np.array([[0.2, -0.1, 0.3, 0.0, 0.05, 0.0]])
    path = np.vstack([out, out[-2::-1]])
    traj = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    there = time_parametrize(out, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    back = time_parametrize(out[::-1], UR5_VEL, UR5_ACC, UR5_JERK, DT)
    assert traj.duration == pytest.approx(there.duration + back.duration)
    turn = int(np.argmax(traj.positions[:, 2]))
    assert np.array_equal(traj.positions[turn], out[-1])
    assert not traj.velocities[turn].any() and not traj.accelerations[turn].any()
    assert np.array_equal(traj.positions[0], path[0]) and np.array_equal(
        traj.positions[-1], path[0]
    )
    assert np.all(np.diff(traj.times) > 0) and np.all(np.diff(traj.arc) >= 0)
    assert traj.arc[-1] == pytest.approx(2 * np.linalg.norm(out[-1]))
    _assert_within_limits(traj, UR5_VEL, UR5_ACC, UR5_JERK)


def test_position_limits_are_respected_at_a_waypoint_on_the_limit() -> None:
    """A joint peaking at its upper limit: the trajectory must not overshoot it."""
    t = np.linspace(0, 1, 7)
    path = np.zeros((7, 6))
    path[:, 0] = 1.0 - 4 * np.abs(t - 0.5)  # a sharp peak at exactly 1.0 rad
    path[:, 1] = t
    lower, upper = np.full(6, -2.0), np.full(6, 1.0)
    traj = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT, position_limits=(lower, upper))
    assert traj.positions[:, 0].max() <= 1.0
    _assert_within_limits(traj, UR5_VEL, UR5_ACC, UR5_JERK)
    with pytest.raises(ConfigError, match="waypoint 3 has joint 0 at 1 rad"):
        time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT, position_limits=(lower, upper - 0.5))


def test_speed_scale_and_arc_speed_cap_slow_it_down() -> None:
    path = np.linspace(np.zeros(6), np.full(6, 1.5), 20)
    full = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    durations = [full.duration]
    for scale in (0.5, 0.2):
        slow = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT, speed_scale=scale)
        assert np.abs(slow.velocities).max() <= scale * 3.15 * (1 + 1e-9)
        durations.append(slow.duration)
    assert durations[0] < durations[1] < durations[2]
    arc = np.linspace(0.0, 0.3, 20)  # e.g. a 0.3 m TCP path
    capped = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT, arc=arc, max_arc_speed=0.1)
    assert np.diff(capped.arc).max() / DT <= 0.1 * (1 + 1e-9)
    assert capped.duration > 0.3 / 0.1
    assert capped.arc[0] == 0.0 and capped.arc[-1] == pytest.approx(0.3)


def test_motionless_path_is_a_single_sample_at_rest() -> None:
    traj = time_parametrize(np.ones((4, 6)), UR5_VEL, UR5_ACC, UR5_JERK, DT)
    assert traj.duration == 0.0 and traj.positions.shape == (1, 6)
    q, v, a = traj.sample(1.0)
    assert np.array_equal(q, np.ones(6)) and not v.any() and not a.any()


def test_sample_interpolates_and_holds_the_ends() -> None:
    path = np.linspace(np.zeros(6), np.ones(6), 5)
    traj = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    assert np.array_equal(traj.sample(-1.0)[0], path[0])
    assert np.array_equal(traj.sample(traj.duration + 1.0)[0], path[-1])
    k = len(traj.times) // 2
    q, v, _ = traj.sample(float(traj.times[k]))
    assert np.allclose(q, traj.positions[k]) and np.allclose(v, traj.velocities[k])
    mid = traj.sample(float(traj.times[k] + DT / 2))[0]
    assert np.allclose(mid, (traj.positions[k] + traj.positions[k + 1]) / 2)
    with pytest.raises(ConfigError, match="nan"):
        traj.sample(float("nan"))


def test_a_held_trajectory_stays_at_rest_at_its_end_for_the_dwell() -> None:
    # A segment's dwell (a spread's hang), as the ROS planner node times it: the samples the
    # in-process executor commands after a trajectory's end (its last position, at rest).
    path = np.linspace(np.zeros(6), np.ones(6), 5)
    traj = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    held = traj.held(1.0, DT)
    n, extra = len(traj.times), 360
    assert len(held.times) == n + extra
    assert np.allclose(np.diff(held.times), DT) and held.duration == pytest.approx(
        traj.duration + 1.0
    )
    assert np.array_equal(held.positions[:n], traj.positions)
    assert np.array_equal(held.positions[n:], np.repeat(traj.positions[-1:], extra, axis=0))
    assert not held.velocities[n:].any() and not held.accelerations[n:].any()
    assert np.array_equal(held.arc[n:], np.full(extra, traj.arc[-1]))
    assert traj.held(0.0, DT) is traj
    for bad in ((-1.0, DT), (float("nan"), DT), (1.0, 0.0)):
        with pytest.raises(ConfigError, match="a hold needs seconds ≥ 0"):
            traj.held(*bad)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"path": [[0.0, np.nan], [1.0, 1.0]]}, "nan at waypoint 0, joint 1"),
        ({"path": np.zeros((0, 2))}, "N ≥ 1"),
        ({"path": [0.0, 1.0]}, "N × dof"),
        ({"vel_limits": [1.0, 0.0]}, r"velocity limits must be finite and > 0, got \[1.0, 0.0\]"),
        ({"acc_limits": [1.0, -2.0]}, r"acceleration limits .* got \[1.0, -2.0\]"),
        ({"jerk_limits": [1.0, np.inf]}, r"jerk limits .* got \[1.0, inf\]"),
        ({"vel_limits": [1.0, 1.0, 1.0]}, "2 values"),
        ({"dt": 0.0}, "dt must be a positive number of seconds, got 0.0"),
        ({"speed_scale": 1.5}, r"speed_scale must be in \(0, 1\], got 1.5"),
        ({"speed_scale": 0.0}, r"speed_scale must be in \(0, 1\], got 0.0"),
        ({"arc": [1.0, 0.0]}, "non-decreasing"),
        ({"arc": [0.0, 1.0, 2.0]}, "one path coordinate per waypoint"),
        ({"max_arc_speed": -1.0}, "max_arc_speed must be > 0, got -1.0"),
    ],
)
def test_bad_inputs_raise_config_error_naming_the_value(kwargs: dict, message: str) -> None:
    args = {
        "path": [[0.0, 0.0], [1.0, 1.0]],
        "vel_limits": [1.0, 1.0],
        "acc_limits": [1.0, 1.0],
        "jerk_limits": [1.0, 1.0],
        "dt": DT,
    } | kwargs
    with pytest.raises(ConfigError, match=message):
        time_parametrize(**args)


# ---------------------------------------------------------------------------- executor on a UR5
@pytest.fixture(scope="module")
def cell() -> Iterator[tuple[SimWorld, Robot, SoftCloth]]:
    """The UR5 and a settled 20 cm towel, 5 vertices a side, at the workspace centre (25 cm
    under the parked TCP)."""
    world = SimWorld()
    lay = world.layout
    robot = make_robot("ur5", world.client, lay)
    mesh = make_towel(TowelSpec(0.2, 0.2, 5))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), lay.table_height, lay.workspace_center_xy)
    settle(world, cloth)
    yield world, robot, cloth
    world.close()


@pytest.fixture()
def executor(cell: tuple[SimWorld, Robot, SoftCloth]) -> ArmExecutor:
    world, robot, cloth = cell
    robot.reset_joints(robot.home_q)
    return ArmExecutor(world, robot, ClothGrasp(world, robot, cloth))


def test_carry_arc_keeps_its_cartesian_shape_and_speed(executor: ArmExecutor) -> None:
    robot = executor.robot
    lay = executor.world.layout
    cx, cy = lay.workspace_center_xy
    z = lay.table_height + 0.005
    arc = carry_arc(np.array([cx, cy - 0.15, z]), np.array([cx, cy + 0.15, z]), MotionConfig())
    seg = Segment("carry", arc, 0.15)
    planned = executor.plan([Segment("to start", line_path(robot.tcp_pose()[0], arc[0]), 0.3)])
    robot.reset_joints(planned[0].joint_path[-1])
    (carry,) = executor.plan([seg])
    traj = executor.trajectory_for(carry.joint_path, carry.points, seg.speed)
    _assert_within_limits(traj, robot.velocity_limits, robot.acceleration_limits, robot.jerk_limits)
    tcp = np.array([robot.fk_tcp(q)[0] for q in traj.positions[::3]])
    # The TCP stays within 1 mm of the Cartesian waypoint polyline (measured ≈ 0.1 mm) ...
    assert _polyline_distance(tcp, carry.points).max() < 1e-3
    # ... and at the segment's speed or below (TCP speed over 3 samples).
    speed = np.linalg.norm(np.diff(tcp, axis=0), axis=1) / (3 * DT)
    assert speed.max() <= 0.15 * 1.02
    assert speed.max() >= 0.15 * 0.9


def test_executor_follows_a_short_segment_within_limits(executor: ArmExecutor) -> None:
    """A short diagonal descent onto the towel's corner, the jaws closed at its end: the arm
    follows it within the UR5's limits and the grasp holds the corner; the way back lifts it,
    and the jaws open there."""
    world, robot, grasp = executor.world, executor.robot, executor.grasp
    corner_id = grasp.cloth.mesh.keypoints["corner_00"]
    target = grasp.cloth.sim_vertices()[corner_id] + np.array([0.0, 0.0, 0.004])
    start = target - np.array([0.05, 0.03, -0.06])
    (to_start,) = executor.plan([Segment("to start", line_path(robot.tcp_pose()[0], start), 0.3)])
    robot.reset_joints(to_start.joint_path[-1])
    open_before = robot.gripper_opening()
    measured: list[np.ndarray] = []
    world.add_step_hook(lambda w: measured.append(robot.joint_velocities()))
    try:
        log = executor.run(Segment("move", line_path(start, target), 0.2, "close"))
    finally:
        world._step_hooks.pop()
    assert log.max_tracking_error < 5e-3
    assert np.linalg.norm(robot.tcp_pose()[0] - target) < 2e-3
    # The gripper's close settles after the motion: `measured` counts its steps too.
    close_steps = round(0.4 / world.time_step)
    assert log.duration == pytest.approx((len(measured) - close_steps) * world.time_step)
    assert log.duration > np.linalg.norm(target - start) / 0.2
    assert 0.0 < log.peak_joint_velocity <= 3.15
    assert 0.0 < log.peak_joint_acceleration <= 8.0
    # The simulated joints, too, stay within the velocity limits (they lag a little behind).
    assert np.abs(np.array(measured)).max() <= 3.15
    # The jaws closed on the corner: the grasp holds it, and they stand nearly shut.
    assert log.grasp is not None and log.grasp.success, log.grasp
    assert corner_id in log.grasp.vertex_ids and grasp.holding
    closed = robot.gripper_opening()
    assert closed < 0.01 < open_before
    heights: list[float] = []
    world.add_step_hook(lambda w: heights.append(grasp.cloth.sim_vertices()[corner_id, 2]))
    try:
        log = executor.run(Segment("back", line_path(robot.tcp_pose()[0], start), 0.2, "open"))
    finally:
        world._step_hooks.pop()
    # The held corner rose with the jaws on the way back, and was let go there: open again.
    assert max(heights) > target[2] + 0.05
    assert log.grasp is None and not grasp.holding and grasp.held == ()
    assert robot.gripper_opening() > closed + 0.05


def test_executor_runs_a_planned_segment_from_where_the_arm_is(executor: ArmExecutor) -> None:
    robot = executor.robot
    start = robot.tcp_pose()[0]
    target = start + np.array([0.0, 0.0, -0.03])
    planned = executor.plan([Segment("down", line_path(start, target), 0.1)])[0]
    assert isinstance(planned, PlannedSegment)
    robot.reset_joints(planned.joint_path[0] + 1e-3)  # drifted off the planned start
    log = executor.run(planned)
    assert log.max_tracking_error < 5e-3
    assert np.linalg.norm(robot.tcp_pose()[0] - target) < 2e-3


def test_executor_rejects_a_non_positive_speed(executor: ArmExecutor) -> None:
    start = executor.robot.tcp_pose()[0]
    with pytest.raises(ConfigError, match=r"segment speed must be > 0 m/s, got 0\.0"):
        executor.run(Segment("move", line_path(start, start + [0.02, 0, 0]), 0.0))


def _two_motions_with_a_rest() -> JointTrajectory:
    """Two rest-to-rest motions with 0.3 s at rest between them, one sample clock (as the task
    node chains a gripper event's steps into one driver goal). Each path keeps on its way (every
    joint moving one way), so neither comes to rest on the way (no cusp)."""
    rng = np.random.default_rng(5)
    first = time_parametrize(np.cumsum(np.abs(rng.normal(0, 0.2, (8, 6))), axis=0), UR5_VEL,
                             UR5_ACC, UR5_JERK, DT).held(0.3, DT)  # fmt: skip
    onward = np.cumsum(np.abs(rng.normal(0, 0.3, (5, 6))), axis=0)
    path = np.vstack([first.positions[-1], first.positions[-1] - onward])
    second = time_parametrize(path, UR5_VEL, UR5_ACC, UR5_JERK, DT)
    t0 = first.times[-1]
    return JointTrajectory(
        np.concatenate([first.times, t0 + second.times[1:]]),
        np.vstack([first.positions, second.positions[1:]]),
        np.vstack([first.velocities, second.velocities[1:]]),
        np.vstack([first.accelerations, second.accelerations[1:]]),
        np.concatenate([first.arc, first.arc[-1] + second.arc[1:]]),
    )


def test_a_driver_goal_thinned_to_50_hz_is_splined_back_to_the_plan() -> None:
    """A trajectory goes to a real arm's driver at 50 Hz, not at the 360 Hz physics step: its
    points carry positions and velocities, which the driver splines (cubic Hermite, as
    ros_control's controller does). Splined back onto the physics steps it is the plan."""
    traj = _two_motions_with_a_rest()
    keep = thin_samples(traj.times, 0.02, traj.velocities)
    assert keep[0] == 0 and keep[-1] == len(traj.times) - 1
    gaps = np.diff(traj.times[keep])
    assert len(keep) < len(traj.times) / 5  # 1 in 8 at the 1/360 s step: about 45 Hz
    assert (gaps < 0.02 - 1e-9).sum() <= 4  # only beside the rest's two ends, always kept
    assert gaps.max() <= 1.5 * 0.02 + DT
    q, v = hermite_resample(
        traj.times[keep], traj.positions[keep], traj.velocities[keep], traj.times
    )
    assert np.abs(q - traj.positions).max() < 1e-5  # rad
    assert np.abs(v - traj.velocities).max() < 1e-3  # rad/s
    # The rest between the motions is kept exact: both its ends are points of the goal.
    rest = np.all(traj.velocities == 0.0, axis=1)
    held = np.flatnonzero(rest[1:-1]) + 1
    assert np.array_equal(q[held], traj.positions[held]) and not v[held].any()


def test_thinning_keeps_the_ends_and_names_bad_input() -> None:
    times = np.arange(11) * 0.01
    assert thin_samples(times, 0.03).tolist() == [0, 3, 6, 10]  # 9 would leave 0.01 s to 10
    assert thin_samples(times, 0.0).tolist() == list(range(11))
    assert thin_samples(times[:1], 0.02).tolist() == [0]
    with pytest.raises(ConfigError, match="strictly increasing"):
        thin_samples(np.array([0.0, 0.1, 0.1]), 0.02)
    with pytest.raises(ConfigError, match="period must be ≥ 0 s, got -1"):
        thin_samples(times, -1)
