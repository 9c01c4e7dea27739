"""VisionEstimator: Observation → ClothState from the RGB-D frame alone (no simulator access)."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from foldbot.errors import ConfigError
from foldbot.perception.geometry import pixel_rays, polygon_area
from foldbot.perception.keypoints import KeypointConfig, find_corners, label_corners
from foldbot.perception.segmentation import SegmentationConfig, segment_cloth
from foldbot.perception.state import NO_CLOTH, ClothState
from foldbot.types import Observation


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of the vision estimator."""

    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    """Cloth segmentation thresholds."""
    keypoints: KeypointConfig = field(default_factory=KeypointConfig)
    """Corner detector settings."""
    corner_height_radius_px: int = 10
    """Radius (px) around a corner whose cloth pixels give the corner's height above the table."""

    def __post_init__(self) -> None:
        if not (
            isinstance(self.corner_height_radius_px, int)
            and 1 <= self.corner_height_radius_px <= 100
        ):
            raise ConfigError(
                f"EstimatorConfig.corner_height_radius_px must be an integer in [1, 100], "
                f"got {self.corner_height_radius_px!r}"
            )


class VisionEstimator:
    """Estimate the cloth's mask, corners, coverage and flatness from one RGB-D Observation."""

    def __init__(self, config: EstimatorConfig | None = None) -> None:
        self.config = config or EstimatorConfig()

    def estimate(self, obs: Observation) -> ClothState:
        """ClothState of `obs`; detected=False (reason "no cloth detected") when there is none.

        Raises PerceptionError on malformed input (shapes, dtypes, empty images, bad K, no depth).
        """
        cfg = self.config
        seg = segment_cloth(obs, cfg.segmentation)
        pw = seg.plane_world
        plane = np.r_[pw.normal, pw.offset]
        shape = seg.mask.shape
        if not seg.found:
            return ClothState.not_detected(NO_CLOTH, shape, table_plane=plane, stamp=obs.stamp)

        corners = find_corners(seg.mask, exclude=seg.occluder, config=cfg.keypoints)
        if corners is None:
            return ClothState.not_detected(NO_CLOTH, shape, table_plane=plane, stamp=obs.stamp)

        # Heights of the visible cloth (the mask also covers cloth hidden under the arm), on
        # the 2×2-block height map.
        h2 = seg.height
        cloth2 = seg.mask[::2, ::2][: h2.shape[0], : h2.shape[1]]
        heights = h2[cloth2]
        heights = heights[np.isfinite(heights)]
        if heights.size == 0:
            return ClothState.not_detected(
                "cloth pixels have no depth", shape, table_plane=plane, stamp=obs.stamp
            )
        p5, h_med, p95 = (float(v) for v in np.percentile(heights, [5.0, 50.0, 95.0]))

        origin, dirs = pixel_rays(corners.contour, obs.intrinsics, obs.T_world_camera)
        outline = pw.intersect(origin, dirs, height=h_med)
        nz = abs(float(pw.normal[2])) or 1.0
        coverage = polygon_area(outline[:, :2]) / nz
        if coverage < cfg.segmentation.min_area:
            return ClothState.not_detected(NO_CLOTH, shape, table_plane=plane, stamp=obs.stamp)

        # Corner heights from the cloth blocks near each corner, away from the blurred edge.
        inner = cv2.erode(cloth2.view(np.uint8), np.ones((3, 3), np.uint8)).view(bool)
        r = max(1, cfg.corner_height_radius_px // 2)
        corner_h = np.full(4, h_med)
        for k, (u, v) in enumerate(corners.uv / 2.0):
            u0, u1 = max(0, int(u) - r), min(h2.shape[1], int(u) + r + 1)
            v0, v1 = max(0, int(v) - r), min(h2.shape[0], int(v) + r + 1)
            win = h2[v0:v1, u0:u1][inner[v0:v1, u0:u1]]
            win = win[np.isfinite(win)]
            if win.size >= 5:
                corner_h[k] = float(np.median(win))
        _, cdirs = pixel_rays(corners.uv, obs.intrinsics, obs.T_world_camera)
        xyz = np.array([pw.intersect(origin, cdirs[k], corner_h[k])[0] for k in range(4)])
        labels = label_corners(xyz)
        keypoints = {name: (xyz[i], float(corners.confidence[i])) for name, i in labels.items()}
        return ClothState(
            detected=True,
            reason=f"segmented by {seg.cue}",
            keypoints=keypoints,
            mask=seg.mask,
            coverage_m2=float(coverage),
            flatness=float(p95 - p5),
            outline_world=outline,
            table_plane=plane,
            stamp=float(obs.stamp),
        )
