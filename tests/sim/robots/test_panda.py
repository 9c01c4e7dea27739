"""Franka Panda (pybullet_data) behind the same Robot API, in PyBullet's deformable world."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pybullet as p
import pytest

from foldbot.errors import ConfigError, UnreachableTargetError
from foldbot.sim.layout import DEFAULT_LAYOUT
from foldbot.sim.robots import Panda, gripper_down_quaternion, make_robot
from foldbot.sim.robots.kinematics import rotation_angle_between

LAYOUT = DEFAULT_LAYOUT
PANDA_REACH_SIDE = 0.4
"""The Panda is tested on the central 0.4 m × 0.4 m of the 0.6 m workspace (shorter reach)."""


@pytest.fixture(scope="module")
def client() -> Iterator[int]:
    cid = p.connect(p.DIRECT)
    p.resetSimulation(p.RESET_USE_DEFORMABLE_WORLD, physicsClientId=cid)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    yield cid
    p.disconnect(cid)


@pytest.fixture(scope="module")
def loaded(client: int) -> Panda:
    robot = make_robot("panda", client, LAYOUT)
    assert isinstance(robot, Panda)
    return robot


@pytest.fixture()
def robot(loaded: Panda) -> Panda:
    """The module's Panda, back at home with the gripper open."""
    loaded.reset_joints(loaded.home_q)
    loaded.reset_gripper(loaded.max_opening)
    return loaded


def _rot(quat: np.ndarray) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(list(quat))).reshape(3, 3)


def _all_joint_states(robot: Panda) -> list[tuple[float, float]]:
    n = p.getNumJoints(robot.body_id, physicsClientId=robot.client)
    states = p.getJointStates(robot.body_id, list(range(n)), physicsClientId=robot.client)
    return [(s[0], s[1]) for s in states]


def _central_bounds() -> tuple[float, float, float, float]:
    cx, cy = LAYOUT.workspace_center_xy
    h = PANDA_REACH_SIDE / 2
    return cx - h, cx + h, cy - h, cy + h


def test_indices(robot: Panda) -> None:
    assert robot.name == "panda"
    assert robot.arm_joint_indices == (0, 1, 2, 3, 4, 5, 6)
    assert robot.finger_joint_indices == (9, 10)
    assert robot.finger_link_indices == (9, 10)
    assert robot.tcp_link_index == 11
    assert (
        p.getJointInfo(robot.body_id, 11, physicsClientId=robot.client)[12] == b"panda_grasptarget"
    )
    for link in robot.finger_link_indices:
        assert (
            p.getDynamicsInfo(robot.body_id, link, physicsClientId=robot.client)[0] > 0.0
        )  # fingers carry mass
    # getBasePositionAndOrientation reports the base's centre of mass (5 cm above link0's frame);
    # link0's URDF frame is at the mount point: joint 1 sits 0.333 m straight above it.
    _, orn = p.getBasePositionAndOrientation(robot.body_id, physicsClientId=robot.client)
    np.testing.assert_allclose(orn, [0, 0, 0, 1], atol=1e-9)
    link1 = p.getLinkState(
        robot.body_id, 0, computeForwardKinematics=True, physicsClientId=robot.client
    )[4]
    np.testing.assert_allclose(link1, np.add(LAYOUT.robot_base_xyz, [0, 0, 0.333]), atol=1e-6)


def test_limits_within_urdf(robot: Panda) -> None:
    for k, j in enumerate(robot.arm_joint_indices):
        info = p.getJointInfo(robot.body_id, j, physicsClientId=robot.client)
        assert info[8] <= robot.lower_limits[k] < robot.upper_limits[k] <= info[9]
        assert info[10] == pytest.approx(robot.effort_limits[k])
        assert info[11] == pytest.approx(robot.velocity_limits[k])
    assert robot.acceleration_limits.shape == robot.jerk_limits.shape == (7,)
    assert robot.max_opening == pytest.approx(0.08)


