"""The gripper's orientation along a planned path: a grasp taken with the tool tilted, and turns
from one orientation to another. Quaternions (x, y, z, w), world frame; the conventions are
sim.robots.base's ("gripper down": TCP z along −z world, at yaw 0 the fingers close along y)."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from foldbot.errors import require

GRIPPER_DOWN = np.array([0.0, 1.0, 0.0, 0.0])
"""Gripper down at yaw 0 (sim.robots.base.gripper_down_quaternion(0)): Ry(π)."""


def gripper_leaning_quaternion(tilt: float, heading: float) -> np.ndarray:
    """The TCP's orientation with the wrist leaning `tilt` (rad) from straight down towards the
    world heading `heading` (rad about z from +x; < 0 tilt leans the other way): the tool
    points down and back under the wrist, and the fingers close across the lean, horizontally,
    so both pads stay level as gripper down. This is R(tilt about the closing axis)·Rz(heading)·Ry(π),
    the closing axis being (−sin heading, cos heading, 0)."""
    require(math.isfinite(tilt), f"tilt must be finite, got {tilt!r}")
    require(math.isfinite(heading), f"heading must be finite, got {heading!r}")
    closing = np.array([-math.sin(heading), math.cos(heading), 0.0])
    down = Rotation.from_quat(
        [-math.sin(heading / 2), math.cos(heading / 2), 0.0, 0.0]
    )  # sim.robots.base.gripper_down_quaternion(heading)
    return (Rotation.from_rotvec(tilt * closing) * down).as_quat()


def slerp_quaternions(a: np.ndarray, b: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Orientations (N × 4) turned from `a` to `b` by each of `fractions` (0 to 1), the shorter
    way round at a steady rate (scipy's Slerp)."""
    turn = Slerp([0.0, 1.0], Rotation.from_quat([a, b]))
    return turn(np.clip(np.asarray(fractions, dtype=float).reshape(-1), 0.0, 1.0)).as_quat()
