"""Where to grasp and place on the cloth seen now: geometry on perceived states (ClothState and
the RGB-D frame), shared by the towel loop (foldbot.loop) and the garment loop.

A corner that earlier actions dragged is found by its label, its position or the moving side's
tip; a stack is grasped at the table under every layer; what is left past a fold line is carried
from its tip; a placement is checked only where it should make a corner.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial import ConvexHull

from foldbot.metrics import FoldLine
from foldbot.perception.geometry import backproject, backproject_pixel, project_points
from foldbot.perception.keypoints import max_area_quad
from foldbot.perception.segmentation import SegmentationConfig
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.types import Observation

GRASP_INSET = 0.01
"""A grasp moved onto the cloth lands this far (m) inside the perceived outline."""
TIP_BAND = 0.01
"""Outline points within this (m) of the farthest one from the line tie for the tip."""
MIN_LEFT = 0.03
"""Cloth reaching less than this (m) past a stage's fold line is the crease's bulge, not cloth
left to fold: a from-tip or finishing action runs only when more is left."""
ARM_HEIGHT = SegmentationConfig().occluder_height
"""A surface seen higher than this (m) above the table is the arm or gripper, never cloth (the
segmentation's occluder rule)."""
SURFACE_SEARCH_RADII = (4, 8, 12, 16, 24)
"""Pixel radii searched, nearest first, for cloth beside a grasp point the arm hides."""


def nearest_keypoint(state: ClothState, point: np.ndarray, radius: float) -> np.ndarray | None:
    """The perceived keypoint nearest `point` in the table plane, if within `radius`."""
    if not state.detected or not state.keypoints:
        return None
    pts = np.array([xyz for xyz, _conf in state.keypoints.values()])
    d = np.linalg.norm(pts[:, :2] - point[:2], axis=1)
    k = int(np.argmin(d))
    return pts[k] if d[k] <= radius else None


def moving_side_tip(
    state: ClothState, line: tuple[float, float, float, float], near: np.ndarray, band: float
) -> np.ndarray | None:
    """The perceived outline's point on the moving side of `line` that lies farthest from it (within
    `band`, the one nearest `near`), or None when no cloth is left there.

    Once the stage's first corner is folded, the cloth still on the moving side is the part that
    hangs on the corner not yet carried, so its farthest point from the line is that corner, even
    where the first carry dragged it into a shape the four-corner detector fits poorly."""
    outline = np.asarray(state.outline_world, dtype=float).reshape(-1, 3)
    if not state.detected or len(outline) < 3:
        return None
    return farthest_past(outline, line, near, band)


def farthest_past(
    points: np.ndarray, line: tuple[float, float, float, float], near: np.ndarray, band: float
) -> np.ndarray | None:
    """Of `points` (N×3), the one on the moving side of `line` farthest from it (within `band`,
    the one nearest `near`), or None when none lies more than `band` past it."""
    x, y, dx, dy = line
    normal = np.array([-dy, dx]) / max(float(np.hypot(dx, dy)), 1e-12)
    s = (points[:, :2] - [x, y]) @ normal
    if len(s) == 0 or s.max() <= band:
        return None
    cand = points[s >= s.max() - band]
    k = int(np.argmin(np.linalg.norm(cand[:, :2] - near[:2], axis=1)))
    return cand[k]


def regrasp_point(
    state: ClothState,
    label: str,
    planned: np.ndarray,
    radius: float,
    label_radius: float,
    line: tuple[float, float, float, float] | None = None,
    tip_gap: float = 0.015,
) -> np.ndarray | None:
    """Where to grasp a corner now: the keypoint with the planned label if it lies within
    `label_radius` of the plan (a fold drags the other corners by up to ~15 cm), else the
    keypoint nearest the plan within `radius`.

    With the stage's fold `line` given, a corner still on the moving side is checked against the
    outline: where the moving side's tip nearest that keypoint lies more than `tip_gap` from it, the
    keypoint is a poor fit of a dragged corner and the tip is taken instead, at the planned height
    (the corner not yet carried lies in one layer on the table)."""
    seen = None
    if state.detected and label in state.keypoints:
        xyz = np.asarray(state.keypoints[label][0])
        if np.linalg.norm(xyz[:2] - planned[:2]) <= label_radius:
            seen = xyz
    if seen is None:
        seen = nearest_keypoint(state, planned, radius)
    if line is None:
        return seen
    x, y, dx, dy = line
    if (planned[1] - y) * dx - (planned[0] - x) * dy <= 0.01 * float(np.hypot(dx, dy)):
        return seen  # not a corner still to be carried (e.g. one placed off, to be re-placed)
    near = planned if seen is None else seen
    tip = moving_side_tip(state, line, near, band=0.01)
    if tip is None or np.linalg.norm(tip[:2] - planned[:2]) > label_radius:
        return seen
    if seen is None or np.linalg.norm(tip[:2] - seen[:2]) > tip_gap:
        return np.array([tip[0], tip[1], planned[2]])
    return seen


def stack_grasp_point(state: ClothState, point: np.ndarray, height: float) -> np.ndarray:
    """`point` lowered to `height` above the perceived table plane under it, so the jaws close
    under every layer of a stack (unchanged without a usable table plane)."""
    a, b, c, d = (float(v) for v in np.asarray(state.table_plane, dtype=float).reshape(4))
    if c < 0.5:
        return np.asarray(point, dtype=float)
    z_table = -(a * point[0] + b * point[1] + d) / c
    return np.array([point[0], point[1], min(float(point[2]), z_table + height)])


def surface_height(
    obs: Observation,
    point: np.ndarray,
    radius: int = 2,
    table_plane: np.ndarray | None = None,
) -> float | None:
    """Height (world z, m) of the surface the camera sees at `point`'s x, y (robust depth around
    its pixel); None when that pixel is outside the image or has no depth. Given the
    `table_plane` (a, b, c, d), a surface more than ARM_HEIGHT above it is the arm hiding the
    cloth there (parked over a garment's waist, say), so the height is the cloth's nearest beside
    it (SURFACE_SEARCH_RADII), or None when the arm hides all of that."""
    uv, z = project_points(
        np.asarray(point, dtype=float)[None, :], obs.intrinsics, obs.T_world_camera
    )
    (u, v), h, w = uv[0], obs.intrinsics.height, obs.intrinsics.width
    if not (z[0] > 0 and 0 <= u < w and 0 <= v < h):
        return None
    plane = None if table_plane is None else np.asarray(table_plane, dtype=float).reshape(-1)
    if plane is None or plane.size != 4 or not np.any(plane[:3]):
        seen = backproject_pixel(obs, float(u), float(v), radius)
        return float(seen[2]) if np.all(np.isfinite(seen)) else None
    for r in (radius, *(q for q in SURFACE_SEARCH_RADII if q > radius)):
        pts = _window_points(obs, float(u), float(v), r)
        if len(pts) == 0:
            continue
        cloth = pts[pts @ plane[:3] + plane[3] <= ARM_HEIGHT]
        if r == radius and len(cloth) == len(pts):
            # Nothing of the arm in sight: the plain robust lookup, as without a table plane.
            seen = backproject_pixel(obs, float(u), float(v), radius)
            return float(seen[2]) if np.all(np.isfinite(seen)) else None
        if len(cloth):
            return float(np.median(cloth[:, 2]))
    return None


def _window_points(obs: Observation, u: float, v: float, radius: int) -> np.ndarray:
    """World points (N×3) of the pixels with depth in the (2r+1)² window at pixel (u, v)."""
    rows, cols = obs.depth.shape
    c, r = int(np.rint(u)), int(np.rint(v))
    vv, uu = np.mgrid[
        max(0, r - radius) : min(rows, r + radius + 1),
        max(0, c - radius) : min(cols, c + radius + 1),
    ]
    depth = obs.depth[vv, uu].astype(float)
    ok = np.isfinite(depth) & (depth > 0)
    uv = np.stack([uu[ok], vv[ok]], axis=1).astype(float)
    return backproject(uv, depth[ok], obs.intrinsics, obs.T_world_camera)


def tip_action(
    state: ClothState, planned: FoldAction, inset: float = GRASP_INSET
) -> FoldAction | None:
    """The action that carries the cloth left on `planned`'s moving side from its tip: the outline
    point farthest from the line (ties: nearest the planned grasp), `inset` back toward the line,
    placed at its mirror; None when the cloth reaches less than MIN_LEFT past the line."""
    line = FoldLine(*planned.fold_line)
    outline = np.asarray(state.outline_world, dtype=float).reshape(-1, 3)
    if (
        not state.detected
        or len(outline) < 3
        or line.side(outline).max() < MIN_LEFT * np.hypot(line.dx, line.dy)
    ):
        return None
    tip = moving_side_tip(state, planned.fold_line, planned.grasp, band=TIP_BAND)
    if tip is None:
        return None
    return carried_to_mirror(planned, tip, inset, planned.grasp[2])


def carried_to_mirror(
    planned: FoldAction, tip: np.ndarray, inset: float, height: float
) -> FoldAction:
    """`planned` grasping at `tip` moved `inset` (m) back toward its line, at `height`, and
    placing at the grasp's mirror across the line (at the planned place's height)."""
    line = FoldLine(*planned.fold_line)
    normal = np.array([-line.dy, line.dx]) / np.hypot(line.dx, line.dy)  # toward the moving side
    grasp = np.array([*(tip[:2] - normal * inset), height])
    place = line.reflect_xy(grasp)
    place[2] = planned.place[2]
    return dataclasses.replace(planned, grasp=grasp, place=place)


def top_layer_action(
    laid: np.ndarray, planned: FoldAction, inset: float = GRASP_INSET
) -> FoldAction | None:
    """The action that carries, from its own tip, the top layer of a stack carried from its tip:
    `laid` (N×3) are the points of the layer the previous stage laid (seen in depth,
    perception.layers.mask_points); its point farthest past `planned`'s line (ties: nearest the
    planned grasp), `inset` back toward the line, placed at its mirror. None when that layer
    reaches less than MIN_LEFT past the line.

    Folded over together, the stack's top layer is held by nothing where it ends short of the
    bottom layer's tip, and slides off into the crease; carried first, it goes over on its own and
    the bottom layer, carried next from its tip, folds over it, the order the goal wants."""
    pts = np.asarray(laid, dtype=float).reshape(-1, 3)
    line = FoldLine(*planned.fold_line)
    if len(pts) == 0 or line.side(pts).max() < MIN_LEFT * np.hypot(line.dx, line.dy):
        return None
    tip = farthest_past(pts, planned.fold_line, planned.grasp, TIP_BAND)
    if tip is None:
        return None
    return dataclasses.replace(carried_to_mirror(planned, tip, inset, tip[2]), layers=1)


def finish_action(state: ClothState, obs: Observation, last: FoldAction) -> FoldAction | None:
    """After a stage's planned actions: the action that carries cloth still left past the stage's
    fold line over it, from its tip, grasped at the surface the camera sees there (one layer), or
    None when no more than the crease's bulge is left."""
    extra = tip_action(state, last)
    if extra is None:
        return None
    top = surface_height(obs, extra.grasp, table_plane=state.table_plane)
    grasp = extra.grasp if top is None else np.r_[extra.grasp[:2], top]
    return dataclasses.replace(extra, grasp=grasp, label=f"finish_{last.label}", layers=1)


CORNER_TURN = np.radians(30.0)
"""An outline vertex whose boundary turns by at least this much is a corner the keypoint detector
finds; a shallower one is a bump on a side."""


def outline_corners(outline: np.ndarray, min_turn: float = CORNER_TURN) -> np.ndarray:
    """The corners a perceived keypoint can stand for on a counter-clockwise outline (N×2 or N×3):
    as the towel detector does, the largest-area quad on its convex hull, of which the vertices
    where the boundary turns left by at least `min_turn` (rad). A small bump on a side (a folded
    corner just past it) is no corner."""
    pts = np.asarray(outline, dtype=float).reshape(len(outline), -1)
    if len(pts) < 3:
        return pts
    if len(pts) > 4:
        hull = pts[ConvexHull(pts[:, :2]).vertices]
        pts = hull[max_area_quad(hull[:, :2])]
    xy = pts[:, :2]
    into = xy - np.roll(xy, 1, axis=0)
    out = np.roll(xy, -1, axis=0) - xy
    turn = np.arctan2(into[:, 0] * out[:, 1] - into[:, 1] * out[:, 0], np.sum(into * out, axis=1))
    return pts[turn >= min_turn]


ON_CORNER = 0.005
"""A planned place within this (m) of a corner of the outline its stage should leave makes that
corner: both come from the same perceived corners (in the benchmark's half folds they lie under
1 mm apart). Thirds' second stage lays its far corners twice its crease room (about 2.5 cm)
short of the stack's crease corners, on its sides: no corner there, nor is checked a one-arm
quarter fold's second-stage place 5-30 mm from its predicted corner (docs/experiments.md)."""


def place_is_corner(place: np.ndarray, corners: np.ndarray | None, tol: float = ON_CORNER) -> bool:
    """Whether a place point is one of `corners`, the corners of the outline the stage should leave
    (within `tol`, m): only there can the placed corner be checked against a perceived corner
    keypoint. A corner laid inside the outline or on its side (thirds' first and second stages)
    is no keypoint; the stage check covers it. Without predicted corners every place is checked."""
    if corners is None:
        return True
    if len(corners) == 0:
        return False
    d = np.linalg.norm(np.asarray(corners)[:, :2] - np.asarray(place)[:2], axis=1)
    return bool(d.min() <= tol)


def shifted_grasp(action: FoldAction, shift: np.ndarray) -> FoldAction:
    """`action` with its grasp moved by `shift` (x, y; m) and its place by the mirror image of that
    shift across the fold line, so the point the grasp was aimed at still lands on its place."""
    shift = np.asarray(shift, dtype=float)[:2]
    line = FoldLine(*action.fold_line)
    d = np.array([line.dx, line.dy]) / np.hypot(line.dx, line.dy)
    mirrored = 2 * (shift @ d) * d - shift
    grasp = np.r_[action.grasp[:2] + shift, action.grasp[2]]
    place = np.r_[action.place[:2] + mirrored, action.place[2]]
    return dataclasses.replace(action, grasp=grasp, place=place)


def inset_grasp(
    state: ClothState, action: FoldAction, corner: np.ndarray, inset: float
) -> FoldAction:
    """`action` with its grasp moved `inset` (m) from `corner` toward the perceived cloth's centre
    (see shifted_grasp)."""
    if inset <= 0 or not state.detected:
        return action
    outline = np.asarray(state.outline_world, dtype=float).reshape(-1, 3)
    centre = (
        outline[:, :2].mean(axis=0) if len(outline) >= 3 else state.keypoint_array()[:, :2].mean(0)
    )
    return inset_toward(action, corner, centre, inset)


def inset_toward(
    action: FoldAction, corner: np.ndarray, centre: np.ndarray, inset: float
) -> FoldAction:
    """`action` with its grasp moved `inset` (m) from `corner` toward `centre` (x, y; see
    shifted_grasp); unchanged where `corner` lies within 2 × `inset` of it."""
    if inset <= 0:
        return action
    inward = np.asarray(centre, dtype=float)[:2] - np.asarray(corner, dtype=float)[:2]
    norm = float(np.linalg.norm(inward))
    if norm < 2 * inset:
        return action
    return shifted_grasp(action, inward / norm * inset)
