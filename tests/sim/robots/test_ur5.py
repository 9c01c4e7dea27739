"""UR5 + parallel gripper in PyBullet's deformable world: URDF vs DH, IK, reach, gripper."""

from __future__ import annotations

import importlib.util
import math
import sys
from collections.abc import Iterator
from types import ModuleType

import numpy as np
import pybullet as p
import pytest

from foldbot.errors import ConfigError, UnreachableTargetError
from foldbot.sim.layout import DEFAULT_LAYOUT
from foldbot.sim.robots import ROBOT_NAMES, UR5, gripper_down_quaternion, make_robot
from foldbot.sim.robots.kinematics import rotation_angle_between, ur5_fk_base_link
from foldbot.sim.robots.ur5 import FLANGE_TO_TCP, URDF_PATH

LAYOUT = DEFAULT_LAYOUT


@pytest.fixture(scope="module")
def client() -> Iterator[int]:
    cid = p.connect(p.DIRECT)
    p.resetSimulation(p.RESET_USE_DEFORMABLE_WORLD, physicsClientId=cid)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    yield cid
    p.disconnect(cid)


@pytest.fixture(scope="module")
def loaded(client: int) -> UR5:
    robot = make_robot("ur5", client, LAYOUT)
    assert isinstance(robot, UR5)
    return robot


@pytest.fixture()
def robot(loaded: UR5) -> UR5:
    """The module's UR5, back at home with the gripper open."""
    loaded.reset_joints(loaded.home_q)
    loaded.reset_gripper(loaded.max_opening)
    return loaded


def _rot(quat: np.ndarray) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(list(quat))).reshape(3, 3)


def _all_joint_states(robot: UR5) -> list[tuple[float, float]]:
    n = p.getNumJoints(robot.body_id, physicsClientId=robot.client)
    states = p.getJointStates(robot.body_id, list(range(n)), physicsClientId=robot.client)
    return [(s[0], s[1]) for s in states]


def test_make_robot_rejects_unknown_name(client: int) -> None:
    with pytest.raises(ConfigError) as err:
        make_robot("kuka", client, LAYOUT)
    msg = str(err.value)
    assert "'kuka'" in msg
    for name in ROBOT_NAMES:
        assert name in msg
    assert ROBOT_NAMES == ("ur5", "ur5e", "panda")


def test_indices_and_mounting(robot: UR5) -> None:
    assert robot.name == "ur5"
    assert len(robot.arm_joint_indices) == 6
    for j in robot.arm_joint_indices:
        assert p.getJointInfo(robot.body_id, j, physicsClientId=robot.client)[2] == p.JOINT_REVOLUTE
    for j in robot.finger_joint_indices:
        assert (
            p.getJointInfo(robot.body_id, j, physicsClientId=robot.client)[2] == p.JOINT_PRISMATIC
        )
    assert (
        p.getJointInfo(robot.body_id, robot.tcp_link_index, physicsClientId=robot.client)[12]
        == b"tcp"
    )
    pos, orn = p.getBasePositionAndOrientation(robot.body_id, physicsClientId=robot.client)
    np.testing.assert_allclose(pos, LAYOUT.robot_base_xyz, atol=1e-9)
    np.testing.assert_allclose(orn, [0, 0, 0, 1], atol=1e-9)
    # Base x towards the table: at q = 0 the arm stretches along +x world.
    robot.reset_joints(np.zeros(6))
    flange, _ = robot.flange_pose()
    assert flange[0] - LAYOUT.robot_base_xyz[0] == pytest.approx(0.81725, abs=1e-6)


def test_urdf_limits_equal_constants(robot: UR5) -> None:
    for k, j in enumerate(robot.arm_joint_indices):
        info = p.getJointInfo(robot.body_id, j, physicsClientId=robot.client)
        assert info[8] == pytest.approx(robot.lower_limits[k], abs=1e-12)
        assert info[9] == pytest.approx(robot.upper_limits[k], abs=1e-12)
        assert info[10] == pytest.approx(robot.effort_limits[k])
        assert info[11] == pytest.approx(robot.velocity_limits[k])
    np.testing.assert_allclose(
        robot.lower_limits, [-2 * math.pi] * 2 + [-math.pi] + [-2 * math.pi] * 3
    )
    np.testing.assert_allclose(robot.velocity_limits, [3.15] * 6)
    np.testing.assert_allclose(robot.effort_limits, [150, 150, 150, 28, 28, 28])
    assert robot.acceleration_limits.shape == robot.jerk_limits.shape == (6,)
    for j in robot.finger_joint_indices:
        info = p.getJointInfo(robot.body_id, j, physicsClientId=robot.client)
        assert (info[8], info[9]) == (0.0, pytest.approx(0.039))


