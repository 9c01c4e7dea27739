"""GarmentEstimator: the named keypoints of a flat T-shirt or pair of pants from one RGB-D frame.

Everything comes from the Observation (never from the simulator):
1. Segment the cloth (`segment_cloth`) and lift the mask's outer contour onto the table plane at
   the cloth's median height (the helpers `VisionEstimator` uses), giving the outline in the world.
   A colour mask's contour is first moved half a pixel outwards (its boundary pixels lie inside
   the true edge); a depth mask's measured unbiased.
2. Garment axis: the line through the outline's area centroid about which the outline is most
   mirror-symmetric (mean distance from the mirrored outline to the outline, searched over yaw
   within `axis_window` of the prior `top_yaw`, by default every axis, and refined). Which end is
   the top is read from the shape: the keypoints are looked for with the top on the prior's side
   first and, where that finds no complete garment, the other way round (a T-shirt's neckline
   dent and a pair of pants' notch between the legs each exist at one end only), so a garment
   lying in any direction is recognised. Garment frame: v along the axis towards the top (neck,
   waist), u to the garment's right (the mesh's +x side; "left" keypoints lie at u < 0, as in
   `foldbot.garments`).
3. Keypoints in the garment frame, on the outline ordered counter-clockwise:
   - on the axis: the neck (the upper crossing of the outline with the axis) and the crotch (the
     lower crossing, refined as the corner between the inseams, which a camera can miss where
     the legs nearly touch);
   - extremal corners: hem corners, waist corners and the legs' hem corners (extreme along a
     diagonal of the garment frame);
   - concavities: the armpits, the deepest dents of the outline's convex hull on either side
     (the neckline's dent, which the axis crosses, left out);
   - the shoulders: where the outline above the armpit crosses back over the body's side line
     (fitted between the hem corner and the armpit): the sleeve starts above the side seam;
   - the cuffs: the two outline points that, with the armpit and the shoulder, span the largest
     quadrilateral over the sleeve; the keypoint is the middle of the cuff.
   Every corner is then refined by fitting straight lines to the outline on both sides of it
   (skipping the corner's rounding) and intersecting them. Dents shallower than `MIN_DENT` and
   a notch between the legs lower than `MIN_NOTCH` do not count, so a towel seen as a T-shirt
   has no neck, armpits, shoulders or sleeves, and as pants no crotch or inner leg corners.
4. 3-D: each keypoint is lifted back through its pixel to the table plane at the local cloth
   height (as `VisionEstimator` does for towel corners).

Detection: the garment is detected only when it is recognised as a flat garment of its kind:
its outline is mirror-symmetric within `max_residual` (judged on the outline the arm does not
hide, nor its mirror partners) and every keypoint is found; otherwise detected=False and
`reason` says what failed (a folded garment, a towel, a keypoint hidden by the arm), so a caller
can fall back to the generic `VisionEstimator`. Where the arm hides part of the outline (the
outline there is the amodal mask's hull), a left or right keypoint there is its partner's mirror
image, the crotch is where the inseams seen below the arm meet, and a T-shirt's neck, which no
other outline gives, is left out of the keypoints (`reason` names it) rather than guessed; the
recipes do not plan from it.
A garment whose mask touches the image border is not detected either (its outline is cut).

Confidence: a keypoint's confidence is the axis quality exp(−(r/`symmetry_scale`)²) (r: mirror
residual, m) times its line fits' quality exp(−(rms/`fit_scale`)²), × 0.3 where the refinement
failed and the coarse point is kept, × 0.3 next to an occluder (arm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.optimize import minimize_scalar
from scipy.spatial import cKDTree

from foldbot.errors import ConfigError
from foldbot.garments.pants import PANTS_KEYPOINTS
from foldbot.garments.tshirt import TSHIRT_KEYPOINTS
from foldbot.perception.estimator import lift_outline, lift_pixels, local_heights, visible_heights
from foldbot.perception.geometry import Plane, project_points
from foldbot.perception.segmentation import SegmentationConfig, segment_cloth
from foldbot.perception.state import NO_CLOTH, ClothState
from foldbot.types import Observation

GARMENT_KEYPOINT_NAMES: dict[str, tuple[str, ...]] = {
    "tshirt": TSHIRT_KEYPOINTS,
    "pants": PANTS_KEYPOINTS,
}
"""The keypoints GarmentEstimator looks for, by garment kind (the names `foldbot.garments` uses)."""
GARMENT_KINDS = tuple(GARMENT_KEYPOINT_NAMES)
"""Garment kinds GarmentEstimator handles."""
BORDER_PX = 2
"""A mask reaching within this many pixels of the image border is refused (a cut outline)."""
MAX_AXIS_SHIFT = 0.03
"""Where the arm hides part of the outline, the axis may pass up to this far (m) beside the
outline's area centroid."""
MIN_DENT = 0.01
"""Smallest depth (m) of the neckline's and an armpit's dent in the outline, and distance between
a leg's hem corners: shallower dents are outline noise (a towel has none)."""
MIN_NOTCH = 0.02
"""Smallest height (m) of the notch between the legs, crotch above the inner hem corners."""
CROTCH_GAP_FRACTION = 0.35
"""Inseam points used for the crotch lie at least this share of the inner hem corner's distance
from the axis away from it (where the gap between the legs is visible)."""


