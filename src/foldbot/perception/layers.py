"""Where a fold left its top layer short, seen in depth: the part of the region a stage should have
covered with a new layer that still shows the surface it had before the stage.

A fixed camera sees the same pixels before and after a fold, so a pixel's rise in height is the
cloth laid on it. Where the laid layer sprang back, bunched or dog-eared, the region it should cover
shows no rise: that gap is what the outline cannot show (the layer beneath keeps the outline).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from foldbot.errors import PerceptionError
from foldbot.perception.geometry import (
    backproject,
    backproject_pixel,
    project_points,
    robust_depth,
)
from foldbot.perception.keypoints import max_area_quad
from foldbot.perception.state import polygon_mask
from foldbot.types import Observation

MAX_CLOTH_HEIGHT = 0.1
"""Surfaces higher than this above the table (m) are not cloth (e.g. the parked arm)."""


def height_map(obs: Observation, table_plane: np.ndarray) -> np.ndarray:
    """Height (m) above the table plane (a, b, c, d) of the surface each pixel sees; NaN where the
    pixel has no depth."""
    plane = np.asarray(table_plane, dtype=float).reshape(-1)
    if plane.shape != (4,) or not np.all(np.isfinite(plane)) or plane[2] < 0.5:
        raise PerceptionError(
            f"table plane must be (a, b, c, d) with an upward unit normal, got {plane.tolist()}"
        )
    h, w = obs.depth.shape
    v, u = np.mgrid[0:h, 0:w]
    z = obs.depth.astype(float).reshape(-1)
    valid = np.isfinite(z) & (z > 0)
    pts = backproject(
        np.c_[u.reshape(-1), v.reshape(-1)],
        np.where(valid, z, 1.0),
        obs.intrinsics,
        obs.T_world_camera,
    )
    height = pts @ plane[:3] + plane[3]
    return np.where(valid, height, np.nan).reshape(h, w)


def surface_rise(
    before: Observation, before_plane: np.ndarray, after: Observation, after_plane: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """How much each pixel's surface rose from `before` to `after` (m, H×W; 0 where not seen), and
    where it was seen in both frames as cloth or table (finite, under MAX_CLOTH_HEIGHT)."""
    if before.depth.shape != after.depth.shape:
        raise PerceptionError(
            f"frames differ in size: {before.depth.shape} before, {after.depth.shape} after"
        )
    h0 = height_map(before, before_plane)
    h1 = height_map(after, after_plane)
    seen = np.isfinite(h0) & np.isfinite(h1) & (h0 < MAX_CLOTH_HEIGHT) & (h1 < MAX_CLOTH_HEIGHT)
    return np.where(seen, h1 - h0, 0.0), seen


@dataclass(frozen=True)
class LayerCover:
    """How a stage's new layer lies over the region it should cover (image masks, H×W bool)."""

    layer_rise: float
    """Median rise of the region's surface over the stage (m): one laid layer's height."""
    covered: np.ndarray
    """Pixels of the region the laid layer covers."""
    exposed: np.ndarray
    """Pixels of the region it leaves uncovered."""


@dataclass(frozen=True)
class CoverGap:
    """The deepest spot a stage's new layer should cover and does not (world frame, m)."""

    deepest: np.ndarray
    """(3,) the uncovered point farthest from the laid layer, on the surface seen there."""
    edge: np.ndarray
    """(3,) the laid layer's point nearest `deepest`, on its top surface."""
    depth: float
    """Distance from `edge` to `deepest` in the table plane (m)."""


def layer_cover(
    before: Observation,
    before_plane: np.ndarray,
    after: Observation,
    after_plane: np.ndarray,
    cover_polygon: np.ndarray,
    inset_px: int = 2,
    min_rise: float = 0.002,
) -> LayerCover | None:
    """Where the layer a stage laid over `cover_polygon` (N×3 world polygon: the region the moved
    cloth should lie on) lies and where it does not, from the frames before and after the stage;
    None when the region is not seen or no layer rose at least `min_rise` (m) over it. A pixel is
    uncovered where its surface rose by less than half the region's median rise; `inset_px`
    pixels along the region's border are ignored (its edge blurs in depth)."""
    rise, seen = surface_rise(before, before_plane, after, after_plane)
    region = polygon_mask(cover_polygon, after.intrinsics, after.T_world_camera)
    if inset_px > 0:
        region = cv2.erode(region.astype(np.uint8), np.ones((3, 3), np.uint8), iterations=inset_px)
        region = region.astype(bool)
    seen &= region
    if seen.sum() < 20:
        return None
    rise = np.where(seen, rise, 0.0)
    layer = float(np.median(rise[seen]))
    if layer < min_rise:
        return None
    exposed = seen & (rise < 0.5 * layer)
    exposed = cv2.morphologyEx(
        exposed.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)
    ).astype(bool)
    return LayerCover(layer_rise=layer, covered=seen & ~exposed, exposed=exposed)


