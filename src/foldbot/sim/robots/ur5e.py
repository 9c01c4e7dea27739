"""Universal Robots UR5e (e-Series) with foldbot's parallel-jaw gripper (urdf/ur5e_gripper.urdf).

The UR5 (CB3) class's frames, joint names, gripper and TCP, on the UR5e's own DH lengths (d1 =
0.1625, a3 = −0.3922, d4 = 0.1333, d5 = 0.0997, d6 = 0.0996 m), link masses and joint speeds
(π rad/s on every joint, ur_description's ur5e): what plans and simulates the arm most labs now
have, whose ROS driver (ur_robot_driver) serves the same joint names and actions as the CB3's.
"""

from __future__ import annotations

import math
from pathlib import Path

from foldbot.sim.robots.ur5 import UR5


class UR5e(UR5):
    """UR5e arm (6 DOF) with the UR5's two-finger parallel gripper."""

    name = "ur5e"
    URDF = Path(__file__).resolve().parent / "urdf" / "ur5e_gripper.urdf"
    VELOCITY_LIMITS = (math.pi,) * 6
