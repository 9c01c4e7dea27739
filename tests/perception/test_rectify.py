"""A real lens's distortion taken out before perception (camera_info's D), and nothing done to
the simulated camera's ideal images."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from foldbot.errors import PerceptionError
from foldbot.perception.estimator import VisionEstimator
from foldbot.perception.rectify import rectify, rectify_depth
from foldbot.sim.perception_scenes import default_scene, render_scene
from foldbot.types import Observation

# Barrel distortion (k1 k2 p1 p2 k3), about 20 px at the image corners with the cell's K.
D = np.array([-0.25, 0.05, 0.0005, -0.0003, 0.0])


def _distorted(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What a camera with distortion D sees of the scene an ideal pinhole K sees as (rgb, depth):
    each distorted pixel takes the ideal image at its undistorted position."""
    h, w = depth.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    pts = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    ideal = cv2.undistortPoints(pts, K, D, None, K)  # to 1e-4 px here (checked)
    mx = ideal[:, 0, 0].reshape(h, w).astype(np.float32)
    my = ideal[:, 0, 1].reshape(h, w).astype(np.float32)
    color = cv2.remap(rgb, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    z = cv2.remap(
        depth.astype(np.float32), mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE
    )
    return color, z


def _worst_mm(obs: Observation, truth: dict[str, np.ndarray]) -> float:
    state = VisionEstimator().estimate(obs)
    assert state.detected
    return max(1000 * float(np.linalg.norm(state.keypoints[n][0] - truth[n])) for n in truth)


def test_the_simulated_cameras_images_pass_through_untouched():
    rgb, depth, K = np.zeros((4, 6, 3), np.uint8), np.ones((4, 6), np.float32), np.eye(3)
    for model in ("plumb_bob", "rational_polynomial", "equidistant", ""):
        out_rgb, out_depth = rectify(rgb, depth, K, [0.0] * 5, model)
        assert out_rgb is rgb and out_depth is depth


def test_a_distorted_view_is_rectified_back_to_the_corners():
    # A towel near the image's edge, where barrel distortion moves it most.
    r = render_scene(default_scene(x=0.55, y=0.12, yaw=0.3), 640, 480, 12, settle_time=0.6)
    K = r.obs.intrinsics.K
    rgb, depth = _distorted(r.obs.rgb, r.obs.depth, K)
    raw = Observation(rgb, depth, r.obs.intrinsics, r.obs.T_world_camera)
    fixed_rgb, fixed_depth = rectify(rgb, depth, K, D)
    fixed = Observation(fixed_rgb, fixed_depth, r.obs.intrinsics, r.obs.T_world_camera)
    clean = _worst_mm(r.obs, r.corners)
    assert _worst_mm(fixed, r.corners) < clean + 0.5
    assert _worst_mm(raw, r.corners) > 5.0  # read through K alone, the corners lie off
    # Depth is picked, never blended: every rectified value is one the camera measured.
    seen = np.unique(depth)
    values = fixed_depth[np.isfinite(fixed_depth)]
    assert np.isin(values, seen).all()


@pytest.mark.parametrize(
    ("distortion", "model", "match"),
    [
        ([0.1, 0.0, 0.0, 0.0, 0.0], "equidistant", "cannot rectify distortion model 'equidistant'"),
        ([0.1, 0.0, 0.0], "plumb_bob", "takes 4, 5 or 8 coefficients, got 3"),
        ([np.nan, 0.0, 0.0, 0.0, 0.0], "plumb_bob", "must be finite"),
    ],
)
def test_a_distortion_it_cannot_take_is_named(distortion, model, match):
    rgb, depth = np.zeros((4, 6, 3), np.uint8), np.ones((4, 6), np.float32)
    with pytest.raises(PerceptionError, match=match):
        rectify(rgb, depth, np.eye(3), distortion, model)


def test_colour_and_depth_of_different_sizes_are_refused():
    with pytest.raises(PerceptionError, match="differ in size"):
        rectify(np.zeros((4, 6, 3), np.uint8), np.ones((5, 6), np.float32), np.eye(3), D)


def test_a_depth_image_alone_is_rectified_as_with_its_colour():
    # A depth sensor with its own camera_info is rectified on its own (then registered).
    rng = np.random.default_rng(1)
    K = np.array([[60.0, 0, 15.5], [0, 60.0, 11.5], [0, 0, 1]])
    rgb = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
    depth = rng.uniform(0.9, 1.1, (24, 32)).astype(np.float32)
    _, with_colour = rectify(rgb, depth, K, D)
    alone = rectify_depth(depth, K, D)
    np.testing.assert_array_equal(alone, with_colour)
    assert rectify_depth(depth, K, [0.0] * 5) is depth
