"""Cloth segmentation from one RGB-D frame: height above a fitted table plane plus colour.

Method (each step is what makes it robust to one nuisance):
1. Depth work runs on 2×2 means of the valid depths (a quarter of the pixels; the final edges are
   interpolated back to full resolution). Fit the table plane (RANSAC on a subsample, normal
   within ~25° of world up, then least squares on table pixels only, so the cloth does not lift
   the plane). Every pixel gets a height above the table (m).
2. Arm and gripper: anything higher than `occluder_height` above the table is an occluder, not
   cloth (a flat or folded towel lies within a few cm of the table), and so is unknown depth
   joined to it (a depth sensor beside the colour camera does not see what lies just beside
   the arm). Occluders are left out of the depth smoothing so they do not bleed into their
   surroundings.
3. Depth cue: heights averaged over 4×4 blocks and smoothed give a rough cloth mask against a
   threshold set from the measured depth noise. This finds the cloth whatever its colour, even on
   a table of the same colour (a settled flat cloth lies only ~1–2 mm above the table here).
4. Colour cue: the table's colour is the median RGB of table blocks, the cloth's the median of the
   depth-detected cloth. When they differ enough, each pixel is classified by its position along
   the table→cloth colour axis (threshold halfway), gated by the depth cue so that shadows and
   stains on the table are not taken for cloth; colour gives pixel-sharp edges. Otherwise the
   edges come from the depth alone: a box-smoothed height map (the box grows with the noise),
   interpolated to full resolution and thresholded at half the cloth height, where a blurred
   straight edge stays in place.
5. Clean-up: specks are opened away; pieces of cloth the arm cuts apart are joined, holes are
   filled and the cloth hidden under the arm (inside their convex hull) is filled in — an amodal
   mask.

The cell's fixtures (`fixtures`: the layout's obstacles, a bin or a tray beside the workspace)
are occluders wherever the depth image sees a point inside one: a fixture lower than
`occluder_height` would otherwise pass for cloth lying on the table, and one as large as a towel
was taken for it (`foldbot eval-perception --layout layouts/cloth_tray.toml`). Their pixels are
also left out of the table-plane fit.

Measured on `foldbot eval-perception` scenes (640×480): see the command's summary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol

import cv2
import numpy as np

from foldbot.errors import ConfigError
from foldbot.perception.geometry import (
    Plane,
    check_observation,
    fit_plane_lstsq,
    fit_plane_ransac,
)
from foldbot.types import Observation


class Fixture(Protocol):
    """A fixed box of the cell that perception is told of (a layout's sim.layout.Obstacle is
    one): its corners and which world points (m) lie in it, each grown by `margin` (m)."""

    name: str

    def corners(self, margin: float = 0.0) -> np.ndarray: ...

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray: ...


@dataclass(frozen=True)
class SegmentationConfig:
    """Thresholds of the cloth segmentation (metres; sizes in half-resolution pixels)."""

    ransac_stride: int = 6
    """Stride (half-res px) of the subsample used for the RANSAC table-plane fit."""
    refit_stride: int = 3
    """Stride (half-res px) of the subsample used to refit the plane on table pixels only."""
    plane_threshold: float = 0.006
    """RANSAC inlier distance (m) for the table plane."""
    ransac_iterations: int = 48
    """RANSAC hypotheses for the table plane."""
    max_below_fraction: float = 0.02
    """A cloth that fills much of the view (a towel over ~50 cm) can outvote the table, and the
    plane found then runs through the cloth, tilted, with table below it. Where more than this
    share of the RANSAC sample lies clearly below the plane (past `plane_threshold` and four
    times the depth noise, short of `max_below`), the table plane is fitted again on those
    points."""
    max_below: float = 0.05
    """Depth below the first plane (m) past which a point is not table (the floor, a hole)."""
    block: int = 2
    """Block size (half-res px) of the averaged height/colour image for the coarse decisions."""
    occluder_height: float = 0.06
    """Anything higher than this above the table (m) is arm/gripper, never cloth."""
    occluder_shadow: int = 12
    """How far (half-res px) unknown depth joined to an occluder counts as hidden by it: a depth
    sensor beside the colour camera cannot see the cloth just beside the arm (its shadow, NaN
    once registered), which the colour camera sees; 12 covers the arm 35 cm over the cloth
    with a 5 cm baseline at 640 × 480."""
    smooth_size: int = 3
    """Smallest side (half-res px, odd) of the box filter smoothing heights for depth edges."""
    max_smooth_size: int = 11
    """Largest side (half-res px, odd) the box filter grows to when the depth is noisy."""
    min_height: float = 0.0004
    """Lower bound (m) of the depth thresholds; the actual ones adapt to the measured noise."""
    noise_factor: float = 4.0
    """Coarse cloth threshold = max(min_height, noise_factor × σ of the smoothed heights)."""
    edge_noise_factor: float = 3.0
    """Depth edges: the filter grows until edge_noise_factor × σ ≤ 45 % of the cloth height."""
    min_colour_separation: float = 30.0
    """RGB distance (0..255 units) between cloth and table from which the colour cue is used."""
    min_area: float = 0.003
    """Smallest cloth area (m², top view) reported as a detection."""
    fixtures: tuple[Fixture, ...] = ()
    """The cell's fixtures (its layout's obstacles, world frame): what the depth image sees
    inside one is an occluder, never cloth or table (the module's docstring)."""
    fixture_margin: float = 0.015
    """How far (m) around a fixture a seen point still counts as the fixture's: the depth's
    noise and the camera pose's error (a calibration's ~1 cm at the table)."""

    def __post_init__(self) -> None:
        def odd(v: object, hi: int) -> bool:
            return isinstance(v, int) and v % 2 == 1 and 1 <= v <= hi

        def integer(v: object, lo: int, hi: int) -> bool:
            return isinstance(v, int) and lo <= v <= hi

        checks = {
            "ransac_stride": integer(self.ransac_stride, 1, 64),
            "refit_stride": integer(self.refit_stride, 1, 64),
            "plane_threshold": 0.0 < self.plane_threshold < 0.1,
            "ransac_iterations": integer(self.ransac_iterations, 1, 10000),
            "max_below_fraction": 0.0 < self.max_below_fraction <= 1.0,
            "max_below": self.plane_threshold < self.max_below < 1.0,
            "block": integer(self.block, 1, 16),
            "occluder_height": 0.0 < self.occluder_height < 1.0,
            "occluder_shadow": integer(self.occluder_shadow, 0, 64),
            "smooth_size": odd(self.smooth_size, 31),
            "max_smooth_size": odd(self.max_smooth_size, 63)
            and self.max_smooth_size >= self.smooth_size,
            "min_height": 0.0 <= self.min_height < self.occluder_height,
            "noise_factor": 0.0 <= self.noise_factor < 100.0,
            "edge_noise_factor": 0.0 <= self.edge_noise_factor < 100.0,
            "min_colour_separation": 0.0 < self.min_colour_separation < 400.0,
            "min_area": 0.0 <= self.min_area < 10.0,
            "fixture_margin": isinstance(self.fixture_margin, int | float)
            and not isinstance(self.fixture_margin, bool)
            and 0.0 <= self.fixture_margin <= 0.2,
        }
        for name, ok in checks.items():
            if not ok:
                raise ConfigError(
                    f"SegmentationConfig.{name} = {getattr(self, name)!r} is out of range"
                )
        fixtures = self.fixtures
        if not isinstance(fixtures, tuple | list) or not all(
            callable(getattr(f, "corners", None)) and callable(getattr(f, "contains", None))
            for f in fixtures
        ):
            raise ConfigError(
                f"SegmentationConfig.fixtures must be a tuple of fixtures (a layout's obstacles, "
                f"sim.layout.Obstacle), got {fixtures!r}"
            )
        object.__setattr__(self, "fixtures", tuple(fixtures))


@dataclass(frozen=True)
class Segmentation:
    """Result of segmenting one frame; images are H×W, heights in metres above the table plane."""

    mask: np.ndarray
    """bool: the cloth, one region, including what the arm hides inside its outline."""
    height: np.ndarray
    """float32 (H/2)×(W/2): height above the table (m) of each 2×2 pixel block — pixel (u, v) is
    in block [v // 2, u // 2]; NaN where unknown or occluded."""
    occluder: np.ndarray
    """bool: arm/gripper or anything else above `occluder_height`, and the cell's fixtures
    (slightly dilated)."""
    plane_world: Plane
    """The fitted table plane in the world frame, normal pointing up."""
    plane_camera: Plane
    """The same plane in the camera frame."""
    cue: str
    """Which cue gave the mask edges: "colour", "depth" or "none"."""
    cloth_height: float
    """Median height of the cloth above the table (m); NaN when none found."""
    depth_threshold: float
    """Height threshold of the coarse depth cue (m)."""
    colour_separation: float
    """RGB distance between the cloth's and the table's median colours (NaN if unknown)."""
    fixture: np.ndarray | None = None
    """bool: the pixels that see one of the config's fixtures (in `occluder` too); None where
    it named none."""

    @property
    def found(self) -> bool:
        """Whether any cloth pixel was found."""
        return bool(self.mask.any())


def _median_height(contour: np.ndarray, mask: np.ndarray, height: np.ndarray) -> float:
    """Median height (m) of the mask pixels inside a contour's bounding box (2×2-block map)."""
    x, y, w, h = cv2.boundingRect(contour)
    hb = height[y // 2 : (y + h) // 2 + 1, x // 2 : (x + w) // 2 + 1]
    mb = mask[y : y + h : 2, x : x + w : 2][: hb.shape[0], : hb.shape[1]]
    vals = hb[: mb.shape[0], : mb.shape[1]][mb]
    vals = vals[np.isfinite(vals)]
    return float(np.median(vals)) if vals.size else float("nan")


def cloth_region(
    mask: np.ndarray, occluder: np.ndarray, height: np.ndarray | None = None
) -> np.ndarray:
    """The cloth as one region (an amodal mask): its largest blob, plus blobs the arm cuts off
    from it, plus the occluded pixels inside their convex hull, holes filled.

    A blob next to the arm joins when it is not tiny and, given the 2×2-block `height` map, lies
    about as high as the largest blob (low parts of the robot, e.g. its base, do not).
    """
    contours, _ = cv2.findContours(
        np.ascontiguousarray(mask, dtype=np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
    )
    out = np.zeros(mask.shape, np.uint8)
    if not contours:
        return out.view(bool)
    areas = np.array([cv2.contourArea(c) for c in contours])
    best = int(np.argmax(areas))
    keep = [contours[best]]
    if occluder.any():
        near = cv2.dilate(occluder.view(np.uint8), np.ones((5, 5), np.uint8))
        h_best = _median_height(contours[best], mask, height) if height is not None else 0.0
        for k, c in enumerate(contours):
            pts = c.reshape(-1, 2)
            if k == best or areas[k] < max(50.0, 0.01 * areas[best]):
                continue
            if not near[pts[:, 1], pts[:, 0]].any():
                continue
            if height is not None:
                h_k = _median_height(c, mask, height)
                if not abs(h_k - h_best) <= max(0.005, 0.5 * abs(h_best)):
                    continue
            keep.append(c)
    cv2.drawContours(out, keep, -1, 1, thickness=cv2.FILLED)
    if occluder.any():
        hull = np.zeros(mask.shape, np.uint8)
        cv2.fillConvexPoly(hull, cv2.convexHull(np.concatenate(keep)), 1)
        out |= occluder.view(np.uint8) & hull
    return out.view(bool)


def _with_shadow(occluder: np.ndarray, unknown: np.ndarray, reach: int) -> np.ndarray:
    """`occluder` grown into the `unknown` pixels joined to it, up to `reach` pixels away: what
    a depth sensor beside the colour camera cannot see past the arm is hidden by the arm (where
    the depth is the colour camera's own, no unknown pixels border the arm and nothing changes)."""
    if reach <= 0 or not occluder.any() or not unknown.any():
        return occluder
    kernel = np.ones((3, 3), np.uint8)
    free = unknown.view(np.uint8)
    grown = occluder.view(np.uint8)
    for _ in range(reach):
        step = cv2.dilate(grown, kernel) & (free | grown)
        if np.array_equal(step, grown):
            break
        grown = step
    return grown.view(bool)


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
    if f == 1:
        return values
    return cv2.resize(values[: size[1] * f, : size[0] * f], size, interpolation=cv2.INTER_AREA)


def _weighted_block_mean(
    values: np.ndarray, weight: np.ndarray, f: int
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted means of f×f blocks (NaN where under a quarter is weighted) and block weights.

    `values` must be finite (0 where the weight is 0)."""
    w = _block_mean(weight, f)
    out = _block_mean(values * weight, f)
    out /= np.maximum(w, np.float32(1e-6))
    out[w < 0.25] = np.nan
    return out, w


def _upsample(img: np.ndarray, shape: tuple[int, int], linear: bool, fill: float) -> np.ndarray:
    """An image of 2×2 blocks back to full size `shape` (odd last row/column filled)."""
    up = cv2.resize(
        img,
        (img.shape[1] * 2, img.shape[0] * 2),
        interpolation=cv2.INTER_LINEAR if linear else cv2.INTER_NEAREST,
    )
    if up.shape == shape:
        return up
    out = np.full(shape, fill, dtype=up.dtype)
    out[: up.shape[0], : up.shape[1]] = up
    return out


def _robust_sigma(x: np.ndarray) -> float:
    """Standard deviation from the median absolute deviation (0 with < 10 finite values)."""
    x = x[np.isfinite(x)][::2]  # every other value is plenty
    if x.size < 10:
        return 0.0
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


@lru_cache(maxsize=16)
def _block_grid(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, f: int
) -> tuple[np.ndarray, np.ndarray]:
    """Normalised image coordinates of the f×f block centres (1×w, h×1)."""
    u = (np.arange(width // f, dtype=np.float32) * f + (f - 1) / 2.0 - cx) / fx
    v = (np.arange(height // f, dtype=np.float32) * f + (f - 1) / 2.0 - cy) / fy
    return u[None, :], v[:, None]


def _lowest_plane(
    plane: Plane,
    pts: np.ndarray,
    valid: np.ndarray,
    cfg: SegmentationConfig,
    rng: np.random.Generator,
    up: np.ndarray,
) -> Plane:
    """The table is the lowest large surface in view: where more than `max_below_fraction` of
    the valid points of the RANSAC sample (`pts`, a grid of camera-frame points, and `valid`)
    lie clearly below `plane` (by more than `plane_threshold` and four times the depth noise,
    less than `max_below`), the plane ran through a cloth that fills much of the view, and the
    table is fitted again on those points (RANSAC as before); otherwise `plane` unchanged."""
    h = plane.height(pts)
    pairs = valid[:, 1:] & valid[:, :-1]
    noise = _robust_sigma(np.diff(h, axis=1)[pairs]) / math.sqrt(2.0)  # neighbours' difference
    hv = h[valid]
    below = (hv < -max(cfg.plane_threshold, 4.0 * noise)) & (hv > -cfg.max_below)
    if below.sum() < max(3, cfg.max_below_fraction * hv.size):
        return plane
    lower, _ = fit_plane_ransac(
        pts[valid][below], cfg.plane_threshold, rng, cfg.ransac_iterations, up=up, max_tilt=0.45
    )
    return lower


def _plane_gain(plane: Plane, xn: np.ndarray, yn: np.ndarray) -> np.ndarray:
    """g such that height = depth·g + offset at normalised image coordinates (xn, yn)."""
    n = plane.normal.astype(np.float32)
    return n[0] * xn + n[1] * yn + n[2]


def segment_cloth(obs: Observation, config: SegmentationConfig | None = None) -> Segmentation:
    """Segment the cloth lying on the table in `obs` (PerceptionError on malformed input)."""
    cfg = config or SegmentationConfig()
    K, T = check_observation(obs)
    h_img, w_img = obs.depth.shape
    depth = np.asarray(obs.depth, dtype=np.float32)
    up_cam = T[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    kernel = np.ones((3, 3), np.uint8)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]

    # 1. Half resolution: 2×2 means of the valid depths.
    depth0 = np.fmax(depth, np.float32(0.0))  # NaN and negative → 0 (unknown)
    z2, wz = _weighted_block_mean(depth0, (depth0 > 0).astype(np.float32), 2)
    valid2 = wz >= 0.25
    z2 = np.where(valid2, z2, np.float32(0.0))
    x2, y2 = _block_grid(w_img, h_img, fx, fy, cx, cy, 2)
    xl, yl = _block_grid(w_img, h_img, fx, fy, cx, cy, 2 * cfg.block)

    # The cell's fixtures: the blocks whose point lies in one (left out of the plane, occluders).
    fix2 = _fixture_blocks(z2, x2, y2, valid2, T, cfg) if cfg.fixtures else None
    surface2 = valid2 if fix2 is None else valid2 & ~fix2

    def sample(stride: int) -> tuple[np.ndarray, np.ndarray]:
        zs = z2[::stride, ::stride]
        xs = np.broadcast_to(x2[:, ::stride], zs.shape)
        ys = np.broadcast_to(y2[::stride, :], zs.shape)
        pts = np.stack([xs * zs, ys * zs, zs], axis=-1).astype(np.float64)
        return pts, surface2[::stride, ::stride]

    # Table plane (camera frame): RANSAC on a coarse subsample.
    pts, vs = sample(cfg.ransac_stride)
    rng = np.random.default_rng(0)  # deterministic: same frame, same answer
    plane, _ = fit_plane_ransac(
        pts[vs], cfg.plane_threshold, rng, cfg.ransac_iterations, up=up_cam, max_tilt=0.45
    )
    plane = _lowest_plane(plane, pts, vs, cfg, rng, up_cam)
    h2 = z2 * _plane_gain(plane, x2, y2) + np.float32(plane.offset)
    h2[~valid2] = 0.0  # heights are used with weight2, which is 0 there

    # 2. Occluders, and block means of what is left (smoothing that ignores the arm and holes).
    above2 = valid2 & (h2 > cfg.occluder_height)
    occ2 = _with_shadow(above2 if fix2 is None else above2 | fix2, ~valid2, cfg.occluder_shadow)
    weight2 = (valid2 & ~occ2).astype(np.float32)
    b = cfg.block
    hl, _ = _weighted_block_mean(h2, weight2, b)
    zl, _ = _weighted_block_mean(z2, weight2, b)
    occ_l = _block_mean(occ2.view(np.uint8), b) > 0 if b > 1 else occ2
    w3 = np.isfinite(hl).astype(np.float32)

    def coarse(hl: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, float]:
        """Smoothed block heights, their noise-adaptive threshold, the rough cloth blocks and
        the noise σ (m) of one block."""
        hls = _normalised_blur(np.nan_to_num(hl, nan=0.0), w3, 3)
        with np.errstate(invalid="ignore"):
            sigma = _robust_sigma((hl - hls)[np.abs(hls) < cfg.plane_threshold])
            thr = max(cfg.min_height, cfg.noise_factor * sigma / 3.0)
            rough = ((hls > thr) & ~occ_l).view(np.uint8)
        return hls, thr, cv2.morphologyEx(rough, cv2.MORPH_OPEN, kernel), sigma

    hls, thr, rough, sigma_l = coarse(hl)

    # 3. Refit the plane on table pixels only (the cloth would lift and tilt it a fraction of a mm),
    # then correct the heights: h changes by depth·Δg + Δoffset.
    near_cloth = cv2.dilate(rough, kernel, iterations=2)
    pts, vs = sample(cfg.refit_stride)
    ri = np.minimum(np.arange(0, h2.shape[0], cfg.refit_stride) // b, hl.shape[0] - 1)
    ci = np.minimum(np.arange(0, h2.shape[1], cfg.refit_stride) // b, hl.shape[1] - 1)
    table_sel = vs & (near_cloth[np.ix_(ri, ci)] == 0) & ~occ_l[np.ix_(ri, ci)]
    with np.errstate(invalid="ignore"):
        table_sel &= np.abs(h2[:: cfg.refit_stride, :: cfg.refit_stride]) < cfg.plane_threshold
    if table_sel.sum() >= 30:
        refit = fit_plane_lstsq(pts[table_sel])
        if refit.normal @ up_cam < 0:
            refit = Plane(-refit.normal, -refit.offset)
        delta = Plane(refit.normal - plane.normal, refit.offset - plane.offset)
        h2 += z2 * _plane_gain(delta, x2, y2) + np.float32(delta.offset)
        hl += zl * _plane_gain(delta, xl, yl) + np.float32(delta.offset)
        plane = refit
        hls, thr, rough, sigma_l = coarse(hl)

    core = cv2.erode(rough, kernel).view(bool)
    core_h = hls[core]
    if core_h.size >= 8:
        low_h, cloth_height = (float(v) for v in np.percentile(core_h, [10.0, 50.0]))
    else:
        cloth_height = low_h = float("nan")

    # 4. Colour cue, from the colours at the coarse blocks' centres.
    f = 2 * b  # full-res pixels per coarse block
    rgb = np.ascontiguousarray(obs.rgb)
    rgb_l = rgb[f // 2 :: f, f // 2 :: f].astype(np.float32)[: hl.shape[0], : hl.shape[1]]
    with np.errstate(invalid="ignore"):
        table_l = (np.abs(hls) < thr / 2) & ~occ_l & (near_cloth == 0)
    table_rgb = np.median(rgb_l[table_l][::4], axis=0) if table_l.sum() >= 32 else None
    cloth_rgb = None
    if core.sum() >= 8:
        cloth_rgb = np.median(rgb_l[core][::2], axis=0)
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

    shape = (h_img, w_img)
    occ = _upsample(cv2.dilate(occ2.view(np.uint8), kernel), shape, False, 0).view(bool)
    if math.isfinite(separation) and separation >= cfg.min_colour_separation:
        # Position t along the table→cloth colour axis (0 table, 1 cloth), computed on uint8 as
        # 100·t + 100 (saturating) and thresholded halfway.
        axis = 100.0 * (cloth_rgb - table_rgb) / separation**2
        m = np.array([[*axis, 100.0 - float(axis @ table_rgb)]], dtype=np.float32)
        mask = np.zeros(shape, bool)
        roi = (slice(0, h_img), slice(0, w_img))
        gate = None
        if math.isfinite(cloth_height):
            # Depth gate: colour edges are sharp, but shadows and stains are not raised. Only the
            # gate's bounding box needs classifying.
            with np.errstate(invalid="ignore"):
                gate_l = (hls > min(thr, 0.35 * cloth_height)).view(np.uint8)
            gate_l = cv2.dilate(gate_l, kernel, iterations=2)
            if gate_l.any():
                c0, r0, cw, rh = cv2.boundingRect(gate_l)
                roi = (slice(r0 * f, (r0 + rh) * f), slice(c0 * f, (c0 + cw) * f))
                gate = cv2.resize(
                    gate_l[r0 : r0 + rh, c0 : c0 + cw],
                    (cw * f, rh * f),
                    interpolation=cv2.INTER_NEAREST,
                ).view(bool)
        sub = rgb[roi]
        cls = cv2.transform(sub, m).reshape(sub.shape[:2]) > 150
        mask[roi] = cls & gate if gate is not None else cls
        cue = "colour"
    elif math.isfinite(cloth_height):
        # A half-res pixel's noise is σ_block·block; a k×k box divides it by k. Grow k until the
        # noise is well below half the cloth height, then threshold there, on the smoothed heights
        # interpolated to full resolution: a box blur leaves a straight edge's half-height
        # crossing in place (it only rounds the corners).
        sigma_px = sigma_l * b
        k = cfg.smooth_size
        while k < cfg.max_smooth_size and cfg.edge_noise_factor * sigma_px / k > 0.45 * low_h:
            k += 2
        hs = _upsample(_normalised_blur(h2, weight2, k), shape, True, 0)
        level = max(cfg.min_height, cfg.edge_noise_factor * sigma_px / k, 0.5 * low_h)
        with np.errstate(invalid="ignore"):
            mask = hs > level
        cue = "depth"
    else:
        mask = np.zeros(shape, bool)
        cue = "none"

    mask &= ~occ
    mask = cv2.morphologyEx(mask.view(np.uint8), cv2.MORPH_OPEN, kernel).view(bool)
    h2[weight2 == 0] = np.nan
    mask = cloth_region(mask, occ, h2) if mask.any() else mask
    if not mask.any():
        cue = "none"

    return Segmentation(
        mask=mask,
        height=h2,
        occluder=occ,
        plane_world=plane.transformed(T),
        plane_camera=plane,
        cue=cue,
        cloth_height=cloth_height,
        depth_threshold=thr,
        colour_separation=separation,
        fixture=None
        if fix2 is None
        else _upsample(fix2.view(np.uint8), shape, False, 0).view(bool),
    )


def _fixture_blocks(
    z2: np.ndarray,
    x2: np.ndarray,
    y2: np.ndarray,
    valid2: np.ndarray,
    T_world_camera: np.ndarray,
    cfg: SegmentationConfig,
) -> np.ndarray:
    """Bool per 2×2 block: its point (depth `z2` at normalised image coordinates `x2`, `y2`)
    lies in one of `cfg.fixtures`, grown by `cfg.fixture_margin` (world frame). Only the blocks
    inside a fixture's image (its corners' bounding box) are tested."""
    R, t = T_world_camera[:3, :3], T_world_camera[:3, 3]
    xs, ys = x2[0], y2[:, 0]  # ascending normalised coordinates of the block centres
    out = np.zeros(z2.shape, bool)
    for fixture in cfg.fixtures:
        corners = (fixture.corners(cfg.fixture_margin) - t) @ R  # camera frame
        if np.all(corners[:, 2] <= 1e-3):  # wholly behind the camera: out of its view
            continue
        rows, cols = slice(None), slice(None)
        if np.all(corners[:, 2] > 1e-3):  # wholly in front of the camera: its image's box
            u, v = corners[:, 0] / corners[:, 2], corners[:, 1] / corners[:, 2]
            c0, c1 = np.searchsorted(xs, [u.min(), u.max()])
            r0, r1 = np.searchsorted(ys, [v.min(), v.max()])
            cols = slice(max(int(c0) - 1, 0), int(c1) + 1)
            rows = slice(max(int(r0) - 1, 0), int(r1) + 1)
        z = z2[rows, cols]
        if z.size == 0:
            continue
        cam = np.stack([xs[cols] * z, ys[rows, None] * z, z], axis=-1)
        world = cam @ R.T.astype(np.float32) + t.astype(np.float32)
        out[rows, cols] |= fixture.contains(world, cfg.fixture_margin)
    return out & valid2
