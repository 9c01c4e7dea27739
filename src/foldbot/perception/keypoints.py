"""Cloth corners: the labelling rule (shared with the oracle) and sub-pixel corner detection.

Corner labelling rule (world frame, seen from the robot at the table's near edge looking along +x):
- "near" = smaller world x (closer to the robot), "far" = larger x; "left" = +y, "right" = −y.
- Take the centroid c of the four corners (their mean, in the table plane) and each corner's
  angle φ_i = atan2(y_i − c_y, x_i − c_x). The corner whose angular distance |wrap(φ_i − 3π/4)| to
  the near-left direction (−x, +y) is smallest is "near_left" (exact ties go to the corner with the
  larger φ in [−π, π)). Going counter-clockwise from it (increasing angle) follow "near_right",
  "far_right", "far_left".
- Consequence: the labels are a pure function of the corner positions, the same for vision and the
  oracle. As the cloth turns they stay with the same physical corners until two corners are
  equally far from the 135° direction (for a square: when a diagonal is aligned with the world
  x or y axis, i.e. at 45° + k·90°); there every label moves on by one position, counter-clockwise
  when the cloth turns clockwise and vice versa. Near such a tie, measurement noise can flip the
  assignment.

Corner detection (image space): the cloth mask's outer contour is reduced to the maximum-area
quadrilateral over its convex hull (robust to notches cut by the arm), then each corner is refined
by fitting straight lines (Huber) to the two adjacent outline sides — the part of each side nearest
the corner, away from the corner's rounding and from pixels next to occluders or the image border —
and intersecting them. The binary mask's boundary pixels lie on average half a pixel step inside
the true edge, which the line fit corrects for.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from foldbot.errors import PerceptionError

CORNER_LABELS: tuple[str, str, str, str] = ("near_left", "near_right", "far_right", "far_left")
"""Corner names in counter-clockwise order (seen from above, world frame)."""
NEAR_LEFT_ANGLE = 3.0 * math.pi / 4.0
"""Direction (rad, world frame, from the centroid) that defines "near_left": (−x, +y)."""


def label_corners(corners_xy: np.ndarray) -> dict[str, int]:
    """Label 4 corners (4×2 or 4×3 world points; x, y used) by the rule above: name → row index."""
    pts = np.asarray(corners_xy, dtype=float)
    if pts.ndim != 2 or pts.shape[0] != 4 or pts.shape[1] < 2 or not np.all(np.isfinite(pts)):
        raise PerceptionError(f"label_corners needs 4 finite points (4×2 or 4×3), got {pts.shape}")
    xy = pts[:, :2]
    d = xy - xy.mean(axis=0)
    phi = np.arctan2(d[:, 1], d[:, 0])
    order = np.argsort(phi, kind="stable")  # counter-clockwise
    dist = np.abs((phi[order] - NEAR_LEFT_ANGLE + math.pi) % (2.0 * math.pi) - math.pi)
    best = dist.min()
    ties = np.flatnonzero(dist <= best + 1e-12)
    start = int(ties[-1])  # tie → larger angle
    rolled = np.roll(order, -start)
    return {label: int(i) for label, i in zip(CORNER_LABELS, rolled, strict=True)}


@dataclass(frozen=True)
class KeypointConfig:
    """Parameters of the image-space corner detector (pixels unless stated)."""

    side_fraction: float = 0.45
    """Part of each adjacent side (from the corner) used to fit that corner's edge lines."""
    corner_margin: float = 0.04
    """Skip this fraction of the side length next to the corner (rounded or curled corners)."""
    min_margin_px: float = 3.0
    """…and at least this many pixels."""
    exclusion_px: int = 2
    """Ignore outline points within this distance of an occluder or the image border."""
    max_shift_px: float = 12.0
    """A refined corner further than this from the coarse one is rejected (coarse kept)."""
    max_hidden_shift: float = 0.8
    """…for a hidden corner (extended sides), up to this fraction of the mean side length."""
    residual_scale_px: float = 1.5
    """Line-fit RMS (px) at which a corner's confidence has dropped to 1/e."""