@dataclass(frozen=True)
class GarmentKeypointConfig:
    """Settings of the garment keypoint estimator (metres and radians)."""

    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    """Cloth segmentation thresholds."""
    top_yaw: float = math.pi
    """Prior world direction (rad) of the garment's top (neck, waist), tried first: π = towards
    the robot (−x), where the fold pipeline places garments by default."""
    axis_window: float = math.pi / 2
    """The symmetry axis is searched within ± this of `top_yaw` (rad); π/2 (the default) searches
    every axis, so the garment may lie in any direction."""
    axis_step: float = math.radians(2.0)
    """Step (rad) of the coarse axis search before the refinement."""
    corner_skip: float = 0.004
    """Outline length (m) next to a corner left out of its line fits (the corner's rounding)."""
    corner_reach: float = 0.035
    """Longest outline stretch (m) on each side of a corner used for its line fits."""
    max_corner_shift: float = 0.015
    """A refined corner further than this (m) from the coarse one is rejected (coarse kept)."""
    min_corner_angle: float = math.radians(15.0)
    """Two fitted sides meeting at less than this angle (rad) give no reliable corner."""
    height_radius_px: int = 10
    """Radius (px) around a keypoint whose cloth pixels give its height above the table."""
    symmetry_scale: float = 0.006
    """Mirror residual (m) at which the axis quality, and so every confidence, drops to 1/e."""
    max_residual: float = 0.005
    """An outline less mirror-symmetric than this (mean residual, m; flat garments measured
    0.6–0.8 mm) is not taken for a flat garment (e.g. a folded one): not detected."""
    fit_scale: float = 0.0015
    """Line-fit RMS (m) at which a corner's fit quality drops to 1/e."""

    def __post_init__(self) -> None:
        checks = {
            "top_yaw": math.isfinite(self.top_yaw),
            "axis_window": 0.0 < self.axis_window <= math.pi / 2,
            "axis_step": 0.0 < self.axis_step <= self.axis_window,
            "corner_skip": 0.0 <= self.corner_skip < self.corner_reach,
            "corner_reach": 0.0 < self.corner_reach <= 0.2,
            "max_corner_shift": 0.0 < self.max_corner_shift <= 0.1,
            "min_corner_angle": 0.0 < self.min_corner_angle < math.pi / 2,
            "height_radius_px": isinstance(self.height_radius_px, int)
            and 1 <= self.height_radius_px <= 100,
            "symmetry_scale": self.symmetry_scale > 0.0,
            "fit_scale": self.fit_scale > 0.0,
            "max_residual": self.max_residual > 0.0,
        }
        for name, ok in checks.items():
            if not ok:
                raise ConfigError(
                    f"GarmentKeypointConfig.{name} = {getattr(self, name)!r} is out of range"
                )


