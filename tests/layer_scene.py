"""A synthetic top-down RGB-D scene of cloth layers on a table, for the depth-layer tests: a camera
1 m above the table at z = 0 looks straight down; heights are given per world region."""

from __future__ import annotations

import numpy as np

from foldbot.perception.geometry import pixel_rays
from foldbot.types import CameraIntrinsics, Observation

W, H, F = 240, 200, 300.0
CAMERA_HEIGHT = 1.0
TABLE_PLANE = np.array([0.0, 0.0, 1.0, 0.0])
INTRINSICS = CameraIntrinsics(W, H, np.array([[F, 0, W / 2], [0, F, H / 2], [0, 0, 1.0]]))
T_WORLD_CAMERA = np.array(
    [[1.0, 0, 0, 0], [0, -1.0, 0, 0], [0, 0, -1.0, CAMERA_HEIGHT], [0, 0, 0, 1.0]]
)


def box(x0: float, x1: float, y0: float, y1: float, height: float):
    """A region of the given surface height (m) over the table: (bounds, height)."""
    return (x0, x1, y0, y1), height


def observe(*regions) -> Observation:
    """The frame of a surface made of `regions` (later ones on top) over a bare table."""
    v, u = np.mgrid[0:H, 0:W]
    _, rays = pixel_rays(np.c_[u.ravel(), v.ravel()], INTRINSICS, T_WORLD_CAMERA)
    xy = rays[:, :2] * CAMERA_HEIGHT  # where each ray meets the table (parallax is negligible)
    height = np.zeros(len(xy))
    for (x0, x1, y0, y1), h in regions:
        inside = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
        height[inside] = h
    depth = (CAMERA_HEIGHT - height).reshape(H, W).astype(np.float32)
    return Observation(
        rgb=np.zeros((H, W, 3), np.uint8),
        depth=depth,
        intrinsics=INTRINSICS,
        T_world_camera=T_WORLD_CAMERA,
    )
