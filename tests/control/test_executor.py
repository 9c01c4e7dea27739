"""The executor (foldbot.control.executor): every planned waypoint keeps the arm clear of the
table, and several arms move on one clock; on real UR5s in a PyBullet world."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from foldbot.control.executor import ArmExecutor, move_joints_together, run_together
from foldbot.errors import (
    ConfigError,
    SimulationDivergedError,
    UnreachableTargetError,
    failed_segment,
)
from foldbot.planning.motion import Segment, line_path
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimWorld


@pytest.fixture
def executor():
    with SimWorld() as world:
        robot = make_robot("ur5", world.client, world.layout)
        yield ArmExecutor(world, robot, grasp=None)


def test_a_path_that_would_push_the_wrist_into_the_table_is_refused(executor):
    world, robot = executor.world, executor.robot
    start = robot.tcp_pose()[0]
    # IK reaches a TCP 10 cm under the table top; the palm would be inside the table.
    below = np.array([start[0], start[1], world.layout.table_height - 0.10])
    q0 = robot.joint_positions()
    with pytest.raises(UnreachableTargetError, match=r"segment 'dive'.*would touch the table") as e:
        executor.plan([Segment("dive", line_path(start, below), 0.25)])
    assert e.value.segment == "dive"
    assert np.array_equal(robot.joint_positions(), q0) and world.steps == 0


def test_a_grasp_at_the_cloth_on_the_table_is_allowed(executor):
    # The fingers close on cloth lying on the table: only they come down to it.
    world, robot = executor.world, executor.robot
    start = robot.tcp_pose()[0]
    grasp = np.array([start[0], start[1], world.layout.table_height + 0.004])
    (planned,) = executor.plan([Segment("descend", line_path(start, grasp), 0.25)])
    assert len(planned.joint_path) > 2


def test_a_twin_without_a_table_is_not_checked():
    with SimWorld() as world, SimWorld() as model_world:
        robot = make_robot("ur5", world.client, world.layout)
        twin = make_robot("ur5", model_world.client, model_world.layout)
        assert ArmExecutor(world, robot, grasp=None, model=twin).model_table_id is None
        checked = ArmExecutor(world, robot, None, model=twin, model_table_id=model_world.table_id)
        assert checked.model_table_id == model_world.table_id


@pytest.fixture
def two_arms():
    with SimWorld() as world:
        arms = [make_robot("ur5", world.client, lay) for lay in world.layout.arm_layouts(2)]
        yield world, [ArmExecutor(world, arm, grasp=None) for arm in arms]


def test_both_arms_move_at_once_and_the_shorter_move_waits(two_arms):
    world, (left, right) = two_arms
    z = world.layout.table_height + 0.1
    a0, b0 = left.robot.tcp_pose()[0], right.robot.tcp_pose()[0]
    a1 = np.array([0.50, 0.15, z])  # a long move
    b1 = b0 + [0.0, 0.0, -0.05]  # a short one
    steps = [
        (left, left.plan([Segment("long", line_path(a0, a1), 0.25)])[0]),
        (right, right.plan([Segment("short", line_path(b0, b1), 0.25)])[0]),
    ]
    long_samples = len(left.start(steps[0][1]).traj.times)
    logs = run_together(steps)
    # One clock: the world stepped as long as the longer move, not the sum of both.
    assert world.steps == long_samples - 1
    assert np.linalg.norm(left.robot.tcp_pose()[0] - a1) < 0.01
    assert np.linalg.norm(right.robot.tcp_pose()[0] - b1) < 0.01
    assert [log.name for log in logs] == ["long", "short"]
    assert all(log.max_tracking_error < 0.02 for log in logs)
    assert logs[0].duration > logs[1].duration


def test_both_arms_park_together(two_arms):
    world, arms = two_arms
    targets = [(ex, ex.robot.out_of_view_q) for ex in arms]
    logs = move_joints_together(targets, "park")
    for ex in arms:
        assert np.abs(ex.robot.joint_positions() - ex.robot.out_of_view_q).max() < 0.02
    assert world.steps == round(max(log.duration for log in logs) / world.time_step)
    # Already there: nothing moves.
    before = world.steps
    move_joints_together(targets, "park")
    assert world.steps == before


def test_arms_in_different_worlds_are_refused(two_arms):
    _world, (left, _right) = two_arms
    with SimWorld() as other:
        stranger = ArmExecutor(other, make_robot("ur5", other.client, other.layout), grasp=None)
        a0 = left.robot.tcp_pose()[0]
        s0 = stranger.robot.tcp_pose()[0]
        steps = [
            (left, left.plan([Segment("a", line_path(a0, a0 + [0, 0, 0.02]), 0.25)])[0]),
            (stranger, stranger.plan([Segment("b", line_path(s0, s0 + [0, 0, 0.02]), 0.25)])[0]),
        ]
        with pytest.raises(ValueError, match="share one world"):
            run_together(steps)


def test_a_dwell_holds_the_arm_still_at_the_segment_end(executor):
    world, robot = executor.world, executor.robot
    a0 = robot.tcp_pose()[0]
    a1 = a0 + [0.0, 0.0, 0.05]
    (planned,) = executor.plan([Segment("hang", line_path(a0, a1), 0.25, dwell=0.5)])
    samples = len(executor.start(planned).traj.times)
    executor.run(planned)
    # The move, then 0.5 s more at its end, on the world's clock.
    assert world.steps == samples - 1 + round(0.5 / world.time_step)
    assert np.linalg.norm(robot.tcp_pose()[0] - a1) < 0.005
    assert np.abs(robot.joint_velocities()).max() < 0.01


def test_a_divergence_names_the_segment_the_arms_were_running(two_arms):
    world, (left, right) = two_arms
    a0, b0 = left.robot.tcp_pose()[0], right.robot.tcp_pose()[0]
    steps = [
        (left, left.plan([Segment("lift", line_path(a0, a0 + [0.0, 0.0, 0.05]), 0.25)])[0]),
        (right, right.plan([Segment("lift", line_path(b0, b0 + [0.0, 0.0, 0.05]), 0.25)])[0]),
    ]

    def blow_up(w):  # as the cloth's DivergenceMonitor raises, 36 steps (0.1 s) in
        if w.steps == 36:
            raise SimulationDivergedError("cloth simulation diverged: non-finite vertex positions")

    world.add_step_hook(blow_up)
    with pytest.raises(
        SimulationDivergedError, match=r"non-finite.*in segment lift, 0\.10 s in"
    ) as e:
        run_together(steps)
    assert e.value.segment == "lift" and failed_segment(e.value) == "lift"


def test_a_relays_few_mm_carry_is_timed_in_seconds_over_a_stadium_not_a_minute(executor):
    # Up 5 cm and 8 mm over: the half-sine's tip turns on 0.13 mm, which caps the whole
    # motion's speed; the stadium's half circle turns on 4 mm (docs/experiments.md).
    import dataclasses

    from foldbot.planning.actions import FoldAction
    from foldbot.planning.motion import MotionConfig, action_segments

    z = executor.world.layout.table_height
    x, y = executor.world.layout.workspace_center_xy
    relay = FoldAction(
        grasp=np.array([x + 0.004, y, z + 0.006]),
        place=np.array([x - 0.004, y, z]),
        fold_line=(x, y - 0.2, 0.0, 0.4),
        carry="stadium",
    )
    start = executor.robot.tcp_pose()[0]
    durations = {}
    for carry in ("arc", "stadium"):
        segs = action_segments(dataclasses.replace(relay, carry=carry), start, MotionConfig())
        planned = executor.plan(segs)[2]  # timed from its planned start, as run after descend
        traj = executor.trajectory_for(planned.joint_path, planned.points, planned.segment.speed)
        durations[carry] = traj.duration
    assert durations["stadium"] < 10.0 < 30.0 < durations["arc"], durations


def test_a_corner_laid_back_a_fraction_of_a_mm_goes_up_and_down_in_seconds(executor):
    # A slipped corner that fell where it lay is laid back 0.3 mm over, lifted 5 cm
    # (LoopConfig.slip_lay_back_lift): a half circle that narrow turned on 0.15 mm, and the
    # lay-back took 90 s. Under STADIUM_MIN_WIDTH the carry goes straight up and down, coming to
    # rest at the top (control.trajectory's cusps).
    from foldbot.planning.actions import FoldAction
    from foldbot.planning.motion import STADIUM_MIN_WIDTH, MotionConfig, action_segments

    z = executor.world.layout.table_height
    x, y = executor.world.layout.workspace_center_xy
    lay_back = FoldAction(
        grasp=np.array([x, y, z]),
        place=np.array([x - 0.0003, y, z + 0.004]),
        fold_line=(x, y - 0.2, 0.0, 0.4),
        carry="stadium",
        lift=0.05,
    )
    segs = action_segments(lay_back, executor.robot.tcp_pose()[0], MotionConfig())
    carry = segs[2].points
    assert np.ptp(carry[:, 0]) < STADIUM_MIN_WIDTH and np.ptp(carry[:, 1]) < 1e-9
    assert carry[:, 2].max() == pytest.approx(max(carry[0, 2], carry[-1, 2]) + 0.05, abs=1e-4)
    planned = executor.plan(segs)[2]
    traj = executor.trajectory_for(planned.joint_path, planned.points, planned.segment.speed)
    assert traj.duration < 10.0, traj.duration


def test_a_tilted_tool_is_lifted_as_it_is_held_in_a_second(executor):
    """After a failed grasp with the tool tilted 20° and turned 109° about the vertical (a
    spread's lean away from the other corner), the lift keeps the tool as it is: righting it
    at the lift's start (as every lift did: the wrist turning 1.9 rad there) capped the speed
    of the whole 8 cm. An upright tool lifts gripper down, as before."""
    from scipy.spatial.transform import Rotation

    from foldbot.sim.robots.base import gripper_down_quaternion

    world, robot = executor.world, executor.robot
    x, y = world.layout.workspace_center_xy
    down = gripper_down_quaternion(executor.yaw)
    lean = Rotation.from_rotvec([0.0, 0.0, -1.9]) * Rotation.from_rotvec([0.35, 0.0, 0.0])
    tilted = (lean * Rotation.from_quat(down)).as_quat()
    start = robot.tcp_pose()[0]
    reach = line_path(start, np.array([x, y, world.layout.table_height + 0.03]))
    executor.run(Segment("reach", reach, 0.25, orientations=np.tile(tilted, (len(reach), 1))))
    here, held = robot.tcp_pose()
    lift = executor.lift_segment(here, held, 0.08, 0.5)
    assert lift.orientations is not None and np.allclose(lift.orientations, held)
    assert lift.points[-1] == pytest.approx(here + [0.0, 0.0, 0.08])

    def duration(segment: Segment) -> float:
        (planned,) = executor.plan([segment])
        return executor.trajectory_for(planned.joint_path, planned.points, 0.5).duration

    righted = Segment("lift", lift.points, 0.5)  # gripper down from the first waypoint on
    assert duration(lift) < 1.0 < 5.0 < duration(righted)
    executor.run(lift)
    assert robot.tcp_pose()[0] == pytest.approx(lift.points[-1], abs=2e-3)
    # Upright (within KEEP_TURN_RAD of gripper down): lifted gripper down, the executor's own.
    assert executor.lift_segment(here, down, 0.08, 0.5).orientations is None


def test_a_joint_move_into_the_table_is_refused_before_it_moves():
    from foldbot.sim.layout import DEFAULT_LAYOUT

    with SimWorld() as world:
        robot = make_robot("ur5", world.client, DEFAULT_LAYOUT)
        ex = ArmExecutor(world, robot, None)
        q0 = robot.home_q
        ex.check_joint_move(q0, q0 + [0.0, -0.6, 0.0, 0.0, 0.0, 0.0])  # up, away from it
        with pytest.raises(UnreachableTargetError, match="would touch the table"):
            ex.check_joint_move(q0, q0 + [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])  # the shoulder down
        assert np.allclose(robot.joint_positions(), q0)  # nothing moved


def test_a_slowed_arm_makes_the_same_moves_in_1_over_s_the_time():
    # speed_scale s scales time: velocity ×s, acceleration ×s², jerk ×s³, TCP speed ×s, so a
    # segment and a joint move keep their shape and take 1/s as long (a real arm's slider).
    with SimWorld() as world:
        robot = make_robot("ur5", world.client, world.layout)
        full = ArmExecutor(world, robot, grasp=None)
        slow = ArmExecutor(world, robot, grasp=None, speed_scale=0.25)
        a0 = robot.tcp_pose()[0]
        seg = Segment("carry", line_path(a0, a0 + [0.1, 0.05, -0.05]), 0.25)
        (planned,) = full.plan([seg])
        fast_traj = full.trajectory_for(planned.joint_path, planned.points, 0.25)
        slow_traj = slow.trajectory_for(planned.joint_path, planned.points, 0.25)
        assert slow_traj.duration == pytest.approx(4 * fast_traj.duration, rel=0.02)
        # The same path at each instant 4× later.
        t = np.linspace(0.0, fast_traj.duration, 9)
        for j in range(robot.dof):
            fast_q = np.interp(t, fast_traj.times, fast_traj.positions[:, j])
            slow_q = np.interp(4 * t, slow_traj.times, slow_traj.positions[:, j])
            assert np.abs(fast_q - slow_q).max() < 2e-3
        assert np.abs(slow_traj.velocities).max() <= 0.25 * np.max(robot.velocity_limits)
        q1 = planned.joint_path[-1]
        q0 = robot.joint_positions()
        assert slow.joint_move_trajectory(q0, q1).duration == pytest.approx(
            4 * full.joint_move_trajectory(q0, q1).duration, rel=0.02
        )
        # And the slowed arm really moves so, on the simulated UR5.
        log = slow.run(planned)
        assert log.duration == pytest.approx(slow_traj.duration, abs=2 * world.time_step)
        assert np.linalg.norm(robot.tcp_pose()[0] - planned.points[-1]) < 0.005


@pytest.mark.parametrize("scale", [0.0, 0.01, 1.5, float("nan"), True])
def test_a_speed_scale_outside_what_a_slider_allows_is_refused(scale):
    with SimWorld() as world:
        robot = make_robot("ur5", world.client, world.layout)
        with pytest.raises(ConfigError, match=r"speed_scale must be in \[0\.05, 1\]"):
            ArmExecutor(world, robot, grasp=None, speed_scale=scale)


def test_a_path_into_a_layout_obstacle_is_refused_naming_it_before_anything_moves():
    from foldbot.sim.layout import CellLayout, Obstacle
    from foldbot.sim.world import SimConfig

    # A lamp hanging 32–42 cm over the table above the workspace's far left: the wrist meets it
    # coming down to (0.66, 0.12), 8 cm over the table; without it the same path is planned.
    lamp = Obstacle("lamp", (0.66, 0.12, 1.12), (0.12, 0.12, 0.10))
    segments = lambda start: [  # noqa: E731
        Segment("down", line_path(start, np.array([0.66, 0.12, 0.83])), 0.25)
    ]
    with SimWorld() as world:
        robot = make_robot("ur5", world.client, world.layout)
        ArmExecutor(world, robot, grasp=None).plan(segments(robot.tcp_pose()[0]))
    with SimWorld(SimConfig(layout=CellLayout(obstacles=(lamp,)))) as world:
        robot = make_robot("ur5", world.client, world.layout)
        executor = ArmExecutor(world, robot, grasp=None)
        assert executor.model_obstacle_ids == world.obstacle_ids != {}
        q0 = robot.joint_positions()
        with pytest.raises(
            UnreachableTargetError,
            match=r"segment 'down': waypoint \d+: the arm's \w+ would (touch|come within "
            r"[\d.]+ mm of) obstacle 'lamp' \(at least 20 mm needed\)",
        ):
            executor.plan(segments(robot.tcp_pose()[0]))
        assert np.array_equal(robot.joint_positions(), q0) and world.steps == 0
        # Where the arm rests is checked before it: its home is clear of the lamp.
        executor.check_postures({"home": robot.home_q})


def test_a_layout_obstacle_where_the_arm_rests_is_refused_by_name():
    from foldbot.sim.layout import CellLayout, Obstacle
    from foldbot.sim.world import SimConfig

    # Hanging 32 cm over the workspace centre: the arm's home holds its gripper 25 cm up there.
    lamp = Obstacle("lamp", (0.55, 0.10, 1.10), (0.30, 0.30, 0.08))
    with SimWorld(SimConfig(layout=CellLayout(obstacles=(lamp,)))) as world:
        robot = make_robot("ur5", world.client, world.layout)
        with pytest.raises(
            ConfigError,
            match=r"^the arm's home posture meets an obstacle of the layout: the arm's \w+ would "
            r"touch obstacle 'lamp'.*; move the obstacle, or the arm \(robot_base_xyz, home_xy\)$",
        ):
            ArmExecutor(world, robot, grasp=None).check_postures({"home": robot.home_q})


def test_a_joint_move_sweeping_through_a_layout_obstacle_is_refused_naming_it():
    from foldbot.sim.layout import CellLayout, Obstacle
    from foldbot.sim.robots.base import gripper_down_quaternion
    from foldbot.sim.world import SimConfig

    # Gripper down 40 cm over the table at y = ±0.25: the joint move between the two carries
    # the hand through y ≈ 0, where a lamp hangs; both ends are clear of it.
    lamp = Obstacle("lamp", (0.42, 0.0, 1.15), (0.06, 0.06, 0.06))
    with SimWorld(SimConfig(layout=CellLayout(obstacles=(lamp,)))) as world:
        robot = make_robot("ur5", world.client, world.layout)
        ex = ArmExecutor(world, robot, grasp=None)
        down = gripper_down_quaternion(0.0)
        ends = [robot.solve_ik([0.42, y, 1.15], down, q_seed=robot.home_q) for y in (0.25, -0.25)]
        ex.check_postures({"one end": ends[0], "the other": ends[1]})
        with pytest.raises(
            UnreachableTargetError, match=r"would (touch|come within [\d.]+ mm of) obstacle 'lamp'"
        ):
            ex.check_joint_move(*ends, table=False)
    with SimWorld() as world:  # without it, the move is free
        robot = make_robot("ur5", world.client, world.layout)
        ArmExecutor(world, robot, grasp=None).check_joint_move(*ends, table=False)


def test_a_board_held_at_the_tool_is_kept_clear_of_the_layouts_obstacles_too():
    from foldbot.calibration.board import Chessboard
    from foldbot.calibration.views import BoardMount
    from foldbot.sim.calibration_board import board_twin
    from foldbot.sim.layout import CellLayout, Obstacle
    from foldbot.sim.robots.base import gripper_down_quaternion
    from foldbot.sim.world import SimConfig

    board, mount = Chessboard(), BoardMount()
    # Where the board's plate stands with the gripper down 50 cm over the workspace centre.
    with SimWorld() as world:
        robot = make_robot("ur5", world.client, world.layout)
        q = robot.solve_ik([0.45, 0.0, 1.25], gripper_down_quaternion(0.0), q_seed=robot.home_q)
        pos, quat = robot.fk_tcp(q)
    T_tcp = np.eye(4)
    T_tcp[:3, :3] = Rotation.from_quat(quat).as_matrix()
    T_tcp[:3, 3] = pos
    _x0, x1, _y0, y1 = board.plate_bounds()
    corner = (T_tcp @ mount.T_tcp_board() @ np.array([x1, y1, 0.0, 1.0]))[:3]
    # A small box just beyond the plate's far corner, out of the arm's own way.
    box = Obstacle("box", tuple(corner + 0.025 * (corner - pos) / np.linalg.norm(corner - pos)),
                   (0.02, 0.02, 0.02))  # fmt: skip
    with SimWorld(SimConfig(layout=CellLayout(obstacles=(box,)))) as world:
        robot = make_robot("ur5", world.client, world.layout)
        ex = ArmExecutor(world, robot, grasp=None)
        ex.check_table_clearance(q[None])  # the arm alone keeps clear of it
        ex.carry_body("the board", board_twin(world.client, board), mount.T_tcp_board())
        with pytest.raises(
            UnreachableTargetError,
            match=r"^waypoint 0: the board held at the tool would (touch|come within [\d.]+ mm "
            r"of) obstacle 'box' \(at least 20 mm needed\)",
        ):
            ex.check_table_clearance(q[None])