@dataclass(frozen=True)
class ImageCorners:
    """Four outline corners in image pixels (in outline order) and their quality."""

    uv: np.ndarray
    """4×2 sub-pixel corner positions (u, v)."""
    confidence: np.ndarray
    """(4,) confidence in [0, 1]."""
    contour: np.ndarray
    """N×2 outer contour of the mask (pixel centres)."""


@lru_cache(maxsize=32)
def _quad_combinations(m: int) -> np.ndarray:
    return np.array(list(itertools.combinations(range(m), 4)), dtype=np.intp)


def _quad_areas(points: np.ndarray, combos: np.ndarray) -> np.ndarray:
    q = points[combos]  # C×4×2
    x, y = q[..., 0], q[..., 1]
    return 0.5 * np.abs(
        (x * np.roll(y, -1, axis=1)).sum(axis=1) - (y * np.roll(x, -1, axis=1)).sum(axis=1)
    )


def _line_distance(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    return np.abs(d[0] * (pts[..., 1] - a[1]) - d[1] * (pts[..., 0] - a[0]))


def max_area_quad(points: np.ndarray, max_brute_force: int = 12) -> np.ndarray:
    """Indices (ascending) of the largest-area quadrilateral on a convex polygon's vertices.

    `points` (N×2) are the polygon's vertices in order (e.g. a convex hull). Exhaustive search on
    up to `max_brute_force` evenly spaced vertices, then coordinate ascent over all vertices
    (each corner moves to the vertex farthest from the line through its two neighbours).
    """
    pts = np.asarray(points, dtype=float)
    m = len(pts)
    if m <= 4:
        return np.arange(m)
    sub = np.unique(np.linspace(0, m, min(m, max_brute_force), endpoint=False).astype(np.intp))
    combos = _quad_combinations(len(sub))
    best = sub[combos[int(np.argmax(_quad_areas(pts[sub], combos)))]].copy()
    for _ in range(4 * m):
        changed = False
        for k in range(4):
            a, b = best[k - 1], best[(k + 1) % 4]
            between = np.arange(a + 1, b if b > a else b + m) % m
            if between.size == 0:
                continue
            dist = _line_distance(pts[between], pts[a], pts[b])
            j = int(np.argmax(dist))
            if dist[j] > _line_distance(pts[best[k]], pts[a], pts[b]) + 1e-12:
                best[k] = between[j]
                changed = True
        if not changed:
            break
    return np.sort(best)


def _fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Robust line through points: (point, unit direction, rms residual px) or None."""
    if len(points) < 4:
        return None
    line = cv2.fitLine(points.astype(np.float32), cv2.DIST_HUBER, 0, 0.01, 0.01).reshape(-1)
    d = line[:2].astype(float)
    p0 = line[2:].astype(float)
    n = np.array([-d[1], d[0]])
    r = (points - p0) @ n
    return p0, d, float(np.sqrt(np.mean(r * r)))


def _intersect(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> np.ndarray | None:
    a = np.array([d1, -d2]).T
    if abs(np.linalg.det(a)) < 1e-6:
        return None
    t = np.linalg.solve(a, p2 - p1)
    return p1 + t[0] * d1


def find_corners(
    mask: np.ndarray, exclude: np.ndarray | None = None, config: KeypointConfig | None = None
) -> ImageCorners | None:
    """Four sub-pixel outline corners of the largest blob in `mask`; None if it has no area.

    `exclude` (bool H×W) marks pixels next to which the outline is not a real cloth edge (arm,
    gripper); outline points near them or near the image border are not used in line fits.
    """
    cfg = config or KeypointConfig()
    m = np.ascontiguousarray(mask, dtype=np.uint8)
    if m.ndim != 2 or m.size == 0:
        raise PerceptionError(f"mask must be a non-empty H×W array, got shape {m.shape}")
    contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    cnt = max(contours, key=cv2.contourArea)
    if cv2.contourArea(cnt) < 16.0:
        return None
    contour = cnt.reshape(-1, 2).astype(float)
    n_pts = len(contour)
    hull = cv2.convexHull(contour.astype(np.float32)).reshape(-1, 2).astype(float)
    if len(hull) < 4:
        return None
    quad = hull[max_area_quad(hull)]
    # Order the coarse corners along the contour.
    idx = np.array([int(np.argmin(np.sum((contour - c) ** 2, axis=1))) for c in quad])
    order = np.argsort(idx)
    idx, quad = idx[order], contour[idx[order]]

    # Outline points usable for line fits.
    h, w = m.shape
    ok = (
        (contour[:, 0] >= cfg.exclusion_px)
        & (contour[:, 1] >= cfg.exclusion_px)
        & (contour[:, 0] <= w - 1 - cfg.exclusion_px)
        & (contour[:, 1] <= h - 1 - cfg.exclusion_px)
    )
    if exclude is not None and exclude.any():
        size = 2 * cfg.exclusion_px + 1
        near = cv2.dilate(
            np.ascontiguousarray(exclude, dtype=np.uint8), np.ones((size, size), np.uint8)
        )
        ci = contour.astype(int)
        ok &= near[ci[:, 1], ci[:, 0]] == 0
    centroid = contour.mean(axis=0)

    def side_points(k: int, near_start: bool, fraction: float) -> tuple[np.ndarray, bool]:
        """Usable outline points of side k (corner k → k+1) within `fraction` of its length
        from corner k (near_start) or corner k+1, and whether any point there was unusable."""
        a, b = idx[k], idx[(k + 1) % 4]
        seg = np.arange(a, b if b > a else b + n_pts) % n_pts
        length = len(seg)
        margin = max(cfg.min_margin_px, cfg.corner_margin * length)
        take = max(int(fraction * length), int(margin) + 6)
        pos = np.arange(length) if near_start else (length - 1 - np.arange(length))
        sel = seg[(pos < take) & (pos < length - margin)]
        hidden = not bool(ok[sel].all())
        sel = sel[pos[(pos < take) & (pos < length - margin)] >= margin]
        return contour[sel[ok[sel]]], hidden

    def fit(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, int] | None:
        line = _fit_line(pts)
        if line is None:
            return None
        p0, d, rms = line
        normal = np.array([-d[1], d[0]])
        if (p0 - centroid) @ normal < 0:
            normal = -normal
        # Boundary pixel centres sit on average half a pixel step inside the true edge.
        return p0 + 0.5 * max(abs(d[0]), abs(d[1])) * normal, d, rms, len(pts)

    side_len = float(np.mean(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1)))
    uv = np.zeros((4, 2))
    conf = np.zeros(4)
    for k in range(4):
        # Corner k ends side k−1 and starts side k.
        pa, hid_a = side_points((k - 1) % 4, near_start=False, fraction=cfg.side_fraction)
        pb, hid_b = side_points(k, near_start=True, fraction=cfg.side_fraction)
        occluded = hid_a or hid_b
        max_shift = cfg.max_shift_px
        if occluded:
            # The corner is hidden (arm, image border): extend its visible sides to meet.
            pa, _ = side_points((k - 1) % 4, near_start=False, fraction=1.0)
            pb, _ = side_points(k, near_start=True, fraction=1.0)
            max_shift = max(cfg.max_shift_px, cfg.max_hidden_shift * side_len)
        fa, fb = fit(pa), fit(pb)
        corner = None
        if fa is not None and fb is not None:
            corner = _intersect(fa[0], fa[1], fb[0], fb[1])
        if corner is None or np.linalg.norm(corner - quad[k]) > max_shift:
            uv[k] = quad[k]
            conf[k] = 0.1
            continue
        uv[k] = corner
        q = [
            math.exp(-((f[2] / cfg.residual_scale_px) ** 2)) * min(1.0, f[3] / 10.0)
            for f in (fa, fb)
        ]
        cos_angle = abs(float(fa[1] @ fb[1]))
        conf[k] = min(q) * (1.0 - cos_angle**4) * (0.5 if occluded else 1.0)
    return ImageCorners(uv=uv, confidence=np.clip(conf, 0.0, 1.0), contour=contour)