def test_link_masses_match_ur_description(robot: UR5) -> None:
    masses = [
        p.getDynamicsInfo(robot.body_id, j, physicsClientId=robot.client)[0]
        for j in robot.arm_joint_indices
    ]
    np.testing.assert_allclose(masses, [3.7, 8.393, 2.275, 1.219, 1.219, 0.1879])
    for link in robot.finger_link_indices:
        mass, friction = p.getDynamicsInfo(robot.body_id, link, physicsClientId=robot.client)[:2]
        assert mass == pytest.approx(0.05)
        assert friction >= 1.0


def test_urdf_flange_matches_dh_fk(robot: UR5) -> None:
    rng = np.random.default_rng(11)
    base = np.asarray(LAYOUT.robot_base_xyz)
    for _ in range(20):
        q = rng.uniform(robot.lower_limits, robot.upper_limits)
        robot.reset_joints(q)
        pos, orn = robot.flange_pose()
        t = ur5_fk_base_link(q)  # base_link has identity orientation in the world
        assert np.linalg.norm(pos - base - t[:3, 3]) <= 1e-3
        assert rotation_angle_between(_rot(orn), t[:3, :3]) <= 1e-3
        # The TCP is FLANGE_TO_TCP along the flange z axis, with the flange's axes.
        tcp, tcp_orn = robot.tcp_pose()
        np.testing.assert_allclose(tcp, pos + FLANGE_TO_TCP * _rot(orn)[:, 2], atol=1e-6)
        assert rotation_angle_between(_rot(tcp_orn), _rot(orn)) < 1e-6


def test_home_pose(robot: UR5) -> None:
    pos, orn = robot.tcp_pose()
    cx, cy = LAYOUT.workspace_center_xy
    np.testing.assert_allclose(pos, [cx, cy, LAYOUT.table_height + 0.25], atol=1e-3)
    r = _rot(orn)
    np.testing.assert_allclose(r[:, 2], [0, 0, -1], atol=1e-3)  # approach: down
    np.testing.assert_allclose(r[:, 1], [0, 1, 0], atol=1e-3)  # fingers close along world y
    assert not robot.home_q.flags.writeable


def test_gripper_down_quaternion_axes() -> None:
    for yaw in (0.0, 0.7, -1.2):
        r = _rot(gripper_down_quaternion(yaw))
        np.testing.assert_allclose(r[:, 2], [0, 0, -1], atol=1e-12)
        np.testing.assert_allclose(r[:, 1], [-math.sin(yaw), math.cos(yaw), 0], atol=1e-12)


def test_fk_tcp_leaves_state_untouched(robot: UR5) -> None:
    before = _all_joint_states(robot)
    q = robot.home_q + 0.2
    pos, _ = robot.fk_tcp(q)
    assert _all_joint_states(robot) == before
    robot.reset_joints(q)
    np.testing.assert_allclose(robot.tcp_pose()[0], pos, atol=1e-9)


def test_ik_random_targets_and_state_preserved(robot: UR5) -> None:
    rng = np.random.default_rng(12)
    x0, x1, y0, y1 = LAYOUT.workspace_bounds
    # Leave the arm moving somewhere: IK must not touch positions or velocities.
    robot.command_joint_positions(robot.home_q + 0.1)
    for _ in range(5):
        p.stepSimulation(physicsClientId=robot.client)
    for _ in range(20):
        target = [
            rng.uniform(x0, x1),
            rng.uniform(y0, y1),
            LAYOUT.table_height + rng.uniform(0.01, 0.3),
        ]
        quat = gripper_down_quaternion(rng.uniform(-math.pi / 4, math.pi / 4))
        before = _all_joint_states(robot)
        q = robot.solve_ik(target, quat)
        assert _all_joint_states(robot) == before
        assert np.all(q >= robot.lower_limits) and np.all(q <= robot.upper_limits)
        pos, orn = robot.fk_tcp(q)
        assert np.linalg.norm(pos - target) <= 2e-3
        assert rotation_angle_between(_rot(orn), _rot(quat)) <= 1e-2


@pytest.mark.parametrize("height", [0.01, 0.25])
def test_whole_workspace_reachable_gripper_down(robot: UR5, height: float) -> None:
    x0, x1, y0, y1 = LAYOUT.workspace_bounds
    assert x1 - x0 == pytest.approx(0.6) and y1 - y0 == pytest.approx(0.6)
    for x in np.linspace(x0, x1, 7):
        for y in np.linspace(y0, y1, 7):
            target = [x, y, LAYOUT.table_height + height]
            q = robot.solve_ik(target, q_seed=robot.home_q)
            assert np.linalg.norm(robot.fk_tcp(q)[0] - target) <= 2e-3


