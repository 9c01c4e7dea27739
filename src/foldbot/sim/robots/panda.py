"""Franka Emika Panda with the Franka Hand, from pybullet_data's ``franka_panda/panda.urdf``.

Joints 0–6 are the arm, 9 and 10 the fingers (prismatic, 0–0.04 m each, 0 = touching: the gap is
q_left + q_right, 0–80 mm), link 11 ``panda_grasptarget`` is the TCP, 0.105 m from the hand along
its z axis, between the fingertips (the pads end at 0.112 m). The hand's y axis is the closing
axis, z the approach axis, as for the UR5 gripper.

Reach: the Panda reaches less than the UR5; with the default layout (base at the table's near
edge) the central 0.4 m × 0.4 m of the cloth workspace is reachable gripper-down from 0.01 m to
0.25 m above the table, not the whole 0.6 m square.
"""

from __future__ import annotations

from pathlib import Path

import pybullet as p
import pybullet_data

from foldbot.sim.robots.base import Robot

URDF_PATH = Path(pybullet_data.getDataPath()) / "franka_panda" / "panda.urdf"


class Panda(Robot):
    """Franka Emika Panda arm (7 DOF) with the Franka Hand."""

    name = "panda"
    ARM_JOINT_NAMES = tuple(f"panda_joint{i}" for i in range(1, 8))
    FINGER_JOINT_NAMES = ("panda_finger_joint1", "panda_finger_joint2")
    FINGER_LINK_NAMES = ("panda_leftfinger", "panda_rightfinger")
    TCP_LINK_NAME = "panda_grasptarget"
    JAW_WIDTH = 0.02
    JAW_DEPTH = 0.05
    TIP_BELOW_TCP = 0.007
    # Franka's documented joint-space limits (FCI "Robot and interface specifications"); the
    # position limits are the URDF's soft (safety controller) limits, inside its hard limits.
    LOWER_LIMITS = (-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973)
    UPPER_LIMITS = (2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973)
    VELOCITY_LIMITS = (2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100)
    ACCELERATION_LIMITS = (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)
    JERK_LIMITS = (7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0)
    EFFORT_LIMITS = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
    HOME_SEED = (0.0, 0.0, 0.0, -2.2, 0.0, 2.2, 0.785398)
    CLOSED_GAP = 0.0
    FINGER_FORCE = 35.0
    """Per finger; the Franka Hand grasps with 70 N continuous."""
    FINGER_MAX_VELOCITY = 0.05
    """Per finger; the Franka Hand closes at up to 0.05 m/s per finger (0.1 m/s together)."""

    def _load(self, base_xyz: tuple[float, float, float]) -> int:
        # No URDF_USE_INERTIA_FROM_FILE: the file's inertias are placeholders (0.1 kg·m² on
        # every link, fingers included); PyBullet's inertias from the collision shapes are saner.
        return p.loadURDF(
            str(URDF_PATH),
            basePosition=base_xyz,
            baseOrientation=(0.0, 0.0, 0.0, 1.0),
            useFixedBase=True,
            physicsClientId=self.client,
        )
