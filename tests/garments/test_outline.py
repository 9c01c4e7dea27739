"""Outline → mesh: valid triangles, exact keypoints, the outline as the mesh's boundary."""

import math

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.garments.outline import (
    MIN_ANGLE_DEG,
    Outline,
    mesh_boundary_loops,
    outline_mesh,
    points_inside,
    resample,
    triangle_angles,
)

SQUARE = np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 0.2], [0.0, 0.2]])
# A U shape: a deep concave notch from the top (like the gap between two legs).
U_SHAPE = np.array(
    [[-0.1, 0.0], [-0.02, 0.0], [-0.02, 0.12], [0.02, 0.12], [0.02, 0.0], [0.1, 0.0],
     [0.1, 0.2], [-0.1, 0.2]]
)  # fmt: skip


def _check_valid(mesh, outline_area: float) -> None:
    v, f = mesh.vertices, mesh.faces
    assert np.all(v[:, 2] == 0.0)
    lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)
    np.testing.assert_allclose(lo + hi, 0.0, atol=1e-12)  # bounding box centred
    assert math.degrees(triangle_angles(v, f).min()) >= MIN_ANGLE_DEG
    assert mesh.area == pytest.approx(outline_area, rel=1e-9)
    used = np.zeros(len(v), bool)
    used[f.ravel()] = True
    assert used.all()
    # Counter-clockwise triangles (normals up) and one boundary loop (one piece, no holes).
    p = v[f][..., :2]
    cross = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (
        p[:, 2, 0] - p[:, 0, 0]
    )
    assert np.all(cross > 0)
    assert len(mesh_boundary_loops(f)) == 1


def test_square_mesh_is_valid_with_corners_as_keypoints() -> None:
    outline = Outline(SQUARE, keypoints={"a": 0, "c": 2})
    mesh = outline_mesh(outline, 0.02)
    _check_valid(mesh, 0.04)
    assert np.allclose(mesh.vertices[mesh.keypoints["a"], :2], [-0.1, -0.1])
    assert np.allclose(mesh.vertices[mesh.keypoints["c"], :2], [0.1, 0.1])
    assert mesh.grid_shape is None
    assert mesh.edge_length == pytest.approx(0.02, rel=0.15)


def test_concave_notch_is_left_out() -> None:
    outline = Outline(U_SHAPE, keypoints={"notch": 3}, corners=tuple(range(8)))
    mesh = outline_mesh(outline, 0.02)
    _check_valid(mesh, outline.area)
    # No triangle reaches into the notch.
    centroids = mesh.vertices[mesh.faces].mean(axis=1)[:, :2]
    shift = mesh.vertices[mesh.keypoints["notch"], :2] - U_SHAPE[3]
    assert points_inside(centroids, U_SHAPE + shift).all()


def test_boundary_is_the_resampled_outline_with_exact_keypoints() -> None:
    outline = Outline(U_SHAPE, keypoints={"left": 0, "top": 6}, corners=tuple(range(8)))
    boundary, kp = resample(outline, 0.02)
    seg = np.linalg.norm(np.roll(boundary, -1, axis=0) - boundary, axis=1)
    assert seg.max() <= 0.02 * 1.5 and seg.min() >= 0.02 * 0.6
    np.testing.assert_allclose(boundary[kp["top"]], U_SHAPE[6])
    mesh = outline_mesh(outline, 0.02)
    (loop,) = mesh_boundary_loops(mesh.faces)
    assert len(loop) == len(boundary)
    for name in ("left", "top"):
        assert mesh.keypoints[name] in loop
    # Every original corner is a mesh vertex (shifted with the bounding box).
    shift = mesh.vertices[mesh.keypoints["left"], :2] - U_SHAPE[0]
    d = np.linalg.norm(mesh.vertices[:, None, :2] - (U_SHAPE + shift)[None], axis=2).min(axis=0)
    assert d.max() < 1e-12


def test_symmetric_outline_gives_a_symmetric_mesh_without_smoothing() -> None:
    mesh = outline_mesh(Outline(U_SHAPE, corners=tuple(range(8))), 0.02, smoothing=0)
    v = mesh.vertices[:, :2]
    mirrored = v * [-1.0, 1.0]
    d = np.linalg.norm(v[:, None] - mirrored[None], axis=2).min(axis=1)
    assert d.max() < 1e-9


@pytest.mark.parametrize(
    ("points", "kwargs", "needle"),
    [
        (SQUARE[::-1], {}, "counter-clockwise"),
        (np.array([[0, 0], [1, 1], [1, 0], [0, 1]], float), {}, "cross"),
        (SQUARE, {"keypoints": {"tip": 9}}, "'tip'"),
        (SQUARE[:2], {}, "N ≥ 3"),
        (np.array([[0, 0], [1, 0], [1, 0], [0, 1]], float), {}, "repeat"),
    ],
)
def test_bad_outlines_say_what_is_wrong(points, kwargs, needle) -> None:
    with pytest.raises(ConfigError, match=needle):
        Outline(points, **kwargs)


@pytest.mark.parametrize("edge", [0.0, 0.001, 0.5, float("nan")])
def test_bad_edge_length_is_named(edge) -> None:
    with pytest.raises(ConfigError, match="edge_length"):
        outline_mesh(Outline(SQUARE), edge)


def test_too_coarse_for_a_thin_feature_is_refused() -> None:
    # A 4 mm wide slot cannot be meshed at 2 cm edges without sliver triangles.
    slot = U_SHAPE.copy()
    slot[[1, 2], 0], slot[[3, 4], 0] = -0.002, 0.002
    with pytest.raises(ConfigError, match=r"edge_length 0\.02"):
        outline_mesh(Outline(slot, corners=tuple(range(8))), 0.02)
