"""A depth image from a sensor beside the colour camera (its own pose, intrinsics and size),
registered onto the colour camera, reads as the colour camera's own depth and gives the same
corners."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from rgbd_views import T_COLOR_DEPTH, render_views

from foldbot.errors import PerceptionError
from foldbot.perception.estimator import VisionEstimator
from foldbot.perception.register import register_depth
from foldbot.types import Observation


@pytest.fixture(scope="module")
def views():
    return render_views()


def _registered(color: Observation, depth: Observation) -> np.ndarray:
    size = (color.intrinsics.width, color.intrinsics.height)
    return register_depth(depth.depth, depth.intrinsics.K, color.intrinsics.K, T_COLOR_DEPTH, size)


def test_registered_depth_reads_as_the_colour_cameras_own(views):
    color, depth, _ = views
    z = _registered(color, depth)
    assert z.shape == color.depth.shape and z.dtype == np.float32
    both = np.isfinite(z) & np.isfinite(color.depth)
    assert both.mean() > 0.95  # only the depth sensor's shadows and the view's edge are left
    diff = np.abs(z[both] - color.depth[both])
    assert np.median(diff) < 0.5e-3
    assert np.mean(diff < 5e-3) > 0.98  # the rest: pixels on an edge, one footprint off


def test_corners_from_the_registered_depth_match(views):
    color, depth, truth = views

    def worst_mm(z: np.ndarray) -> float:
        obs = Observation(color.rgb, z, color.intrinsics, color.T_world_camera)
        state = VisionEstimator().estimate(obs)
        assert state.detected
        return max(1000 * float(np.linalg.norm(state.keypoints[n][0] - truth[n])) for n in truth)

    own = worst_mm(color.depth)  # measured 0.08 mm
    assert worst_mm(_registered(color, depth)) < own + 0.5  # measured 0.22 mm
    # The depth sensor's image only resized to the colour image, as if it were registered:
    # the corners lie centimetres off (measured 38.7 mm), so registering is what makes it work.
    unregistered = cv2.resize(depth.depth, (640, 480), interpolation=cv2.INTER_NEAREST)
    assert worst_mm(unregistered) > 10.0


def test_the_same_camera_registers_to_itself(views):
    color, _, _ = views
    size = (color.intrinsics.width, color.intrinsics.height)
    z = register_depth(color.depth, color.intrinsics.K, color.intrinsics.K, np.eye(4), size)
    ok = np.isfinite(color.depth)
    np.testing.assert_allclose(z[ok], color.depth[ok], atol=1e-6)


def test_no_reading_stays_no_reading_and_bad_input_is_named():
    K = np.array([[100.0, 0, 15.5], [0, 100.0, 11.5], [0, 0, 1]])
    z = np.full((24, 32), 1.0, np.float32)
    z[:, :16] = np.nan
    z[:, 16:20] = 0.0  # a 16UC1 sensor's "no reading", once scaled
    out = register_depth(z, K, K, np.eye(4), (32, 24))
    assert np.isnan(out[:, :20]).all() and np.allclose(out[:, 20:], 1.0)
    with pytest.raises(PerceptionError, match="T_color_depth"):
        register_depth(z, K, K, np.eye(3), (32, 24))
    with pytest.raises(PerceptionError, match="K_depth"):
        register_depth(z, np.zeros((3, 3)), K, np.eye(4), (32, 24))
    coarse = np.array([[10.0, 0, 1.5], [0, 10.0, 1.5], [0, 0, 1]])
    with pytest.raises(PerceptionError, match="colour pixels along a side"):
        register_depth(np.ones((4, 4)), coarse, K, np.eye(4), (32, 24))