@dataclass(frozen=True)
class GarmentFrame:
    """The garment's symmetry axis in the table plane (world x, y, m)."""

    origin: np.ndarray
    """(2,) on the axis: the outline's area centroid, or beside it where the arm hides part of
    the outline (symmetry_axis)."""
    top: np.ndarray
    """(2,) unit direction of the axis towards the garment's top (v)."""
    right: np.ndarray
    """(2,) unit direction to the garment's right (u), the mesh's +x side."""
    residual: float
    """Mean distance (m) between the mirrored outline and the outline."""

    def flipped(self) -> GarmentFrame:
        """The same axis with its top at the other end (u turns with it)."""
        return GarmentFrame(self.origin, -self.top, -self.right, self.residual)

    def to_frame(self, xy: np.ndarray) -> np.ndarray:
        """World x, y (N×2) → garment (u, v)."""
        d = np.asarray(xy, dtype=float).reshape(-1, 2) - self.origin
        return np.stack([d @ self.right, d @ self.top], axis=1)

    def to_world(self, uv: np.ndarray) -> np.ndarray:
        """Garment (u, v) (N×2) → world x, y."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        return self.origin + uv[:, :1] * self.right + uv[:, 1:] * self.top


def polygon_centroid(xy: np.ndarray) -> np.ndarray:
    """Area centroid (2,) of a simple polygon (N×2, either orientation)."""
    x, y = xy[:, 0], xy[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = cross.sum() / 2.0
    if abs(a) < 1e-12:
        return xy.mean(axis=0)
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * a)


def symmetry_axis(
    xy: np.ndarray, config: GarmentKeypointConfig, hidden: np.ndarray | None = None
) -> GarmentFrame:
    """The garment frame of an outline (N×2 world x, y): its most mirror-symmetric axis through
    the centroid within the configured window around the prior top direction, its top on the
    prior's side. Outline points `hidden` by the arm (bool per point: there the outline is the
    amodal mask's hull, not the cloth's edge) are left out of the mirror residual, as are points
    whose mirror lands on them, unless they are half the outline or more."""
    c = polygon_centroid(xy)
    tree = cKDTree(xy)
    if hidden is None or not hidden.any() or hidden.mean() >= 0.5:
        hidden = None
    # Query points (relative to c) and, where the arm hides some, which of them it does not.
    steps = {"fine": max(1, len(xy) // 400), "coarse": max(1, len(xy) // 100)}
    queries = {k: (xy[::n] - c, None if hidden is None else ~hidden[::n]) for k, n in steps.items()}

    def cost(angle: float, which: str = "fine", offset: float = 0.0) -> float:
        # The axis through c + offset·right: mirroring across it shifts the image 2·offset right.
        query, seen = queries[which]
        t = np.array([math.cos(angle), math.sin(angle)])
        mirrored = 2.0 * (query @ t)[:, None] * t - query + c
        if offset:
            mirrored += 2.0 * offset * np.array([t[1], -t[0]])
        d, partner = tree.query(mirrored)
        if hidden is None:
            return float(d.mean())
        keep = seen & ~hidden[partner]
        return float(d[keep].mean()) if keep.any() else float(d.mean())

    prior, window, step = config.top_yaw, config.axis_window, config.axis_step
    grid = prior + np.arange(-window, window + 0.5 * step, step)
    best = float(grid[int(np.argmin([cost(a, "coarse") for a in grid]))])
    res = minimize_scalar(
        cost, bounds=(best - step, best + step), method="bounded", options={"xatol": 1e-4}
    )
    angle, residual = float(res.x), float(res.fun)
    if cost(best) < residual:
        angle, residual = best, cost(best)
    offset = 0.0
    if hidden is not None:
        # The area centroid moves with the cloth the arm hides; the axis is found off it.
        shift = minimize_scalar(
            lambda o: cost(angle, "fine", o),
            bounds=(-MAX_AXIS_SHIFT, MAX_AXIS_SHIFT),
            method="bounded",
            options={"xatol": 1e-5},
        )
        turn = minimize_scalar(
            lambda a: cost(a, "fine", float(shift.x)),
            bounds=(angle - step, angle + step),
            method="bounded",
            options={"xatol": 1e-4},
        )
        if float(turn.fun) < residual:
            angle, offset, residual = float(turn.x), float(shift.x), float(turn.fun)
    top = np.array([math.cos(angle), math.sin(angle)])
    right = np.array([top[1], -top[0]])
    return GarmentFrame(origin=c + offset * right, top=top, right=right, residual=residual)


@dataclass(frozen=True)
class _Found:
    """One keypoint in the garment frame and its quality (0..1) before occlusion."""

    uv: np.ndarray
    quality: float


class _Outline:
    """A closed outline in the garment frame (N×2 (u, v), counter-clockwise) and its arc lengths."""

    def __init__(self, uv: np.ndarray, hidden: np.ndarray | None = None) -> None:
        self.p = uv
        self.hidden = np.zeros(len(uv), bool) if hidden is None else np.asarray(hidden, bool)
        """Bool per point: the arm hides the cloth's edge there (the hull's chord in its place)."""
        seg = np.linalg.norm(np.roll(uv, -1, axis=0) - uv, axis=1)
        self.s = np.r_[0.0, np.cumsum(seg)[:-1]]
        self.length = float(seg.sum())
        self.n = len(uv)

    def forward(self, a: int, b: int) -> np.ndarray:
        """Indices from a to b (inclusive) going forward (counter-clockwise)."""
        return np.arange(a, b + 1 if b >= a else b + self.n + 1) % self.n

    def ahead(self, i: int, lo: float, hi: float) -> np.ndarray:
        """Indices whose forward arc distance from i is in [lo, hi] (m)."""
        d = (self.s - self.s[i]) % self.length
        return np.flatnonzero((d >= lo) & (d <= hi))

    def behind(self, i: int, lo: float, hi: float) -> np.ndarray:
        """Indices whose backward arc distance from i is in [lo, hi] (m)."""
        d = (self.s[i] - self.s) % self.length
        return np.flatnonzero((d >= lo) & (d <= hi))

    def segment_hidden(self, i: int) -> bool:
        """The arm hides an end of the segment from point i to the next (a `crossings` index)."""
        return bool(self.hidden[i] or self.hidden[(i + 1) % self.n])

    def arc(self, a: int, b: int) -> float:
        """Forward arc length (m) from index a to b."""
        return float((self.s[b] - self.s[a]) % self.length)

    def crossings(self, u0: float = 0.0) -> list[tuple[int, np.ndarray]]:
        """Where the outline crosses u = u0: (index of the segment's start, point)."""
        u = self.p[:, 0] - u0
        un = np.roll(u, -1)
        out = []
        for i in np.flatnonzero((u <= 0.0) != (un <= 0.0)):
            q, qn = self.p[i], self.p[(i + 1) % self.n]
            t = u[i] / (u[i] - un[i])
            out.append((int(i), q + t * (qn - q)))
        return out

    def defects(self) -> list[tuple[int, int, int, float]]:
        """Dents of the convex hull: (hull start index, hull end index, deepest index, depth m)."""
        hull = cv2.convexHull(self.p.astype(np.float32), clockwise=False, returnPoints=False)
        hull = np.sort(hull.reshape(-1))
        out = []
        for k, a in enumerate(hull):
            b = int(hull[(k + 1) % len(hull)])
            idx = self.forward(int(a), b)
            if len(idx) < 3:
                continue
            pa, pb = self.p[a], self.p[b]
            d = pb - pa
            norm = float(np.linalg.norm(d))
            if norm < 1e-9:
                continue
            rel = self.p[idx] - pa
            depth = np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0]) / norm
            j = int(np.argmax(depth))
            out.append((int(a), b, int(idx[j]), float(depth[j])))
        return out


