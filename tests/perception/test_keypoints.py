"""Corner labelling rule and sub-pixel corner detection on synthetic masks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foldbot.errors import PerceptionError
from foldbot.perception.keypoints import (
    CORNER_LABELS,
    NEAR_LEFT_ANGLE,
    find_corners,
    label_corners,
    max_area_quad,
)


def _rect(w: float, h: float, yaw: float, centre=(0.45, 0.0)) -> np.ndarray:
    half = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2
    c, s = math.cos(yaw), math.sin(yaw)
    return half @ np.array([[c, -s], [s, c]]).T + np.asarray(centre)


def test_axis_aligned_labels() -> None:
    pts = _rect(0.3, 0.2, 0.0)  # rows: (−x,−y), (+x,−y), (+x,+y), (−x,+y)
    assert label_corners(pts) == {"near_left": 3, "near_right": 0, "far_right": 1, "far_left": 2}


def test_labels_do_not_depend_on_input_order() -> None:
    pts = _rect(0.3, 0.25, 0.7)
    ref = {name: tuple(pts[i]) for name, i in label_corners(pts).items()}
    for perm in ([1, 2, 3, 0], [3, 1, 0, 2], [2, 0, 3, 1]):
        got = {name: tuple(pts[perm][i]) for name, i in label_corners(pts[perm]).items()}
        assert got == ref


@pytest.mark.parametrize(("w", "h"), [(0.3, 0.3), (0.4, 0.22), (0.2, 0.45)])
def test_labels_follow_rotation_and_jump_only_at_documented_ties(w: float, h: float) -> None:
    """Turning the cloth by 0.5° steps: a label stays on its physical corner, except that all
    labels move on by one place exactly where two corners are equally far from 135°."""
    step = math.radians(0.5)
    prev = None
    jumps = []
    for k in range(int(2 * math.pi / step) + 1):
        yaw = k * step
        labels = label_corners(_rect(w, h, yaw))
        physical = [labels[name] for name in CORNER_LABELS]  # physical corner index per label
        if prev is not None and physical != prev:
            shift = [(physical.index(i) - prev.index(i)) % 4 for i in range(4)]
            assert len(set(shift)) == 1 and shift[0] in (1, 3), (yaw, prev, physical)
            jumps.append(yaw - step / 2)
        prev = physical
    assert jumps, "a full turn must move the labels"
    for yaw in jumps:  # at each jump, two corners are equally far from the near-left direction
        pts = _rect(w, h, yaw)
        d = pts - pts.mean(axis=0)
        phi = np.arctan2(d[:, 1], d[:, 0])
        dist = np.sort(np.abs((phi - NEAR_LEFT_ANGLE + math.pi) % (2 * math.pi) - math.pi))
        assert dist[1] - dist[0] < 2 * step
    assert len(jumps) == 4  # a full turn moves every label once per quarter


def test_square_ties_are_at_45_degrees() -> None:
    before = label_corners(_rect(0.3, 0.3, math.radians(44.0)))
    after = label_corners(_rect(0.3, 0.3, math.radians(46.0)))
    assert before != after
    assert label_corners(_rect(0.3, 0.3, math.radians(10.0))) == label_corners(
        _rect(0.3, 0.3, math.radians(-10.0))
    )


def test_label_corners_rejects_bad_input() -> None:
    with pytest.raises(PerceptionError, match="4 finite points"):
        label_corners(np.zeros((3, 2)))
    with pytest.raises(PerceptionError, match="4 finite points"):
        label_corners(np.full((4, 2), np.nan))


def _polygon_mask(corners: np.ndarray, shape=(240, 320)) -> np.ndarray:
    """Exact point-sampled raster of a convex polygon: pixel (v, u) is in if (u, v) is inside."""
    v, u = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    signs = []
    for k in range(len(corners)):
        a, b = corners[k], corners[(k + 1) % len(corners)]
        signs.append((b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0]))
    signs = np.array(signs)
    return np.all(signs > 0, axis=0) | np.all(signs < 0, axis=0)


def _match(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.array([np.linalg.norm(found - t, axis=1).min() for t in truth])


@pytest.mark.parametrize("angle", [0.0, 0.3, 0.8, 1.2])
def test_find_corners_is_sub_pixel(angle: float) -> None:
    quad = np.array([[-70, -45], [70, -45], [60, 50], [-65, 45]], float)
    c, s = math.cos(angle), math.sin(angle)
    truth = quad @ np.array([[c, -s], [s, c]]).T + [160.3, 120.7]
    found = find_corners(_polygon_mask(truth))
    assert found is not None
    # A binary mask can place an axis-aligned edge only to within half a pixel.
    assert _match(found.uv, truth).max() < 0.6
    assert _match(found.uv, truth).mean() < 0.35
    assert np.all(found.confidence > 0.8)


def test_hidden_corner_is_extrapolated_with_lower_confidence() -> None:
    truth = np.array([[90.4, 60.2], [230.7, 70.1], [220.3, 180.6], [80.2, 170.4]])
    mask = _polygon_mask(truth)
    occluder = np.zeros_like(mask)
    occluder[40:95, 200:260] = True  # hides the corner at (230.7, 70.1)
    found = find_corners(mask & ~occluder, exclude=occluder)
    assert found is not None
    err = _match(found.uv, truth)
    assert err.max() < 1.0
    hidden = int(np.argmin(np.linalg.norm(found.uv - truth[1], axis=1)))
    assert found.confidence[hidden] < 0.6 < np.delete(found.confidence, hidden).min()


def test_find_corners_edge_cases() -> None:
    assert find_corners(np.zeros((50, 50), bool)) is None
    with pytest.raises(PerceptionError, match="H×W"):
        find_corners(np.zeros((5, 5, 3), bool))


def test_max_area_quad_picks_the_corners_of_a_dense_outline() -> None:
    truth = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]])
    dense = np.concatenate([np.linspace(truth[k], truth[(k + 1) % 4], 25)[:-1] for k in range(4)])
    idx = max_area_quad(dense)
    assert sorted(map(tuple, dense[idx])) == sorted(map(tuple, truth))
