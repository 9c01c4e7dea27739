"""Overlays for people: estimated outline and corners, planned grasp/place points, fold line;
and contact sheets that tile a run's overlays into one picture."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from foldbot.perception.geometry import check_observation, project_points
from foldbot.perception.state import ClothState
from foldbot.types import Observation

OUTLINE_RGB = (40, 230, 40)
KEYPOINT_RGB = (255, 220, 0)
GRASP_RGB = (255, 40, 40)
PLACE_RGB = (40, 200, 255)
FOLD_LINE_RGB = (255, 255, 255)
REFERENCE_RGB = (255, 0, 255)
UNCOVERED_RGB = (255, 120, 0)
EXPECTED_RGB = (255, 150, 0)


def _points(value: np.ndarray | Sequence[Sequence[float]] | None) -> np.ndarray:
    if value is None:
        return np.zeros((0, 3))
    return np.asarray(value, dtype=float).reshape(-1, 3)


def _px(uv: np.ndarray) -> tuple[int, int]:
    """Nearest integer pixel of a sub-pixel position (u, v)."""
    return int(np.rint(uv[0])), int(np.rint(uv[1]))


_OUTLINE_OFFSETS = ((-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1))


def _text(img: np.ndarray, text: str, org: tuple[int, int], color: tuple[int, int, int]) -> None:
    """`text` in `color` with a 1-pixel black outline, readable on any background. The outline is
    the same 1-pixel-stroke text shifted by a pixel each way: OpenCV advances each character by
    its stroke thickness, so a thick black copy underneath would drift right of the text."""
    x, y = org
    for dx, dy in _OUTLINE_OFFSETS:
        cv2.putText(
            img, text, (x + dx, y + dy), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA
        )
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, 0.4, color, 1, cv2.LINE_AA)


def draw_overlay(
    obs: Observation,
    state: ClothState,
    grasp_points: np.ndarray | Sequence[Sequence[float]] | None = None,
    place_points: np.ndarray | Sequence[Sequence[float]] | None = None,
    fold_line: np.ndarray | Sequence[Sequence[float]] | None = None,
    reference: dict[str, np.ndarray] | None = None,
    uncovered: np.ndarray | None = None,
    expected_outline: np.ndarray | Sequence[Sequence[float]] | None = None,
    expected_parts: Sequence[np.ndarray] | None = None,
) -> np.ndarray:
    """RGB image (H×W×3 uint8) of `obs` with the state's outline and labelled corners drawn on.

    Optional world points (N×3, m) are projected with the observation's camera: planned grasp
    points (red crosses), place points (blue circles, joined to their grasp point), a fold line
    given by two points (white), and `reference` corners (e.g. the oracle's, magenta) by label.
    `uncovered` (H×W bool) tints, in orange, what a fold's laid layer left uncovered.
    `expected_outline` (N×3 world points, a closed polygon) is the outline the cloth should take,
    e.g. flattening's expected rectangle (orange); `expected_parts`, several such polygons (a
    folded garment's predicted pieces), drawn alike.
    """
    check_observation(obs)
    img = np.ascontiguousarray(obs.rgb.copy())
    if uncovered is not None and np.shape(uncovered) == img.shape[:2]:
        tint = np.asarray(uncovered, bool)
        img[tint] = (0.2 * img[tint] + 0.8 * np.array(UNCOVERED_RGB)).astype(np.uint8)
    intr, T = obs.intrinsics, obs.T_world_camera

    def proj(points: np.ndarray) -> np.ndarray:
        if len(points) == 0:
            return np.zeros((0, 2))
        uv, _ = project_points(points, intr, T)
        return uv

    for polygon in [expected_outline, *(expected_parts or ())]:
        expected = _points(polygon)
        if len(expected) >= 3:
            uv = np.round(proj(expected)).astype(np.int32)
            cv2.polylines(img, [uv], True, EXPECTED_RGB, 1, cv2.LINE_AA)
    if state.detected and len(state.outline_world) >= 3:
        uv = proj(state.outline_world)
        cv2.polylines(img, [np.round(uv).astype(np.int32)], True, OUTLINE_RGB, 1, cv2.LINE_AA)
    if reference:
        for name, xyz in reference.items():
            del name
            cv2.drawMarker(
                img, _px(proj(_points(xyz))[0]), REFERENCE_RGB, cv2.MARKER_TILTED_CROSS, 9
            )
    for name, (xyz, conf) in state.keypoints.items():
        c = _px(proj(_points(xyz))[0])
        cv2.circle(img, c, 4, KEYPOINT_RGB, 1, cv2.LINE_AA)
        _text(img, f"{name} {conf:.2f}", (c[0] + 6, c[1] - 6), KEYPOINT_RGB)
    grasp, place = _points(grasp_points), _points(place_points)
    g_uv, p_uv = proj(grasp), proj(place)
    for k, uv in enumerate(g_uv):
        c = _px(uv)
        cv2.drawMarker(img, c, GRASP_RGB, cv2.MARKER_CROSS, 12, 2)
        if k < len(p_uv):
            cv2.arrowedLine(img, c, _px(p_uv[k]), GRASP_RGB, 1, cv2.LINE_AA, tipLength=0.05)
    for uv in p_uv:
        cv2.circle(img, _px(uv), 6, PLACE_RGB, 2, cv2.LINE_AA)
    line = _points(fold_line)
    if len(line) >= 2:
        a, b = proj(line[:2])
        cv2.line(
            img,
            _px(a),
            _px(b),
            FOLD_LINE_RGB,
            1,
            cv2.LINE_AA,
        )
    status = state.reason if state.reason else ("cloth" if state.detected else "no cloth")
    _text(img, status, (8, 16), (255, 255, 255))
    return img


def contact_sheet(
    images: Sequence[np.ndarray],
    captions: Sequence[str],
    columns: int = 4,
    scale: float = 0.5,
) -> np.ndarray:
    """One RGB image (uint8) tiling `images` (equal-sized H×W×3 uint8), each scaled by `scale`
    and captioned above, `columns` to a row: a run's steps side by side at a glance."""
    if len(images) == 0:
        raise ValueError("contact_sheet needs at least one image, got none")
    if len(captions) != len(images):
        raise ValueError(f"contact_sheet got {len(images)} images but {len(captions)} captions")
    if not isinstance(columns, int) or columns < 1:
        raise ValueError(f"contact_sheet columns must be an integer >= 1, got {columns!r}")
    if not 0.0 < scale <= 1.0:
        raise ValueError(f"contact_sheet scale must be in (0, 1], got {scale!r}")
    shape = np.shape(images[0])
    for k, image in enumerate(images):
        if np.shape(image) != shape or len(shape) != 3 or shape[2] != 3:
            raise ValueError(
                f"contact_sheet images must all be H×W×3 like the first {shape}; "
                f"image {k} is {np.shape(image)}"
            )
    h, w = max(1, round(shape[0] * scale)), max(1, round(shape[1] * scale))
    bar = 20
    tiles = []
    for image, caption in zip(images, captions, strict=True):
        tile = np.zeros((h + bar, w, 3), np.uint8)
        tile[bar:] = cv2.resize(np.asarray(image, np.uint8), (w, h), interpolation=cv2.INTER_AREA)
        _text(tile, caption, (4, 14), (255, 255, 255))
        tiles.append(tile)
    columns = min(columns, len(tiles))
    tiles += [np.zeros_like(tiles[0])] * (-len(tiles) % columns)
    rows = [np.hstack(tiles[k : k + columns]) for k in range(0, len(tiles), columns)]
    return np.vstack(rows)
