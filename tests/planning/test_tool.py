"""The gripper's orientation along a path (foldbot.planning.tool): the tilted grasp and turns."""

import math

import numpy as np
import pybullet as p
import pytest

from foldbot.errors import ConfigError
from foldbot.planning.tool import (
    GRIPPER_DOWN,
    gripper_leaning_quaternion,
    slerp_quaternions,
)
from foldbot.sim.robots.base import gripper_down_quaternion


def rotation(quat) -> np.ndarray:
    return np.array(p.getMatrixFromQuaternion(list(quat))).reshape(3, 3)


def test_gripper_down_is_the_robots_gripper_down():
    np.testing.assert_allclose(rotation(GRIPPER_DOWN), rotation(gripper_down_quaternion(0.0)))


def test_untilted_the_gripper_points_down_with_the_fingers_closing_along_x():
    np.testing.assert_allclose(
        rotation(gripper_leaning_quaternion(0.0, math.pi / 2)),
        rotation(gripper_down_quaternion(math.pi / 2)),
        atol=1e-12,
    )


@pytest.mark.parametrize("tilt", [0.35, -0.35, 0.6])
def test_a_tilt_leans_the_wrist_sideways_and_keeps_the_pads_level(tilt):
    r = rotation(gripper_leaning_quaternion(tilt, math.pi / 2))
    # The tool axis (TCP z) points down and towards −y at tilt > 0: the wrist above leans to +y.
    np.testing.assert_allclose(r[:, 2], [0.0, -math.sin(tilt), -math.cos(tilt)], atol=1e-12)
    # The fingers close along world x, level with each other.
    np.testing.assert_allclose(r[:, 1], [-1.0, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("heading", [0.0, 0.7, math.pi, -2.0])
@pytest.mark.parametrize("tilt", [0.35, -0.2])
def test_a_lean_tilts_the_wrist_towards_its_heading_and_keeps_the_pads_level(tilt, heading):
    r = rotation(gripper_leaning_quaternion(tilt, heading))
    toward = np.array([math.cos(heading), math.sin(heading), 0.0])
    # The tool axis points down and back under the wrist: the wrist leans towards `heading`.
    np.testing.assert_allclose(
        r[:, 2], -math.sin(tilt) * toward + [0.0, 0.0, -math.cos(tilt)], atol=1e-12
    )
    # The fingers close across the lean, horizontally.
    assert r[2, 1] == pytest.approx(0.0, abs=1e-12)
    assert float(r[:, 1] @ toward) == pytest.approx(0.0, abs=1e-12)


def test_upright_the_heading_only_turns_the_fingers_about_the_vertical():
    np.testing.assert_allclose(
        rotation(gripper_leaning_quaternion(0.0, 0.7)),
        rotation(gripper_down_quaternion(0.7)),
        atol=1e-12,
    )


def test_a_heading_must_be_finite():
    with pytest.raises(ConfigError, match="heading must be finite, got inf"):
        gripper_leaning_quaternion(0.3, float("inf"))


def test_a_tilt_must_be_finite():
    with pytest.raises(ConfigError, match="tilt must be finite, got nan"):
        gripper_leaning_quaternion(float("nan"), 0.0)


def test_a_turn_runs_from_one_orientation_to_the_other_at_a_steady_rate():
    a, b = GRIPPER_DOWN, gripper_leaning_quaternion(0.4, math.pi / 2)
    turn = slerp_quaternions(a, b, np.linspace(0.0, 1.0, 5))
    assert turn.shape == (5, 4)
    np.testing.assert_allclose(np.linalg.norm(turn, axis=1), 1.0)
    np.testing.assert_allclose(rotation(turn[0]), rotation(a), atol=1e-12)
    np.testing.assert_allclose(rotation(turn[-1]), rotation(b), atol=1e-12)

    def angle(q1, q2) -> float:
        return 2.0 * math.acos(min(1.0, abs(float(np.dot(q1, q2)))))

    steps = [angle(turn[i], turn[i + 1]) for i in range(4)]
    np.testing.assert_allclose(steps, angle(a, b) / 4, rtol=1e-9)
    # The shorter way round: -b is the same orientation as b.
    np.testing.assert_allclose(slerp_quaternions(a, -b, [0.5]), turn[2:3], atol=1e-12)