def _fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Total-least-squares line: (point, unit direction, rms residual m) or None (< 4 points)."""
    if len(points) < 4:
        return None
    c = points.mean(axis=0)
    d = points - c
    _, sv, vt = np.linalg.svd(d, full_matrices=False)
    return c, vt[0], float(sv[-1] / math.sqrt(len(points)))


def _intersect(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> np.ndarray | None:
    a = np.array([d1, -d2]).T
    if abs(np.linalg.det(a)) < 1e-9:
        return None
    t = np.linalg.solve(a, p2 - p1)
    return p1 + t[0] * d1


class _Finder:
    """Keypoint search on one garment outline (the steps of the module docstring)."""

    def __init__(self, outline: _Outline, config: GarmentKeypointConfig) -> None:
        self.o = outline
        self.cfg = config
        self.unseen: set[str] = set()
        """Keypoints the arm hides that no other outline gives (they are left out, not lost)."""

    def corner(self, i: int, back: float | None = None, fwd: float | None = None) -> _Found:
        """Refine the corner at outline index i by intersecting lines fitted to the outline
        before it (up to `back` m) and after it (up to `fwd` m)."""
        cfg, o = self.cfg, self.o
        back = cfg.corner_reach if back is None else min(back, cfg.corner_reach)
        fwd = cfg.corner_reach if fwd is None else min(fwd, cfg.corner_reach)
        coarse = o.p[i]
        la = _fit_line(o.p[o.behind(i, cfg.corner_skip, back)])
        lb = _fit_line(o.p[o.ahead(i, cfg.corner_skip, fwd)])
        if la is None or lb is None:
            return _Found(coarse, 0.3)
        sin_angle = abs(float(la[1][0] * lb[1][1] - la[1][1] * lb[1][0]))
        if sin_angle < math.sin(cfg.min_corner_angle):
            return _Found(coarse, 0.3)
        p = _intersect(la[0], la[1], lb[0], lb[1])
        if p is None or np.linalg.norm(p - coarse) > cfg.max_corner_shift:
            return _Found(coarse, 0.3)
        q = math.exp(-((max(la[2], lb[2]) / cfg.fit_scale) ** 2))
        return _Found(p, q)

    def limit(self, i: int, j: int) -> float:
        """Reach (m) from corner i towards neighbour keypoint j: 45 % of the arc between them."""
        a = self.o.arc(i, j)
        return 0.45 * min(a, self.o.length - a)

    def axis_crossing(self, upper: bool) -> tuple[int, np.ndarray] | None:
        """The outline's upper (max v) or lower (min v) crossing with the axis u = 0."""
        cr = self.o.crossings()
        if len(cr) < 2:
            return None
        return max(cr, key=lambda c: c[1][1]) if upper else min(cr, key=lambda c: c[1][1])

    def extreme(self, du: float, dv: float, mask: np.ndarray | None = None) -> int | None:
        """Outline index extreme along direction (du, dv) (optionally among `mask`)."""
        score = self.o.p @ np.array([du, dv])
        if mask is not None:
            if not mask.any():
                return None
            score = np.where(mask, score, -np.inf)
        return int(np.argmax(score))

    def side_line(self, a: int, b: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Line (point, unit direction) fitted to the outline from index a forward to b, its
        ends (a corner's rounding and a fifth of the stretch) and what the arm hides left out
        (the amodal hull bulges round a gripper beside the edge)."""
        idx = self.o.forward(a, b)
        k = max(3, len(idx) // 5)
        if len(idx) <= 2 * k + 4:
            return None
        idx = idx[k:-k]
        idx = idx[~self.o.hidden[idx]]
        fit = _fit_line(self.o.p[idx]) if len(idx) >= 5 else None
        return None if fit is None else (fit[0], fit[1])

    # ---- T-shirt ------------------------------------------------------------------------------

    def tshirt(self) -> dict[str, _Found]:
        o = self.o
        found: dict[str, _Found] = {}
        neck = self.axis_crossing(upper=True)
        if neck is None:
            return found
        i_neck, p_neck = neck
        hem = {"left": self.extreme(-1.0, -1.0), "right": self.extreme(1.0, -1.0)}
        # The neck lies in the neckline's dent; the armpits are the deepest dents on either side.
        dents: dict[str, tuple[int, float]] = {}
        for a, b, far, depth in self.o.defects():
            if i_neck in set(o.forward(a, b).tolist()):
                if depth >= MIN_DENT:
                    found["neck"] = _Found(p_neck, 1.0)
                continue
            side = "left" if o.p[far, 0] < 0 else "right"
            if depth < MIN_DENT:
                continue  # outline noise, not an armpit (a towel has none)
            if side not in dents or depth > dents[side][1]:
                dents[side] = (far, depth)
        if "neck" not in found and o.segment_hidden(i_neck):
            # The arm hides the neckline: the outline there is the hull's chord, whose crossing
            # with the axis lay 25-45 mm off the neck; the neck is reported unseen, not guessed.
            self.unseen.add("neck")
        armpit = {side: far for side, (far, _) in dents.items()}
        for side in ("left", "right"):
            found.update(self._tshirt_side(side, hem, armpit.get(side)))
        return found

    def _tshirt_side(
        self, side: str, hem: dict[str, int | None], i_arm: int | None
    ) -> dict[str, _Found]:
        """One side's hem corner, armpit, shoulder and cuff middle (those that can be found).

        Counter-clockwise the outline runs right_hem → right_armpit → right cuff → right_shoulder
        → neck → left_shoulder → left cuff → left_armpit → left_hem.
        """
        o = self.o
        found: dict[str, _Found] = {}
        i_hem = hem[side]
        if i_hem is None:
            return found
        right = side == "right"
        other = hem["left" if right else "right"]
        along_hem = self.limit(i_hem, other) if other is not None else None
        if i_arm is not None and o.p[i_arm, 1] <= o.p[i_hem, 1]:
            i_arm = None  # a dent below the hem corner is no armpit
        up_side = self.limit(i_arm, i_hem) if i_arm is not None else None
        found[f"{side}_hem"] = (
            self.corner(i_hem, back=along_hem, fwd=up_side)
            if right
            else self.corner(i_hem, back=up_side, fwd=along_hem)
        )
        if i_arm is None:
            return found
        body = self.side_line(i_hem, i_arm) if right else self.side_line(i_arm, i_hem)
        shoulder = self._shoulder(i_arm, body, 1.0 if right else -1.0) if body else None
        cuff = self._cuff(i_arm, shoulder[0], 1.0 if right else -1.0) if shoulder else None
        toward_cuff = self.limit(i_arm, cuff[0]) if cuff is not None else None
        found[f"{side}_armpit"] = (
            self.corner(i_arm, back=up_side, fwd=toward_cuff)
            if right
            else self.corner(i_arm, back=toward_cuff, fwd=up_side)
        )
        if shoulder is None:
            return found
        i_sh, p_sh = shoulder
        found[f"{side}_shoulder"] = _Found(p_sh, 1.0)
        if cuff is None:
            return found
        x, y = cuff  # x: the cuff corner next to the armpit, y: the one next to the shoulder
        if right:
            cx = self.corner(x, back=2 * self.limit(i_arm, x), fwd=self.limit(x, y))
            cy = self.corner(y, back=self.limit(x, y), fwd=2 * self.limit(y, i_sh))
        else:
            cy = self.corner(y, back=2 * self.limit(i_sh, y), fwd=self.limit(y, x))
            cx = self.corner(x, back=self.limit(y, x), fwd=2 * self.limit(x, i_arm))
        found[f"{side}_sleeve"] = _Found(0.5 * (cx.uv + cy.uv), min(cx.quality, cy.quality))
        return found

    def _shoulder(
        self, i_arm: int, body: tuple[np.ndarray, np.ndarray], sign: float
    ) -> tuple[int, np.ndarray] | None:
        """Where the outline, followed from the armpit around the sleeve, crosses back inside the
        body's side line: the shoulder point. `sign` +1 right side (walk forward), −1 left."""
        o = self.o
        c, d = body
        normal = np.array([d[1], -d[0]])
        if normal[0] * sign < 0:
            normal = -normal  # pointing outwards, away from the axis
        steps = np.arange(o.n)
        idx = (i_arm + steps) % o.n if sign > 0 else (i_arm - steps) % o.n
        g = (o.p[idx] - c) @ normal
        outside = np.flatnonzero(g > 0.01)
        if outside.size == 0:
            return None
        after = np.flatnonzero(g[outside[0] :] <= 0.0)
        if after.size == 0:
            return None
        k = outside[0] + after[0]
        i0, i1 = idx[k - 1], idx[k]
        t = g[k - 1] / (g[k - 1] - g[k])
        return int(i1), o.p[i0] + t * (o.p[i1] - o.p[i0])

    def _cuff(self, i_arm: int, i_sh: int, sign: float) -> tuple[int, int] | None:
        """The cuff's corners: the two outline points of the sleeve that span the largest
        quadrilateral with the armpit and the shoulder. Returns (next to armpit, next to shoulder)."""
        o = self.o
        idx = o.forward(i_arm, i_sh) if sign > 0 else o.forward(i_sh, i_arm)
        if len(idx) < 8:
            return None
        sub = idx[:: max(1, len(idx) // 120)]
        p = o.p[sub]
        first, last = o.p[idx[0]], o.p[idx[-1]]
        # Area of (first, p_i, p_j, last) for i < j, by the shoelace formula.
        cross_first = first[0] * p[:, 1] - first[1] * p[:, 0]
        cross_last = p[:, 0] * last[1] - p[:, 1] * last[0]
        pair = p[:, None, 0] * p[None, :, 1] - p[:, None, 1] * p[None, :, 0]
        area = cross_first[:, None] + pair + cross_last[None, :]
        area = np.where(np.triu(np.ones_like(area, dtype=bool), k=1), area, -np.inf)
        i, j = np.unravel_index(int(np.argmax(area)), area.shape)
        a, b = int(sub[i]), int(sub[j])
        return (a, b) if sign > 0 else (b, a)

    # ---- pants --------------------------------------------------------------------------------

    def pants(self) -> dict[str, _Found]:
        o = self.o
        u = o.p[:, 0]
        coarse: dict[str, int | None] = {
            "left_leg_outer": self.extreme(-1.0, -1.0),
            "right_leg_outer": self.extreme(1.0, -1.0),
            "right_waist": self.extreme(1.0, 1.0),
            "left_waist": self.extreme(-1.0, 1.0),
        }
        crotch = self.axis_crossing(upper=False)
        if crotch is not None:
            inner = {
                "left_leg_inner": self.extreme(1.0, -1.0, u < 0),
                "right_leg_inner": self.extreme(-1.0, -1.0, u > 0),
            }
            # The legs must be apart: a notch between them below the crotch, and inner hem
            # corners away from the outer ones (a towel has neither).
            ok = all(i is not None for i in inner.values())
            if ok:
                notch = crotch[1][1] - max(o.p[i, 1] for i in inner.values())
                ok = notch >= MIN_NOTCH
                for side in ("left", "right"):
                    i_in, i_out = inner[f"{side}_leg_inner"], coarse[f"{side}_leg_outer"]
                    ok &= i_out is not None and np.linalg.norm(o.p[i_in] - o.p[i_out]) >= MIN_DENT
            if ok:
                coarse.update(inner)
                coarse["crotch"] = crotch[0]
        order = [
            "left_leg_outer",
            "left_leg_inner",
            "crotch",
            "right_leg_inner",
            "right_leg_outer",
            "right_waist",
            "left_waist",
        ]
        have = [n for n in order if coarse.get(n) is not None]
        found: dict[str, _Found] = {}
        for k, name in enumerate(have):
            i = coarse[name]
            prev_i, next_i = coarse[have[k - 1]], coarse[have[(k + 1) % len(have)]]
            found[name] = self.corner(i, back=self.limit(prev_i, i), fwd=self.limit(i, next_i))
        if crotch is not None and "crotch" in found:
            found["crotch"] = self._crotch(
                crotch, coarse["left_leg_inner"], coarse["right_leg_inner"]
            )
        return found

    def _crotch(self, crossing: tuple[int, np.ndarray], i_left: int, i_right: int) -> _Found:
        """The crotch: where the inseams' straight lines meet. Near the crotch the legs nearly
        touch and the camera sees no gap, so the lines are fitted to the wider part of each inseam
        (at least `CROTCH_GAP_FRACTION` of the inner hem corner's distance from the axis); the
        axis crossing is the fallback. Where the arm hides the crossing, the outline there is the
        hull's chord below the crotch: the lines are fitted to the inseams' seen points only and
        may meet anywhere between the chord and the waist."""
        o = self.o
        i_c, p_c = crossing
        lines = []
        for a, b, corner in ((i_left, i_c, i_left), (i_c, i_right, i_right)):
            idx = o.forward(a, b)
            far = np.abs(o.p[idx, 0]) >= CROTCH_GAP_FRACTION * abs(o.p[corner, 0])
            near_corner = np.minimum(
                (o.s[idx] - o.s[corner]) % o.length, (o.s[corner] - o.s[idx]) % o.length
            )
            sel = idx[far & (near_corner >= 2 * self.cfg.corner_skip) & ~o.hidden[idx]]
            lines.append(_fit_line(o.p[sel]) if len(sel) >= 10 else None)
        la, lb = lines
        if la is None or lb is None:
            return _Found(p_c, 0.3)
        p = _intersect(la[0], la[1], lb[0], lb[1])
        top = p_c[1] + 0.06
        if o.segment_hidden(i_c):
            top = float(o.p[:, 1].max()) - MIN_NOTCH
        if p is None or abs(p[0]) > 0.01 or not (p_c[1] - 0.005 <= p[1] <= top):
            return _Found(p_c, 0.3)
        return _Found(p, math.exp(-((max(la[2], lb[2]) / self.cfg.fit_scale) ** 2)))


def _largest_contour(mask: np.ndarray) -> np.ndarray | None:
    contours, _ = cv2.findContours(
        np.ascontiguousarray(mask, dtype=np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
    )
    if not contours:
        return None
    cnt = max(contours, key=cv2.contourArea)
    if cv2.contourArea(cnt) < 16.0:
        return None
    return cnt.reshape(-1, 2).astype(float)


def _edge_corrected(contour: np.ndarray, k: int = 3) -> np.ndarray:
    """Contour pixel centres (N×2) moved onto the true edge: a colour mask's boundary pixels lie
    on average half a pixel step inside it (the same correction the towel corner fits make).
    A depth mask (a threshold on interpolated heights) measured unbiased: it is left as it is."""
    t = np.roll(contour, -k, axis=0) - np.roll(contour, k, axis=0)
    t /= np.maximum(np.linalg.norm(t, axis=1), 1e-9)[:, None]
    x, y = contour[:, 0], contour[:, 1]
    ccw = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)) > 0
    normal = np.stack([t[:, 1], -t[:, 0]], axis=1) * (1.0 if ccw else -1.0)
    return contour + 0.5 * np.abs(t).max(axis=1)[:, None] * normal


def _on_plane(plane: Plane, xy: np.ndarray, height: float) -> np.ndarray:
    """World points (N×3) above world (x, y) on the table plane raised by `height`."""
    n = plane.normal
    z = (height - plane.offset - xy @ n[:2]) / n[2]
    return np.c_[xy, z]


class GarmentEstimator:
    """Estimate a flat garment's mask, outline and named keypoints from one RGB-D Observation."""

    def __init__(self, kind: str, config: GarmentKeypointConfig | None = None) -> None:
        if kind not in GARMENT_KINDS:
            raise ConfigError(f"GarmentEstimator kind must be one of {GARMENT_KINDS}, got {kind!r}")
        self.kind = kind
        self.names = GARMENT_KEYPOINT_NAMES[kind]
        self.config = config or GarmentKeypointConfig()

    def _keypoints(
        self, frame: GarmentFrame, outline_xy: np.ndarray, hidden: np.ndarray | None = None
    ) -> tuple[dict[str, _Found], set[str]]:
        """The keypoints found on the outline (N×2 world x, y; `hidden`: bool per point, the arm
        hides the edge there) in `frame` (garment u, v), and those the arm hides (unseen)."""
        uv = frame.to_frame(outline_xy)
        hidden = np.zeros(len(uv), bool) if hidden is None else np.asarray(hidden, bool)
        area = 0.5 * float(
            np.sum(uv[:, 0] * np.roll(uv[:, 1], -1) - np.roll(uv[:, 0], -1) * uv[:, 1])
        )
        if area < 0:
            uv, hidden = uv[::-1].copy(), hidden[::-1].copy()
        finder = _Finder(_Outline(uv, hidden), self.config)
        found = finder.tshirt() if self.kind == "tshirt" else finder.pants()
        return found, finder.unseen

    def estimate(self, obs: Observation) -> ClothState:
        """ClothState of `obs` with this garment's keypoints (all of them, but a neck the arm
        hides); detected=False (`reason` says why) when there is no cloth, it reaches the image
        border or is not recognised as a flat garment of this kind (not mirror-symmetric, a
        keypoint not found).

        Raises PerceptionError on malformed input (shapes, dtypes, empty images, bad K, no depth).
        """
        cfg = self.config
        seg = segment_cloth(obs, cfg.segmentation)
        pw = seg.plane_world
        plane = np.r_[pw.normal, pw.offset]
        shape = seg.mask.shape

        def missing(reason: str) -> ClothState:
            return ClothState.not_detected(reason, shape, table_plane=plane, stamp=obs.stamp)

        if not seg.found:
            return missing(NO_CLOTH)
        contour = _largest_contour(seg.mask)
        if contour is None:
            return missing(NO_CLOTH)
        h, w = shape
        b = BORDER_PX
        if (
            contour[:, 0].min() < b
            or contour[:, 1].min() < b
            or contour[:, 0].max() > w - 1 - b
            or contour[:, 1].max() > h - 1 - b
        ):
            return missing(f"the {self.kind} reaches the image border (its outline is cut)")
        stats = visible_heights(seg)
        if stats is None:
            return missing("cloth pixels have no depth")
        p5, h_med, p95 = stats
        # Which outline pixels lie on the arm, read before the colour outline's half-pixel shift
        # moves some of them off it.
        hidden = outline_hidden(seg.occluder, contour)
        if seg.cue == "colour":
            contour = _edge_corrected(contour)
        outline, coverage = lift_outline(obs, pw, contour, h_med)
        if coverage < cfg.segmentation.min_area or not np.all(np.isfinite(outline)):
            return missing(NO_CLOTH)

        frame = symmetry_axis(outline[:, :2], cfg, hidden)
        if frame.residual > cfg.max_residual:
            where = " where the arm hides none of it" if hidden.any() else ""
            return missing(
                f"not a flat {self.kind}: the outline is {1000 * frame.residual:.1f} mm from "
                f"mirror-symmetric{where} (at most {1000 * cfg.max_residual:.1f} mm)"
            )
        # The top on the prior's side first; the other way round where that finds no garment, or
        # one only with a keypoint the arm hides (the arm over a hem's middle reads as a hidden
        # neck: a shirt lying the other way round, its neck in sight, was taken upside down).
        tries = []
        for way in (frame, frame.flipped()):
            found, unseen = self._keypoints(way, outline[:, :2], hidden)
            lost = [n for n in self.names if n not in found and n not in unseen]
            tries.append(((len(lost), len(unseen)), way, found, lost, unseen))
            if not lost and not unseen:
                break
        _, frame, found, lost, unseen = min(tries, key=lambda t: t[0])  # ties: the prior's way
        if lost:
            return missing(f"not a flat {self.kind}: not found: {', '.join(lost)}")
        names = [n for n in self.names if n in found]
        found = mirrored_where_hidden(found, frame, outline[hidden, :2], cfg.corner_reach)

        axis_q = math.exp(-((frame.residual / cfg.symmetry_scale) ** 2))
        xy = frame.to_world(np.array([found[n].uv for n in names]))
        px, _ = project_points(_on_plane(pw, xy, h_med), obs.intrinsics, obs.T_world_camera)
        heights = local_heights(seg, px, cfg.height_radius_px, h_med)
        xyz = lift_pixels(obs, pw, px, heights)
        near = _near_occluder(seg.occluder, px, 4 * BORDER_PX + cfg.height_radius_px)
        keypoints: dict[str, tuple[np.ndarray, float]] = {}
        for k, n in enumerate(names):
            conf = axis_q * found[n].quality * (0.3 if near[k] else 1.0)
            keypoints[n] = (xyz[k], float(np.clip(conf, 0.0, 1.0)))
        hides = f"; the arm hides the {', '.join(sorted(unseen))}" if unseen else ""
        return ClothState(
            detected=True,
            reason=f"segmented by {seg.cue}{hides}",
            keypoints=keypoints,
            mask=seg.mask,
            coverage_m2=float(coverage),
            flatness=float(p95 - p5),
            outline_world=outline,
            table_plane=plane,
            stamp=float(obs.stamp),
        )


def outline_hidden(occluder: np.ndarray, contour: np.ndarray) -> np.ndarray:
    """Bool per outline point (contour N×2 px): on the occluder, where the amodal mask's outline
    is the hull drawn across what the arm hides rather than the cloth's edge."""
    occ = np.asarray(occluder, dtype=bool)
    if not occ.any():
        return np.zeros(len(contour), bool)
    px = np.rint(np.asarray(contour, dtype=float).reshape(-1, 2)).astype(int)
    u = np.clip(px[:, 0], 0, occ.shape[1] - 1)
    v = np.clip(px[:, 1], 0, occ.shape[0] - 1)
    return occ[v, u]


def mirrored_where_hidden(
    found: dict[str, _Found], frame: GarmentFrame, hidden_xy: np.ndarray, reach: float
) -> dict[str, _Found]:
    """`found` with each left or right keypoint that has outline hidden by the arm within
    `reach` (m) of it taken as the mirror image of its partner across the garment's axis, where
    the arm hides nothing near the partner: behind the arm the outline is the amodal mask's hull,
    whose corner can lie centimetres off (8 of the `pants` suite's 20 waist corners, under the
    gripper parked at home: 10–39 mm)."""
    if len(hidden_xy) == 0:
        return found
    tree = cKDTree(np.asarray(hidden_xy, dtype=float).reshape(-1, 2))

    def near(name: str) -> bool:
        return bool(tree.query_ball_point(frame.to_world(found[name].uv)[0], reach))

    out = dict(found)
    for name in found:
        side, _, part = name.partition("_")
        if side not in ("left", "right"):
            continue
        partner = ("right" if side == "left" else "left") + "_" + part
        if partner in found and near(name) and not near(partner):
            u, v = found[partner].uv
            out[name] = _Found(np.array([-u, v]), found[partner].quality)
    return out


def _near_occluder(occluder: np.ndarray, px: np.ndarray, radius: int) -> np.ndarray:
    """Bool per pixel (K×2): an occluder pixel lies within `radius` px."""
    out = np.zeros(len(px), bool)
    if not occluder.any():
        return out
    h, w = occluder.shape
    for k, (u, v) in enumerate(np.rint(px).astype(int)):
        u0, u1 = max(0, u - radius), min(w, u + radius + 1)
        v0, v1 = max(0, v - radius), min(h, v + radius + 1)
        out[k] = u0 < u1 and v0 < v1 and bool(occluder[v0:v1, u0:u1].any())
    return out
