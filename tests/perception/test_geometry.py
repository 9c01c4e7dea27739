"""Camera geometry: input checks, projection ↔ back-projection, planes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foldbot.errors import PerceptionError
from foldbot.perception.geometry import (
    Plane,
    backproject,
    backproject_pixel,
    check_observation,
    fit_plane_ransac,
    pixel_rays,
    polygon_area,
    project_points,
    robust_depth,
)
from foldbot.types import CameraIntrinsics, Observation

W, H = 64, 48


def _intrinsics(cx: float = 30.2, cy: float = 25.7) -> CameraIntrinsics:
    return CameraIntrinsics(W, H, np.array([[80.0, 0.0, cx], [0.0, 82.0, cy], [0.0, 0.0, 1.0]]))


def _pose(tilt: float = 0.4) -> np.ndarray:
    """A camera 1 m above the origin, looking down and tilted about world x."""
    c, s = math.cos(tilt), math.sin(tilt)
    down = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    T = np.eye(4)
    T[:3, :3] = rx @ down
    T[:3, 3] = [0.1, -0.2, 1.0]
    return T


def _obs(**kw) -> Observation:
    fields = {
        "rgb": np.zeros((H, W, 3), np.uint8),
        "depth": np.ones((H, W), np.float32),
        "intrinsics": _intrinsics(),
        "T_world_camera": _pose(),
    }
    fields.update(kw)
    return Observation(**fields)


def test_project_backproject_round_trip() -> None:
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(-0.3, 0.3, (50, 2)), rng.uniform(-0.05, 0.2, 50)]
    intr, T = _intrinsics(), _pose()
    uv, z = project_points(pts, intr, T)
    assert np.all(z > 0)
    back = backproject(uv, z, intr, T)
    np.testing.assert_allclose(back, pts, atol=1e-9)


def test_pixel_rays_hit_the_projected_points() -> None:
    pts = np.array([[0.05, 0.02, 0.0], [-0.1, 0.1, 0.0]])
    intr, T = _intrinsics(), _pose()
    uv, _ = project_points(pts, intr, T)
    origin, dirs = pixel_rays(uv, intr, T)
    hit = Plane(np.array([0.0, 0.0, 1.0]), 0.0).intersect(origin, dirs)
    np.testing.assert_allclose(hit, pts, atol=1e-9)


def test_robust_depth_ignores_holes_and_outliers() -> None:
    depth = np.full((H, W), 1.2, np.float32)
    depth[20:23, 30:33] = np.nan
    depth[21, 31] = 5.0
    depth[20, 30] = 0.0
    assert robust_depth(depth, 31.2, 20.6, radius=2) == pytest.approx(1.2)
    assert math.isnan(robust_depth(np.full((H, W), np.nan, np.float32), 3, 3))
    obs = _obs(depth=depth)
    p = backproject_pixel(obs, 31.0, 21.0, radius=3)
    assert np.all(np.isfinite(p))


def test_ransac_plane_with_outliers_and_up_prior() -> None:
    rng = np.random.default_rng(0)
    n = np.array([0.05, -0.03, 1.0])
    n /= np.linalg.norm(n)
    xy = rng.uniform(-1, 1, (400, 2))
    z = -(n[0] * xy[:, 0] + n[1] * xy[:, 1] + 0.7) / n[2]
    pts = np.c_[xy, z] + rng.normal(0, 1e-4, (400, 3))
    pts[:80, 2] += rng.uniform(0.05, 0.5, 80)  # clutter above the plane
    plane, inliers = fit_plane_ransac(pts, 0.002, rng, up=np.array([0.0, 0.0, 1.0]))
    assert plane.normal @ n == pytest.approx(1.0, abs=1e-4)
    assert plane.offset == pytest.approx(0.7, abs=1e-3)
    assert inliers[80:].mean() > 0.95 and inliers[:80].mean() < 0.1
    with pytest.raises(PerceptionError, match="at least 3"):
        fit_plane_ransac(pts[:2], 0.01, rng)


def test_plane_transform_and_polygon_area() -> None:
    plane = Plane(np.array([0.0, 0.0, 1.0]), -0.75)  # z = 0.75 in frame A
    T = _pose()
    p_a = np.array([[0.3, 0.1, 0.75]])
    p_b = p_a @ T[:3, :3].T + T[:3, 3]
    assert plane.transformed(T).height(p_b)[0] == pytest.approx(0.0, abs=1e-12)
    assert polygon_area(np.array([[0, 0], [2, 0], [2, 1], [0, 1]], float)) == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"rgb": np.zeros((H, W), np.uint8)}, "rgb must be H×W×3"),
        ({"rgb": np.zeros((H, W, 3), np.float32)}, "rgb must be uint8"),
        ({"depth": np.ones((H, W), np.uint16)}, "depth must be float"),
        ({"depth": np.ones((H, W, 1), np.float32)}, "depth must be H×W"),
        ({"depth": np.full((H, W), np.nan, np.float32)}, "no valid pixel"),
        ({"depth": np.ones((H, W - 1), np.float32)}, "differs from rgb"),
        (
            {"rgb": np.zeros((0, 0, 3), np.uint8), "depth": np.zeros((0, 0), np.float32)},
            "empty image",
        ),
        ({"intrinsics": CameraIntrinsics(W, H, np.eye(2))}, "K must be 3×3"),
        ({"intrinsics": CameraIntrinsics(W, H, np.diag([-1.0, 1.0, 1.0]))}, "focal"),
        ({"intrinsics": CameraIntrinsics(W + 1, H, _intrinsics().K)}, "intrinsics size"),
        ({"T_world_camera": np.eye(3)}, "4×4"),
        ({"T_world_camera": np.diag([2.0, 1.0, 1.0, 1.0])}, "rigid"),
    ],
)
def test_malformed_observations_are_named(change: dict, message: str) -> None:
    with pytest.raises(PerceptionError, match=message):
        check_observation(_obs(**change))


def test_not_an_observation() -> None:
    with pytest.raises(PerceptionError, match="expected an Observation"):
        check_observation("frame.png")  # type: ignore[arg-type]
