"""VisionEstimator: Observation → ClothState from the RGB-D frame alone (no simulator access)."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from foldbot.errors import ConfigError
from foldbot.perception.geometry import Plane, pixel_rays, polygon_area
from foldbot.perception.keypoints import KeypointConfig, find_corners, label_corners
from foldbot.perception.segmentation import Segmentation, SegmentationConfig, segment_cloth
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

        stats = visible_heights(seg)
        if stats is None:
            return ClothState.not_detected(
                "cloth pixels have no depth", shape, table_plane=plane, stamp=obs.stamp
            )
        p5, h_med, p95 = stats

        outline, coverage = lift_outline(obs, pw, corners.contour, h_med)
        if coverage < cfg.segmentation.min_area:
            return ClothState.not_detected(NO_CLOTH, shape, table_plane=plane, stamp=obs.stamp)

        # Corner heights from the cloth blocks near each corner, away from the blurred edge.
        corner_h = local_heights(seg, corners.uv, cfg.corner_height_radius_px, h_med)
        xyz = lift_pixels(obs, pw, corners.uv, corner_h)
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


def visible_heights(seg: Segmentation) -> tuple[float, float, float] | None:
    """5th, 50th and 95th percentile heights (m) of the visible cloth above the table; None when
    no cloth pixel has depth. (The mask also covers cloth hidden under the arm; the 2×2-block
    height map leaves those out.)"""
    h2 = seg.height
    cloth2 = seg.mask[::2, ::2][: h2.shape[0], : h2.shape[1]]
    heights = h2[cloth2]
    heights = heights[np.isfinite(heights)]
    if heights.size == 0:
        return None
    p5, h_med, p95 = (float(v) for v in np.percentile(heights, [5.0, 50.0, 95.0]))
    return p5, h_med, p95


def lift_outline(
    obs: Observation, plane_world: Plane, contour: np.ndarray, height: float
) -> tuple[np.ndarray, float]:
    """The image outline (N×2 px) on the table plane raised by `height` (N×3 world, m) and its
    top-view area (m²)."""
    origin, dirs = pixel_rays(contour, obs.intrinsics, obs.T_world_camera)
    outline = plane_world.intersect(origin, dirs, height=height)
    nz = abs(float(plane_world.normal[2])) or 1.0
    return outline, polygon_area(outline[:, :2]) / nz


def local_heights(seg: Segmentation, uv: np.ndarray, radius_px: int, default: float) -> np.ndarray:
    """Height (m) of the cloth near each pixel (K×2): the median over the cloth blocks within
    `radius_px`, away from the blurred edge; `default` where fewer than 5 blocks have depth."""
    h2 = seg.height
    cloth2 = seg.mask[::2, ::2][: h2.shape[0], : h2.shape[1]]
    inner = cv2.erode(cloth2.view(np.uint8), np.ones((3, 3), np.uint8)).view(bool)
    r = max(1, radius_px // 2)
    out = np.full(len(uv), default)
    for k, (u, v) in enumerate(np.asarray(uv, dtype=float).reshape(-1, 2) / 2.0):
        u0, u1 = max(0, int(u) - r), min(h2.shape[1], int(u) + r + 1)
        v0, v1 = max(0, int(v) - r), min(h2.shape[0], int(v) + r + 1)
        win = h2[v0:v1, u0:u1][inner[v0:v1, u0:u1]]
        win = win[np.isfinite(win)]
        if win.size >= 5:
            out[k] = float(np.median(win))
    return out


def lift_pixels(
    obs: Observation, plane_world: Plane, uv: np.ndarray, heights: np.ndarray
) -> np.ndarray:
    """World points (K×3, m) where the rays through pixels `uv` (K×2) meet the table plane raised
    by each one's height (K,)."""
    origin, dirs = pixel_rays(uv, obs.intrinsics, obs.T_world_camera)
    return np.array(
        [plane_world.intersect(origin, dirs[k], heights[k])[0] for k in range(len(dirs))]
    ).reshape(-1, 3)
