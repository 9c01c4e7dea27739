"""ClothState: what perception (or the oracle) says about the cloth, and mask comparisons."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from foldbot.errors import PerceptionError
from foldbot.perception.geometry import project_points
from foldbot.types import CameraIntrinsics

NO_CLOTH = "no cloth detected"
"""`ClothState.reason` when the view holds no cloth."""


@dataclass(frozen=True)
class ClothState:
    """The cloth as estimated from one frame (world frame, metres).

    `keypoints` maps a corner label (see perception.keypoints.CORNER_LABELS) to
    (xyz world position (3,), confidence in [0, 1]). For a folded cloth the corners are those of
    its visible top-view outline. When `detected` is False the other fields are empty/zero and
    `reason` says why.
    """

    detected: bool
    reason: str = ""
    keypoints: dict[str, tuple[np.ndarray, float]] = field(default_factory=dict)
    mask: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))
    """H×W bool cloth mask in the estimated-from image; vision's includes cloth hidden under the
    arm (amodal), the oracle's is the segmentation buffer's visible cloth (empty without camera)."""
    coverage_m2: float = 0.0
    """Top-view area of the cloth (m²)."""
    flatness: float = 0.0
    """Spread of cloth heights above the table (m): 95th − 5th percentile."""
    outline_world: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """N×3 outline of the cloth in the world (on the table plane at cloth height)."""
    table_plane: np.ndarray = field(default_factory=lambda: np.zeros(4))
    """(a, b, c, d): table plane a·x + b·y + c·z + d = 0 in the world, (a, b, c) unit and up."""
    stamp: float = 0.0
    """Time of the observation (s)."""

    @classmethod
    def not_detected(
        cls, reason: str = NO_CLOTH, shape: tuple[int, int] = (0, 0), **kw
    ) -> ClothState:
        """A state that reports no cloth, with an all-False mask of `shape`."""
        return cls(detected=False, reason=reason, mask=np.zeros(shape, bool), **kw)

    def keypoint_array(self, labels: tuple[str, ...] | None = None) -> np.ndarray:
        """Keypoint positions as an N×3 array in `labels` order (default: dict order)."""
        names = labels if labels is not None else tuple(self.keypoints)
        return np.array([self.keypoints[n][0] for n in names], dtype=float).reshape(-1, 3)


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two bool masks of the same shape (1.0 when both are empty)."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    if a.shape != b.shape:
        raise PerceptionError(f"mask shapes differ: {a.shape} vs {b.shape}")
    union = np.logical_or(a, b).sum()
    if union == 0:
        return 1.0
    return float(np.logical_and(a, b).sum() / union)


def polygon_mask(
    polygon_world: np.ndarray, intrinsics: CameraIntrinsics, T_world_camera: np.ndarray
) -> np.ndarray:
    """Rasterise a world polygon (N×3, e.g. the outline a fold plan predicts) into an image mask."""
    pts = np.asarray(polygon_world, dtype=float).reshape(-1, 3)
    uv, z = project_points(pts, intrinsics, T_world_camera)
    out = np.zeros((intrinsics.height, intrinsics.width), np.uint8)
    if len(pts) >= 3 and np.all(z > 0):
        cv2.fillPoly(out, [np.round(uv * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    return out.astype(bool)


def fold_check_iou(
    mask: np.ndarray,
    predicted: np.ndarray,
    intrinsics: CameraIntrinsics | None = None,
    T_world_camera: np.ndarray | None = None,
) -> float:
    """IoU of an observed cloth mask with the shape a fold plan predicts.

    `predicted` is either an H×W bool mask or an N×3 world polygon (the predicted top-view outline),
    which is then rasterised with the observation's camera (`intrinsics`, `T_world_camera`).
    """
    pred = np.asarray(predicted)
    if pred.ndim == 2 and pred.shape[1] == 3 and pred.shape != np.shape(mask):
        if intrinsics is None or T_world_camera is None:
            raise PerceptionError("a predicted polygon needs intrinsics and T_world_camera")
        pred = polygon_mask(pred, intrinsics, T_world_camera)
    return mask_iou(mask, pred)
