"""Cloth segmentation from one RGB-D frame: height above a fitted table plane plus colour.

Method (each step is what makes it robust to one nuisance):
1. Fit the table plane to the depth image (RANSAC on a pixel subsample, normal within ~25° of world
   up, then least squares on table pixels only). Every pixel gets a height above the table (m).
2. Arm and gripper: anything higher than `occluder_height` above the table is an occluder, not
   cloth (a flat or folded towel lies within a few cm of the table). Occluders are left out of
   the depth smoothing so they do not bleed into their surroundings.
3. Depth cue: the height map is smoothed (normalised box filter, which also bridges depth
   dropouts) and thresholded against a noise-adaptive threshold: this finds the cloth whatever its
   colour, even on a table of the same colour (a flat cloth lies only ~2 mm above the table here).
4. Colour cue: the table's colour is the median Lab colour of table pixels, the cloth's the median
   of the depth-detected cloth. When they differ enough, each pixel is classified by its position
   along the table→cloth Lab axis (threshold halfway), gated by the depth cue so that shadows and
   texture on the table are not taken for cloth. Colour gives sharper edges than smoothed depth.
5. Clean-up: small specks are opened away, the largest component is kept and its holes (e.g. under
   the arm) are filled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from foldbot.errors import ConfigError
from foldbot.perception.geometry import (
    Plane,
    check_observation,
    fit_plane_lstsq,
    fit_plane_ransac,
    normalised_grid,
)
from foldbot.types import Observation


@dataclass(frozen=True)
class SegmentationConfig:
    """Thresholds of the cloth segmentation (metres, pixels, Lab units)."""

    ransac_stride: int = 12
    """Pixel stride of the subsample used for the RANSAC table-plane fit."""
    refit_stride: int = 6
    """Pixel stride of the subsample used to refit the plane on table pixels only."""
    plane_threshold: float = 0.006
    """RANSAC inlier distance (m) for the table plane."""
    ransac_iterations: int = 48
    """RANSAC hypotheses for the table plane."""
    low_res_factor: int = 4
    """Block size (px) of the averaged height/colour image used for the coarse decisions."""
    occluder_height: float = 0.06
    """Anything higher than this above the table (m) is arm/gripper, never cloth."""
    smooth_size: int = 7
    """Side (px) of the box filter smoothing the height map (odd)."""
    min_height: float = 0.0006
    """Lower bound (m) of the depth threshold; the actual one adapts to the measured noise."""
    noise_factor: float = 4.0
    """Depth threshold = max(min_height, noise_factor × smoothed-height noise σ)."""
    min_colour_separation: float = 30.0
    """RGB distance (0..255 units) between cloth and table from which the colour cue is used."""
    min_area: float = 0.003
    """Smallest cloth area (m², top view) reported as a detection."""

    def __post_init__(self) -> None:
        checks = {
            "ransac_stride": isinstance(self.ransac_stride, int) and 1 <= self.ransac_stride <= 64,
            "refit_stride": isinstance(self.refit_stride, int) and 1 <= self.refit_stride <= 64,
            "low_res_factor": isinstance(self.low_res_factor, int)
            and 1 <= self.low_res_factor <= 16,
            "plane_threshold": 0.0 < self.plane_threshold < 0.1,
            "ransac_iterations": isinstance(self.ransac_iterations, int)
            and 1 <= self.ransac_iterations <= 10000,
            "occluder_height": 0.0 < self.occluder_height < 1.0,
            "smooth_size": isinstance(self.smooth_size, int)
            and self.smooth_size % 2 == 1
            and 1 <= self.smooth_size <= 31,
            "min_height": 0.0 <= self.min_height < self.occluder_height,
            "noise_factor": 0.0 <= self.noise_factor < 100.0,
            "min_colour_separation": 0.0 < self.min_colour_separation < 400.0,
            "min_area": 0.0 <= self.min_area < 10.0,
        }
        for name, ok in checks.items():
            if not ok:
                raise ConfigError(
                    f"SegmentationConfig.{name} = {getattr(self, name)!r} is out of range"
                )


@dataclass(frozen=True)
class Segmentation:
    """Result of segmenting one frame; images are H×W, heights in metres above the table plane."""

    mask: np.ndarray
    """bool: the cloth (largest component, holes filled)."""
    height: np.ndarray
    """float32: height of each pixel above the table (m); NaN where depth is unknown."""
    occluder: np.ndarray
    """bool: arm/gripper or anything else above `occluder_height` (dilated by one pixel)."""
    plane_world: Plane
    """The fitted table plane in the world frame, normal pointing up."""
    plane_camera: Plane
    """The same plane in the camera frame."""
    cue: str
    """Which cue gave the mask edges: "colour", "depth" or "none"."""
    cloth_height: float
    """Median height of the cloth above the table (m); NaN when none found."""
    depth_threshold: float
    """Height threshold used by the depth cue (m)."""
    colour_separation: float
    """Lab distance between the cloth's and the table's median colours (NaN if unknown)."""

    @property
    def found(self) -> bool:
        """Whether any cloth pixel was found."""
        return bool(self.mask.any())


def largest_blob_filled(mask: np.ndarray) -> np.ndarray:
    """The largest 8-connected blob of `mask` with all its holes filled."""
    m = np.ascontiguousarray(mask, dtype=np.uint8)
    contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = np.zeros(m.shape, np.uint8)
    if contours:
        best = max(contours, key=cv2.contourArea)
        cv2.drawContours(out, [best], -1, 1, thickness=cv2.FILLED)
    return out.view(bool)


def _normalised_blur(values: np.ndarray, weight: np.ndarray, size: int) -> np.ndarray:
    """Weighted box-filter mean of `values` over size×size windows (NaN where weight is scarce)."""
    num = cv2.blur(values, (size, size), borderType=cv2.BORDER_REPLICATE)
    den = cv2.blur(weight, (size, size), borderType=cv2.BORDER_REPLICATE)
    out = num / np.maximum(den, np.float32(1e-6))
    out[den < 0.25] = np.nan
    return out


def _block_mean(values: np.ndarray, f: int) -> np.ndarray:
    """Means of f×f pixel blocks (the image cropped to a multiple of f)."""
    h, w = values.shape[:2]
    size = (w // f, h // f)
    return cv2.resize(values[: size[1] * f, : size[0] * f], size, interpolation=cv2.INTER_AREA)


def _robust_sigma(x: np.ndarray) -> float:
    """Standard deviation from the median absolute deviation (0 with < 10 finite values)."""
    x = x[np.isfinite(x)]
    if x.size < 10:
        return 0.0
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


@lru_cache(maxsize=8)
def _block_grid(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, f: int
) -> tuple[np.ndarray, np.ndarray]:
    """Normalised image coordinates of the f×f block centres (1×w, h×1)."""
    u = (np.arange(width // f, dtype=np.float32) * f + (f - 1) / 2.0 - cx) / fx
    v = (np.arange(height // f, dtype=np.float32) * f + (f - 1) / 2.0 - cy) / fy
    return u[None, :], v[:, None]


def _plane_gain(plane: Plane, xn: np.ndarray, yn: np.ndarray) -> np.ndarray:
    """g such that height = depth·g + offset at normalised image coordinates (xn, yn)."""
    n = plane.normal.astype(np.float32)
    return n[0] * xn + n[1] * yn + n[2]


def segment_cloth(obs: Observation, config: SegmentationConfig | None = None) -> Segmentation:
    """Segment the cloth lying on the table in `obs` (PerceptionError on malformed input)."""
    cfg = config or SegmentationConfig()
    K, T = check_observation(obs)
    depth = np.asarray(obs.depth, dtype=np.float32)
    h_img, w_img = depth.shape
    with np.errstate(invalid="ignore"):
        valid = depth > 0  # NaN compares False
    depth0 = np.where(valid, depth, np.float32(0.0))
    xn, yn = normalised_grid(K, w_img, h_img)
    f = cfg.low_res_factor
    xl, yl = _block_grid(w_img, h_img, K[0, 0], K[1, 1], K[0, 2], K[1, 2], f)
    up_cam = T[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    kernel = np.ones((3, 3), np.uint8)

    def sample(stride: int) -> tuple[np.ndarray, np.ndarray]:
        zs = depth0[::stride, ::stride]
        xs = np.broadcast_to(xn[:, ::stride], zs.shape)
        ys = np.broadcast_to(yn[::stride, :], zs.shape)
        return np.stack([xs * zs, ys * zs, zs], axis=-1).astype(np.float64), valid[
            ::stride, ::stride
        ]

    # 1. Table plane (camera frame): RANSAC on a coarse subsample.
    pts, vs = sample(cfg.ransac_stride)
    rng = np.random.default_rng(0)  # deterministic: same frame, same answer
    plane, _ = fit_plane_ransac(
        pts[vs], cfg.plane_threshold, rng, cfg.ransac_iterations, up=up_cam, max_tilt=0.45
    )
    h = depth0 * _plane_gain(plane, xn, yn) + np.float32(plane.offset)
    h[~valid] = np.nan

    # 2. Occluders, and block means of what is left (smoothing that ignores the arm and holes).
    with np.errstate(invalid="ignore"):
        occ = h > cfg.occluder_height
    weight = (valid & ~occ).astype(np.float32)
    wl = _block_mean(weight, f)
    inv_wl = 1.0 / np.maximum(wl, np.float32(1e-6))
    seen_l = wl >= 0.25
    hl = _block_mean(np.where(weight > 0, h, np.float32(0.0)), f) * inv_wl
    zl = _block_mean(depth0 * weight, f) * inv_wl
    hl[~seen_l] = np.nan
    occ_l = _block_mean(occ.view(np.uint8), f) > 0
    w3 = seen_l.astype(np.float32)

    def coarse(hl: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
        """Smoothed block heights, their noise-adaptive threshold and the rough cloth blocks."""
        hls = _normalised_blur(np.nan_to_num(hl, nan=0.0), w3, 3)
        with np.errstate(invalid="ignore"):
            sigma = _robust_sigma((hl - hls)[np.abs(hls) < cfg.plane_threshold])
            thr = max(cfg.min_height, cfg.noise_factor * sigma / 3.0)
            rough = ((hls > thr) & ~occ_l).view(np.uint8)
        return hls, thr, cv2.morphologyEx(rough, cv2.MORPH_OPEN, kernel)

    hls, thr, rough = coarse(hl)

    # 3. Refit the plane on table pixels only (the cloth would lift and tilt it a fraction of a mm),
    # then correct the heights: h changes by depth·Δg + Δoffset.
    near_cloth = cv2.dilate(rough, kernel, iterations=2)
    pts, vs = sample(cfg.refit_stride)
    ri = np.minimum(np.arange(0, h_img, cfg.refit_stride) // f, hl.shape[0] - 1)
    ci = np.minimum(np.arange(0, w_img, cfg.refit_stride) // f, hl.shape[1] - 1)
    table_sel = vs & (near_cloth[np.ix_(ri, ci)] == 0) & ~occ_l[np.ix_(ri, ci)]
    with np.errstate(invalid="ignore"):
        table_sel &= np.abs(h[:: cfg.refit_stride, :: cfg.refit_stride]) < cfg.plane_threshold
    if table_sel.sum() >= 30:
        refit = fit_plane_lstsq(pts[table_sel])
        if refit.normal @ up_cam < 0:
            refit = Plane(-refit.normal, -refit.offset)
        delta = Plane(refit.normal - plane.normal, refit.offset - plane.offset)
        h += depth0 * _plane_gain(delta, xn, yn) + np.float32(delta.offset)
        hl += zl * _plane_gain(delta, xl, yl) + np.float32(delta.offset)
        plane = refit
        hls, thr, rough = coarse(hl)

    core = cv2.erode(rough, kernel).view(bool)
    core_h = hls[core]
    if core_h.size >= 8:
        low_h, cloth_height = (float(v) for v in np.percentile(core_h, [10.0, 50.0]))
    else:
        cloth_height = low_h = float("nan")

    # 4. Colour cue, from block-averaged colours.
    rgb = obs.rgb
    rgb_l = _block_mean(rgb, f).astype(np.float32)
    with np.errstate(invalid="ignore"):
        table_l = (np.abs(hls) < thr / 2) & ~occ_l & (near_cloth == 0)
    table_rgb = np.median(rgb_l[table_l], axis=0) if table_l.sum() >= 8 else None
    cloth_rgb = None
    if core.sum() >= 8:
        cloth_rgb = np.median(rgb_l[core], axis=0)
    elif table_rgb is not None:
        # No depth evidence: the cloth is whatever differs strongly from the table's colour.
        far = (np.linalg.norm(rgb_l - table_rgb, axis=-1) > cfg.min_colour_separation) & ~occ_l
        if far.sum() >= 8:
            cloth_rgb = np.median(rgb_l[far], axis=0)
    separation = (
        float(np.linalg.norm(cloth_rgb - table_rgb))
        if cloth_rgb is not None and table_rgb is not None
        else float("nan")
    )

    occ_d = cv2.dilate(occ.view(np.uint8), kernel).view(bool)
    if math.isfinite(separation) and separation >= cfg.min_colour_separation:
        # Position along the table→cloth colour axis, 0 at the table, 1 at the cloth.
        # Computed on uint8 as 100·t + 100 (saturating), thresholded at t = 0.5.
        axis = 100.0 * (cloth_rgb - table_rgb) / separation**2
        m = np.array([[*axis, 100.0 - float(axis @ table_rgb)]], dtype=np.float32)
        t = cv2.transform(np.ascontiguousarray(rgb), m).reshape(h_img, w_img)
        mask = t > 150
        if math.isfinite(cloth_height):
            # Depth gate: colour edges are sharp, but shadows and stains are not raised.
            with np.errstate(invalid="ignore"):
                gate = (hls > min(thr, 0.35 * cloth_height)).view(np.uint8)
            gate = cv2.dilate(gate, kernel, iterations=2)
            full = np.zeros((h_img, w_img), np.uint8)
            full[: gate.shape[0] * f, : gate.shape[1] * f] = cv2.resize(
                gate, (gate.shape[1] * f, gate.shape[0] * f), interpolation=cv2.INTER_NEAREST
            )
            mask &= full.view(bool)
        cue = "colour"
    elif math.isfinite(cloth_height):
        k = cfg.smooth_size
        hs = _normalised_blur(np.where(weight > 0, h, np.float32(0.0)), weight, k)
        # Threshold halfway up the (lowest) cloth layer: an unbiased edge under the box blur;
        # never below the noise threshold scaled to this filter (σ ∝ 1/side of the window).
        level = max(thr * 3.0 * f / k, 0.5 * low_h)
        with np.errstate(invalid="ignore"):
            mask = hs > level
        cue = "depth"
    else:
        mask = np.zeros((h_img, w_img), bool)
        cue = "none"

    mask &= ~occ_d
    mask = cv2.morphologyEx(mask.view(np.uint8), cv2.MORPH_OPEN, kernel)
    # Filling after removing occluders: cloth hidden under the arm counts as cloth.
    mask = largest_blob_filled(mask) if mask.any() else mask.view(bool)
    if not mask.any():
        cue = "none"

    return Segmentation(
        mask=mask,
        height=h,
        occluder=occ_d,
        plane_world=plane.transformed(T),
        plane_camera=plane,
        cue=cue,
        cloth_height=cloth_height,
        depth_threshold=thr,
        colour_separation=separation,
    )
