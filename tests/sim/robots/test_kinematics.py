"""UR5 standard-DH forward kinematics (pure numpy)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from foldbot.sim.robots.kinematics import (
    DH_BASE_IN_BASE_LINK,
    UR5_A,
    UR5_ALPHA,
    UR5_D,
    dh_transform,
    quaternion_to_rotation,
    rotation_angle_between,
    rotation_to_quaternion,
    ur5_fk,
    ur5_fk_base_link,
    ur5_link_transforms,
)


def test_published_parameters() -> None:
    np.testing.assert_allclose(UR5_D, [0.089159, 0, 0, 0.10915, 0.09465, 0.0823])
    np.testing.assert_allclose(UR5_A, [0, -0.425, -0.39225, 0, 0, 0])
    np.testing.assert_allclose(UR5_ALPHA, [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0])


def test_zero_pose_stretches_along_minus_x_of_dh_base() -> None:
    t = ur5_fk(np.zeros(6))
    np.testing.assert_allclose(t[:3, 3], [-0.81725, -0.19145, 0.089159 - 0.09465], atol=1e-9)
    np.testing.assert_allclose(t[:3, :3], [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)


def test_base_link_is_dh_base_turned_by_pi() -> None:
    q = np.array([0.3, -1.2, 1.0, -0.4, 0.7, 2.0])
    t = ur5_fk_base_link(q)
    np.testing.assert_allclose(t, DH_BASE_IN_BASE_LINK @ ur5_fk(q))
    # Turning the DH base frame by π about z is the same as adding π to the pan joint.
    np.testing.assert_allclose(t, ur5_fk(q + np.array([np.pi, 0, 0, 0, 0, 0])), atol=1e-12)


def test_tool_down_pose() -> None:
    # The usual UR "home" with the tool pointing down: flange z along −z, at a known point.
    t = ur5_fk(np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0]))
    np.testing.assert_allclose(t[:3, 2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(t[:3, 3], [-0.48690, -0.10915, 0.089159 + 0.425 - 0.0823], atol=1e-5)


def test_chain_consistency_and_rigid_transforms() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, 6)
        frames = ur5_link_transforms(q)
        t = np.eye(4)
        for i in range(6):
            t = t @ dh_transform(q[i], UR5_D[i], UR5_A[i], UR5_ALPHA[i])
            np.testing.assert_allclose(frames[i], t, atol=1e-12)
            r = frames[i][:3, :3]
            np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
            assert np.linalg.det(r) == pytest.approx(1.0)
        # The wrist-1 → wrist-2 → wrist-3 offsets are d4, d5, d6 whatever the angles.
        assert np.linalg.norm(frames[5][:3, 3] - frames[4][:3, 3]) == pytest.approx(0.0823)
        assert np.linalg.norm(frames[4][:3, 3] - frames[3][:3, 3]) == pytest.approx(0.09465)
        assert np.linalg.norm(frames[3][:3, 3] - frames[2][:3, 3]) == pytest.approx(0.10915)


def test_quaternion_round_trip() -> None:
    rng = np.random.default_rng(4)
    for _ in range(50):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        r = quaternion_to_rotation(quat)
        back = rotation_to_quaternion(r)
        assert abs(abs(back @ quat) - 1.0) < 1e-12
        assert rotation_angle_between(r, quaternion_to_rotation(back)) < 1e-7


def test_rotation_angle_between() -> None:
    c, s = np.cos(0.3), np.sin(0.3)
    rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    assert rotation_angle_between(np.eye(3), rz) == pytest.approx(0.3)
    assert rotation_angle_between(np.eye(3), np.diag([-1.0, -1.0, 1.0])) == pytest.approx(np.pi)


def test_kinematics_does_not_import_pybullet() -> None:
    import foldbot.sim.robots.kinematics as kin

    # Run the module file alone in a fresh interpreter (the package __init__ loads PyBullet).
    code = (
        "import importlib.util, sys\n"
        f"spec = importlib.util.spec_from_file_location('kin', {kin.__file__!r})\n"
        "spec.loader.exec_module(importlib.util.module_from_spec(spec))\n"
        "assert 'pybullet' not in sys.modules, 'kinematics imported pybullet'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