def deepest_gap(cover: LayerCover | None, after: Observation) -> CoverGap | None:
    """The uncovered pixel farthest from the laid layer and the layer's pixel nearest it, as world
    points on the surfaces seen in `after`; None when nothing (or everything) is uncovered."""
    if cover is None or not cover.exposed.any() or not cover.covered.any():
        return None
    covered, exposed = cover.covered, cover.exposed
    dist = cv2.distanceTransform((~covered).astype(np.uint8), cv2.DIST_L2, 5)
    dist[~exposed] = -1.0
    vd, ud = np.unravel_index(int(np.argmax(dist)), dist.shape)
    cv_, cu = np.nonzero(covered)
    k = int(np.argmin((cu - ud) ** 2 + (cv_ - vd) ** 2))
    deepest = backproject_pixel(after, float(ud), float(vd), radius=1)
    edge = backproject_pixel(after, float(cu[k]), float(cv_[k]), radius=1)
    if not (np.all(np.isfinite(deepest)) and np.all(np.isfinite(edge))):
        return None
    return CoverGap(deepest=deepest, edge=edge, depth=float(np.linalg.norm(deepest[:2] - edge[:2])))


def laid_layer_mask(
    before: Observation,
    before_plane: np.ndarray,
    after: Observation,
    after_plane: np.ndarray,
    min_rise: float,
) -> np.ndarray:
    """Pixels (H×W bool) whose surface rose by at least `min_rise` (m) from `before` to `after`:
    the cloth a stage laid there, on cloth or on bare table (the parked arm, higher than
    MAX_CLOTH_HEIGHT, is left out); single stray pixels are opened away."""
    if not min_rise > 0:
        raise PerceptionError(f"min_rise must be > 0 m, got {min_rise!r}")
    rise, seen = surface_rise(before, before_plane, after, after_plane)
    rose = seen & (rise >= min_rise)
    opened = cv2.morphologyEx(rose.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    return opened.astype(bool)


def mask_points(mask: np.ndarray, obs: Observation) -> np.ndarray:
    """World points (N×3, m) of the surface `obs` sees at the pixels of `mask` (H×W bool) that
    have depth: e.g. a laid layer's top surface."""
    if mask.shape != obs.depth.shape:
        raise PerceptionError(f"mask is {mask.shape}, the depth image {obs.depth.shape}")
    v, u = np.nonzero(mask)
    z = obs.depth[v, u].astype(float)
    ok = np.isfinite(z) & (z > 0)
    return backproject(np.c_[u[ok], v[ok]], z[ok], obs.intrinsics, obs.T_world_camera)


@dataclass(frozen=True)
class LaidCorner:
    """A corner of the layer a stage laid, seen in depth (world frame, m)."""

    corner: np.ndarray
    """(3,) the corner itself, on the layer's top surface."""
    grasp: np.ndarray
    """(3,) a point just inside it, on the layer's top surface: where the layer is picked."""


def laid_corner(
    laid: np.ndarray, after: Observation, place: np.ndarray, inset_px: int = 3
) -> LaidCorner | None:
    """The laid layer's corner nearest `place` (a world point: where a carried corner was laid),
    or None when nothing was laid. `laid`: the laid layer's pixels (laid_layer_mask).

    The corner is a vertex of the largest quadrilateral on the convex hull of the laid pixels'
    largest connected piece (as the towel detector finds a towel's corners); the surface there
    is read `inset_px` pixels toward the piece's centre, where depth sees the layer and not the
    surface beyond its edge."""
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(laid.astype(np.uint8), 8)
    if n < 2:
        return None
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if stats[k, cv2.CC_STAT_AREA] < 20:
        return None
    contours, _ = cv2.findContours(
        (labels == k).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
    )
    pts = np.vstack([c.reshape(-1, 2) for c in contours]).astype(np.float32)
    hull = pts[cv2.convexHull(pts, returnPoints=False).reshape(-1)].astype(float)
    quad = hull[max_area_quad(hull)]
    uv, _z = project_points(
        np.asarray(place, dtype=float).reshape(1, 3), after.intrinsics, after.T_world_camera
    )
    corner_px = quad[int(np.argmin(np.linalg.norm(quad - uv[0], axis=1)))]
    inward = centroids[k] - corner_px
    inside_px = corner_px + inward / max(float(np.linalg.norm(inward)), 1e-9) * inset_px
    depth = robust_depth(after.depth, float(inside_px[0]), float(inside_px[1]), radius=1)
    if not np.isfinite(depth):
        return None
    corner, grasp = (
        backproject(px[None], np.array([depth]), after.intrinsics, after.T_world_camera)[0]
        for px in (corner_px, inside_px)
    )
    return LaidCorner(corner=corner, grasp=grasp)