def test_tcp_is_between_the_fingertips(robot: Panda) -> None:
    tcp, orn = robot.tcp_pose()
    left, right = (
        np.asarray(p.getLinkState(robot.body_id, i, physicsClientId=robot.client)[4])
        for i in robot.finger_link_indices
    )
    r = _rot(orn)
    mid = (left + right) / 2
    # On the fingers' mid-plane, between them along the closing axis, 0.105 − 0.0584 m further out.
    assert abs((tcp - mid) @ r[:, 1]) < 1e-6
    assert (tcp - mid) @ r[:, 2] == pytest.approx(0.105 - 0.0584, abs=1e-6)


def test_home_pose(robot: Panda) -> None:
    pos, orn = robot.tcp_pose()
    cx, cy = LAYOUT.workspace_center_xy
    np.testing.assert_allclose(pos, [cx, cy, LAYOUT.table_height + 0.25], atol=1e-3)
    r = _rot(orn)
    np.testing.assert_allclose(r[:, 2], [0, 0, -1], atol=1e-3)
    np.testing.assert_allclose(r[:, 1], [0, 1, 0], atol=1e-3)


def test_fk_tcp_leaves_state_untouched(robot: Panda) -> None:
    before = _all_joint_states(robot)
    q = robot.home_q + 0.05
    pos, _ = robot.fk_tcp(q)
    assert _all_joint_states(robot) == before
    robot.reset_joints(q)
    np.testing.assert_allclose(robot.tcp_pose()[0], pos, atol=1e-9)


def test_ik_random_targets_and_state_preserved(robot: Panda) -> None:
    rng = np.random.default_rng(21)
    x0, x1, y0, y1 = _central_bounds()
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
def test_central_workspace_reachable_gripper_down(robot: Panda, height: float) -> None:
    x0, x1, y0, y1 = _central_bounds()
    for x in np.linspace(x0, x1, 7):
        for y in np.linspace(y0, y1, 7):
            target = [x, y, LAYOUT.table_height + height]
            q = robot.solve_ik(target, q_seed=robot.home_q)
            assert np.linalg.norm(robot.fk_tcp(q)[0] - target) <= 2e-3


def test_unreachable_target_raises(robot: Panda) -> None:
    before = _all_joint_states(robot)
    with pytest.raises(UnreachableTargetError) as err:
        robot.solve_ik([2.0, 0.0, 1.0])
    assert "[2.0, 0.0, 1.0]" in str(err.value)
    assert _all_joint_states(robot) == before
    with pytest.raises(ConfigError):
        robot.solve_ik([np.nan, 0.0, 1.0])


def test_position_control_tracks_in_deformable_world(robot: Panda) -> None:
    target = [0.55, -0.1, LAYOUT.table_height + 0.05]
    robot.command_joint_positions(robot.solve_ik(target))
    for _ in range(480):
        p.stepSimulation(physicsClientId=robot.client)
    assert np.linalg.norm(robot.tcp_pose()[0] - target) < 2e-3


def test_gripper_opens_and_closes_under_position_control(robot: Panda) -> None:
    assert robot.gripper_opening() == pytest.approx(0.08, abs=1e-4)
    robot.set_gripper_opening(0.0)
    for _ in range(5):
        p.stepSimulation(physicsClientId=robot.client)
    assert 0.01 < robot.gripper_opening() < 0.079
    for _ in range(360):
        p.stepSimulation(physicsClientId=robot.client)
    assert robot.gripper_opening() == pytest.approx(0.0, abs=5e-4)
    robot.set_gripper_opening(0.03)
    for _ in range(360):
        p.stepSimulation(physicsClientId=robot.client)
    assert robot.gripper_opening() == pytest.approx(0.03, abs=5e-4)
    with pytest.raises(ConfigError):
        robot.set_gripper_opening(0.081)
