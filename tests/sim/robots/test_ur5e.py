"""UR5e + the parallel gripper: its own URDF on its DH lengths, limits and masses, the cell's
home and park, the whole workspace reached, a pick closing on the table."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pybullet as p
import pytest

from foldbot.sim.layout import DEFAULT_LAYOUT
from foldbot.sim.robots import UR5, UR5e, make_robot, robot_class
from foldbot.sim.robots.kinematics import (
    UR5_ALPHA,
    UR5E_A,
    UR5E_D,
    rotation_angle_between,
    ur5_fk_base_link,
    ur5_link_transforms,
)
from foldbot.sim.robots.ur5 import FLANGE_TO_TCP

LAYOUT = DEFAULT_LAYOUT


@pytest.fixture(scope="module")
def client() -> Iterator[int]:
    cid = p.connect(p.DIRECT)
    p.resetSimulation(p.RESET_USE_DEFORMABLE_WORLD, physicsClientId=cid)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    yield cid
    p.disconnect(cid)


@pytest.fixture(scope="module")
def robot(client: int) -> UR5e:
    arm = make_robot("ur5e", client, LAYOUT)
    assert isinstance(arm, UR5e) and robot_class("ur5e") is UR5e
    return arm


def _rot(quat: np.ndarray) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(list(quat))).reshape(3, 3)


def test_published_dh_lengths() -> None:
    np.testing.assert_allclose(UR5E_D, [0.1625, 0, 0, 0.1333, 0.0997, 0.0996])
    np.testing.assert_allclose(UR5E_A, [0, -0.425, -0.3922, 0, 0, 0])
    frames = ur5_link_transforms(np.array([0.2, -1.0, 1.3, -0.5, 0.4, 1.1]), "ur5e")
    # The wrists are d4, d5, d6 apart whatever the angles: the UR5e's, not the UR5's.
    for i, d in ((3, 0.1333), (4, 0.0997), (5, 0.0996)):
        assert np.linalg.norm(frames[i][:3, 3] - frames[i - 1][:3, 3]) == pytest.approx(d)
    assert len(UR5_ALPHA) == 6


def test_its_own_urdf_on_its_dh_frames(robot: UR5e) -> None:
    assert robot.URDF.name == "ur5e_gripper.urdf" and robot.URDF != UR5.URDF
    robot.reset_joints(np.zeros(6))
    flange, _ = robot.flange_pose()
    assert flange[0] - LAYOUT.robot_base_xyz[0] == pytest.approx(0.425 + 0.3922, abs=1e-6)
    rng = np.random.default_rng(5)
    base = np.asarray(LAYOUT.robot_base_xyz)
    for _ in range(20):
        q = rng.uniform(robot.lower_limits, robot.upper_limits)
        robot.reset_joints(q)
        pos, orn = robot.flange_pose()
        t = ur5_fk_base_link(q, "ur5e")
        assert np.linalg.norm(pos - base - t[:3, 3]) <= 1e-6
        assert rotation_angle_between(_rot(orn), t[:3, :3]) <= 1e-6
        # Off by the UR5's lengths: the two models are told apart.
        assert np.linalg.norm(pos - base - ur5_fk_base_link(q)[:3, 3]) > 0.01
        tcp, _ = robot.tcp_pose()
        np.testing.assert_allclose(tcp, pos + FLANGE_TO_TCP * _rot(orn)[:, 2], atol=1e-6)


def test_limits_and_masses_are_the_ur5es(robot: UR5e) -> None:
    for k, j in enumerate(robot.arm_joint_indices):
        info = p.getJointInfo(robot.body_id, j, physicsClientId=robot.client)
        assert info[1].decode() == UR5.ARM_JOINT_NAMES[k]  # what ur_robot_driver publishes
        assert info[8] == pytest.approx(robot.lower_limits[k], abs=1e-12)
        assert info[9] == pytest.approx(robot.upper_limits[k], abs=1e-12)
        assert info[11] == pytest.approx(math.pi)
    np.testing.assert_allclose(robot.velocity_limits, [math.pi] * 6)
    masses = [
        p.getDynamicsInfo(robot.body_id, j, physicsClientId=robot.client)[0]
        for j in robot.arm_joint_indices
    ]
    np.testing.assert_allclose(masses, [3.761, 8.058, 2.846, 1.37, 1.3, 0.365])


def test_home_and_park_gripper_down(robot: UR5e) -> None:
    cx, cy = LAYOUT.workspace_center_xy
    pos, orn = robot.fk_tcp(robot.home_q)
    np.testing.assert_allclose(pos, [cx, cy, LAYOUT.table_height + 0.25], atol=1e-3)
    np.testing.assert_allclose(_rot(orn)[:, 2], [0, 0, -1], atol=1e-3)
    park = _rot(robot.fk_tcp(robot.out_of_view_q)[1])
    np.testing.assert_allclose(park[:, 2], [0, 0, -1], atol=1e-3)


@pytest.mark.parametrize("height", [0.01, 0.25])
def test_whole_workspace_reachable_gripper_down(robot: UR5e, height: float) -> None:
    x0, x1, y0, y1 = LAYOUT.workspace_bounds
    for x in np.linspace(x0, x1, 5):
        for y in np.linspace(y0, y1, 5):
            target = [x, y, LAYOUT.table_height + height]
            q = robot.solve_ik(target, q_seed=robot.home_q)
            pos, orn = robot.fk_tcp(q)
            assert np.linalg.norm(pos - target) < 1e-3
            assert np.dot(_rot(orn)[:, 2], [0, 0, -1]) > math.cos(math.radians(1))
