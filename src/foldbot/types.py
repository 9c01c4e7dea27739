"""Typed values that flow between modules (see shared design): frozen dataclasses, SI units."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class CameraIntrinsics:
    """OpenCV pinhole intrinsics for an image of `width` × `height` pixels."""

    width: int
    height: int
    K: np.ndarray  # 3×3 [[fx,0,cx],[0,fy,cy],[0,0,1]]

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])


@dataclass(frozen=True)
class Observation:
    """What a real robot's sensors give: one RGB-D frame, its camera model and the joint states.

    `T_world_camera` maps points in the OpenCV camera frame (x right, y down, z forward) to the world.
    `depth` is float32 metres along the optical axis, 0 or NaN where unknown.
    """

    rgb: np.ndarray  # H×W×3 uint8
    depth: np.ndarray  # H×W float32, metres
    intrinsics: CameraIntrinsics
    T_world_camera: np.ndarray  # 4×4
    joint_positions: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stamp: float = 0.0  # simulated seconds


@dataclass(frozen=True)
class GraspResult:
    """Outcome of closing the gripper: which cloth vertices (if any) are now held."""

    success: bool
    vertex_ids: tuple[int, ...]
    reason: str = ""