def test_unreachable_target_raises(robot: UR5) -> None:
    before = _all_joint_states(robot)
    target = [2.0, 0.0, 1.0]
    with pytest.raises(UnreachableTargetError) as err:
        robot.solve_ik(target)
    assert "[2.0, 0.0, 1.0]" in str(err.value)
    assert "mm" in str(err.value)
    assert _all_joint_states(robot) == before


@pytest.mark.parametrize("bad", [[np.nan, 0.0, 1.0], [0.4, np.inf, 1.0], [0.4, 0.0]])
def test_ik_rejects_bad_targets(robot: UR5, bad: list[float]) -> None:
    with pytest.raises(ConfigError):
        robot.solve_ik(bad)
    with pytest.raises(ConfigError):
        robot.solve_ik([0.45, 0.0, 1.0], orientation_xyzw=[0.0, np.nan, 0.0, 1.0])


def test_position_control_tracks_in_deformable_world(robot: UR5) -> None:
    target = [0.6, 0.2, LAYOUT.table_height + 0.05]
    q = robot.solve_ik(target)
    robot.command_joint_positions(q)
    peak = 0.0
    for _ in range(480):
        p.stepSimulation(physicsClientId=robot.client)
        peak = max(peak, float(np.max(np.abs(robot.joint_velocities()) / robot.velocity_limits)))
    assert np.linalg.norm(robot.tcp_pose()[0] - target) < 2e-3
    assert peak <= 1.01  # maxVelocity respected
    with pytest.raises(ConfigError):
        robot.command_joint_positions(robot.upper_limits + 0.1)


def test_gripper_opens_and_closes_under_position_control(robot: UR5) -> None:
    assert robot.max_opening == pytest.approx(0.08)
    assert robot.gripper_opening() == pytest.approx(0.08, abs=1e-4)
    robot.set_gripper_opening(0.0)
    for _ in range(5):
        p.stepSimulation(physicsClientId=robot.client)
    assert 0.01 < robot.gripper_opening() < 0.079  # moving, speed-limited
    for _ in range(240):
        p.stepSimulation(physicsClientId=robot.client)
    assert robot.gripper_opening() == pytest.approx(0.002, abs=2e-4)  # 2 mm closed gap
    robot.set_gripper_opening(0.05)
    for _ in range(240):
        p.stepSimulation(physicsClientId=robot.client)
    assert robot.gripper_opening() == pytest.approx(0.05, abs=5e-4)
    # The measured gap really is the distance between the finger inner faces along TCP y.
    left, right = (
        p.getLinkState(robot.body_id, i, physicsClientId=robot.client)[4]
        for i in robot.finger_link_indices
    )
    y = _rot(robot.tcp_pose()[1])[:, 1]
    assert (np.asarray(left) - right) @ y == pytest.approx(robot.gripper_opening())
    for bad in (-0.001, 0.09, float("nan")):
        with pytest.raises(ConfigError):
            robot.set_gripper_opening(bad)


def load_urdf_generator() -> ModuleType:
    """urdf/make_ur_urdf.py, the script that writes the shipped UR URDFs, as a module."""
    name = "foldbot_make_ur_urdf"
    spec = importlib.util.spec_from_file_location(name, URDF_PATH.with_name("make_ur_urdf.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


def test_shipped_urdfs_match_their_generator() -> None:
    module = load_urdf_generator()
    assert [m.name for m in module.MODELS] == ["ur5", "ur5e"]
    for model in module.MODELS:
        path = module.urdf_path(model)
        assert path.read_text() == module.build(model), "rerun urdf/make_ur_urdf.py"
    assert module.urdf_path(module.UR5) == URDF_PATH


def test_nearest_within_finds_a_body_by_the_tcp_and_only_when_close(robot: UR5) -> None:
    """A small ball 3 cm under the TCP (jaws open) is nearest a finger, over 3 cm away: found within
    6 cm, not within 3 cm, and not at all among the shoulder and upper-arm links."""
    tcp, _ = robot.tcp_pose()
    shape = p.createCollisionShape(p.GEOM_SPHERE, radius=0.002, physicsClientId=robot.client)
    ball = p.createMultiBody(
        0, shape, basePosition=(tcp + [0, 0, -0.03]).tolist(), physicsClientId=robot.client
    )
    try:
        hit = robot.nearest_within(ball, 0.06)
        assert hit is not None
        link, other, dist = hit
        assert link in robot.finger_link_indices and other == -1
        assert 0.03 < dist < 0.06
        assert robot.nearest_within(ball, 0.03) is None
        assert robot.nearest_within(ball, 0.06, links=robot.arm_joint_indices[:3]) is None
    finally:
        p.removeBody(ball, physicsClientId=robot.client)
