"""ros-check's comparison of the running camera with the one a calibration was solved with
(check_node.check_intrinsics): the same camera passes, another image size, K or lens is named."""

from __future__ import annotations

import numpy as np
import pytest
from ros_helpers import requires_ros

pytestmark = requires_ros


@pytest.fixture
def calibrated():
    from foldbot.ros.check_node import CalibratedCamera
    from foldbot.sim.camera import CameraConfig

    cfg = CameraConfig()
    return CalibratedCamera(cfg.K, cfg.width, cfg.height, np.zeros(5))


def _info(K, width=640, height=480, D=(0.0,) * 5):
    from foldbot.ros import convert
    from foldbot.types import CameraIntrinsics

    intr = CameraIntrinsics(width=width, height=height, K=np.asarray(K, dtype=float))
    msg = convert.camera_info_msg(intr, 0.0, "cam")
    msg.D = list(D)
    return msg


def test_the_camera_calibrated_passes(calibrated):
    from foldbot.ros.check_node import check_intrinsics

    check = check_intrinsics(_info(calibrated.K), calibrated)
    assert check.ok and check.name == "the camera as calibrated"
    assert check.detail.startswith("640 × 480 px, fx ")
    assert check.detail.endswith("as the calibration was solved with, its distortion too")
    # A driver's plumb_bob of 5 against a rational_polynomial's 8 zeros: the same lens.
    assert check_intrinsics(_info(calibrated.K, D=(0.0,) * 8), calibrated).ok
    # A calibration that records no distortion compares the rest.
    from dataclasses import replace

    no_dist = replace(calibrated, distortion=None)
    check = check_intrinsics(_info(calibrated.K, D=(-0.2, 0.1, 0, 0, 0)), no_dist)
    assert check.ok and check.detail.endswith("(the calibration records no distortion)")


def test_another_image_size_k_or_lens_is_named(calibrated):
    from foldbot.ros.check_node import check_intrinsics

    bigger = calibrated.K * np.array([[2.0], [2.0], [1.0]])
    check = check_intrinsics(_info(bigger, 1280, 960), calibrated)
    assert not check.ok
    assert check.detail.startswith("its camera_info is 1280 × 960 px, fx ")
    assert "the calibration's 640 × 480 px" in check.detail
    assert check.detail.endswith(
        ": calibrate again (`foldbot ros-calibrate`) or run the camera as it was then "
        "(resolution, driver mode, lens)"
    )
    moved = calibrated.K.copy()
    moved[0, 2] += 3.0  # the principal point 3 px over: another lens or mode
    check = check_intrinsics(_info(moved), calibrated)
    assert not check.ok and "lies 3.0 px from the calibration's" in check.detail
    assert check_intrinsics(_info(calibrated.K + np.diag([0.4, 0.4, 0.0])), calibrated).ok
    check = check_intrinsics(_info(calibrated.K, D=(-0.25, 0.0, 0.0, 0.0, 0.0)), calibrated)
    assert not check.ok
    assert "distortion [-0.25, 0.0, 0.0, 0.0, 0.0] is not the calibration's" in check.detail
    assert "(coefficient 0 0.2500 apart)" in check.detail
