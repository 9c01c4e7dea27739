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


def _multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a·b of two (x, y, z, w) quaternions."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def gripper_tilted_quaternion(tilt: float) -> np.ndarray:
    """The TCP's orientation with the fingers closing along world x and the tool axis tilted
    `tilt` (rad) from straight down about world x: at tilt > 0 the tool points down and
    towards −y, so the wrist above it leans towards +y. Both pads stay level, as gripper down.
    This is Rx(−tilt)·Rz(π/2)·Ry(π)."""
    require(math.isfinite(tilt), f"tilt must be finite, got {tilt!r}")
    down_turned = np.array([-math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0])  # Rz(π/2)·Ry(π)
    rx = np.array([-math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)])
    return _multiply(rx, down_turned)


def slerp_quaternions(a: np.ndarray, b: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Orientations (N × 4) turned from `a` to `b` by each of `fractions` (0 to 1), the shorter
    way round at a steady rate (scipy's Slerp)."""
    turn = Slerp([0.0, 1.0], Rotation.from_quat([a, b]))
    return turn(np.clip(np.asarray(fractions, dtype=float).reshape(-1), 0.0, 1.0)).as_quat()
