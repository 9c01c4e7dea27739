"""A calibration.json written for tests, as `foldbot calibrate` writes one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from foldbot.sim.camera import CameraConfig


def write_calibration(
    path: Path,
    shift: tuple[float, float, float] = (0.004, -0.003, 0.0),
    truth: bool = True,
    intrinsics: bool = False,
    true_pose: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """A calibration.json as `foldbot calibrate` writes it, its pose `true_pose` (default: the
    default camera's) moved by `shift` (m); `truth`: with where the camera truly stood;
    `intrinsics`: solved at 320 × 240. Returns (true pose, pose found)."""
    true = CameraConfig().T_world_camera if true_pose is None else np.array(true_pose, float)
    found = true.copy()
    found[:3, 3] += np.asarray(shift)
    record = {
        "T_world_camera": found.tolist(),
        "parent_frame": "world",
        "child_frame": "camera_color_optical_frame",
    }
    if truth:
        record["truth"] = {"T_world_camera": true.tolist()}
    if intrinsics:
        K = CameraConfig(width=320, height=240).K
        record["camera_info"] = {"width": 320, "height": 240, "K": K.tolist()}
    path.write_text(json.dumps(record))
    return true, found
