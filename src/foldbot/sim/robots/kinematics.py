"""UR5 and UR5e forward kinematics from the published standard Denavit–Hartenberg parameters
(pure numpy).

Frames follow UR's own convention: ``ur5_fk`` is expressed in the DH base frame (the controller's
"base", ur_description's `base`); frame i is reached from frame i-1 by
``Rz(θ_i) · Tz(d_i) · Tx(a_i) · Rx(α_i)``; frame 6 is the tool flange (`tool0`). At θ = 0 the arm
stretches along −x of the DH base frame.

foldbot's UR5 URDF is rooted, like ur_description, at `base_link`, which is the DH base frame
turned by π about z (so at θ = 0 the arm stretches along +x of `base_link`, i.e. over the table):
``pose_in_base_link = DH_BASE_IN_BASE_LINK @ ur5_fk(q)`` (see ``ur5_fk_base_link``).
"""

from __future__ import annotations

import numpy as np

UR5_D = np.array([0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823])
"""DH offsets d_i along the previous z axis (m)."""
UR5_A = np.array([0.0, -0.425, -0.39225, 0.0, 0.0, 0.0])
"""DH lengths a_i along the new x axis (m)."""
UR5_ALPHA = np.array([np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0])
"""DH twists α_i about the new x axis (rad)."""
UR5E_D = np.array([0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996])
"""The UR5e's DH offsets d_i (m); its twists are the UR5's."""
UR5E_A = np.array([0.0, -0.425, -0.3922, 0.0, 0.0, 0.0])
"""The UR5e's DH lengths a_i (m)."""
UR_DH = {"ur5": (UR5_D, UR5_A), "ur5e": (UR5E_D, UR5E_A)}
"""Each Universal Robots model's (d, a) by registry name."""


DH_BASE_IN_BASE_LINK = np.diag([-1.0, -1.0, 1.0, 1.0])
"""Pose of the DH base frame in ur_description's `base_link`: a turn of π about z."""


def dh_transform(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    """4×4 homogeneous transform of one standard-DH joint: Rz(θ)·Tz(d)·Tx(a)·Rx(α)."""
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def ur5_link_transforms(q: np.ndarray, model: str = "ur5") -> list[np.ndarray]:
    """Poses of DH frames 1..6 in the DH base frame for joint angles `q` (6,), as 4×4 matrices,
    of the UR `model` ("ur5", "ur5e")."""
    q = np.asarray(q, dtype=float).reshape(6)
    d, a = UR_DH[model]
    frames = []
    t = np.eye(4)
    for i in range(6):
        t = t @ dh_transform(q[i], d[i], a[i], UR5_ALPHA[i])
        frames.append(t)
    return frames


def ur5_fk(q: np.ndarray, model: str = "ur5") -> np.ndarray:
    """4×4 pose of the UR tool flange (DH frame 6, `tool0`) in the DH base frame."""
    return ur5_link_transforms(q, model)[-1]


def ur5_fk_base_link(q: np.ndarray, model: str = "ur5") -> np.ndarray:
    """4×4 pose of the UR tool flange in `base_link` (the URDF root, the mounting frame)."""
    return DH_BASE_IN_BASE_LINK @ ur5_fk(q, model)


def pose_offset(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """How far apart two 4×4 poses are: the distance between their origins (m) and the angle
    of the rotation between them (rad)."""
    T_a, T_b = np.asarray(T_a, dtype=float), np.asarray(T_b, dtype=float)
    return (
        float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])),
        rotation_angle_between(T_a[:3, :3], T_b[:3, :3]),
    )


def rotation_to_quaternion(r: np.ndarray) -> np.ndarray:
    """Rotation matrix (3×3) to a unit quaternion in (x, y, z, w) order, w ≥ 0."""
    r = np.asarray(r, dtype=float)
    tr = np.trace(r)
    if tr > 0.0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s]
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = 2.0 * np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s]
    elif r[1, 1] > r[2, 2]:
        s = 2.0 * np.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s, (r[1, 0] - r[0, 1]) / s]
    quat = np.array(q)
    quat /= np.linalg.norm(quat)
    return -quat if quat[3] < 0 else quat


def quaternion_to_rotation(quat_xyzw: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) to a 3×3 rotation matrix."""
    x, y, z, w = np.asarray(quat_xyzw, dtype=float) / np.linalg.norm(quat_xyzw)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def rotation_angle_between(r_a: np.ndarray, r_b: np.ndarray) -> float:
    """Angle (rad) of the relative rotation r_aᵀ·r_b, robust near 0 and π."""
    r = np.asarray(r_a).T @ np.asarray(r_b)
    c = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    s = np.linalg.norm([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2.0
    return float(np.arctan2(s, c))
