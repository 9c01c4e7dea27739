"""Message conversions: foldbot types ↔ ROS 1 messages, lossless where it matters."""

import json

import numpy as np
import pytest

pytest.importorskip("rospy", reason="ROS 1 Python packages not installed (scripts/install_ros.sh)")

from foldbot.errors import FoldbotError
from foldbot.perception.state import ClothState
from foldbot.ros import convert
from foldbot.types import CameraIntrinsics


@pytest.mark.parametrize(
    ("array", "encoding"),
    [
        (np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3), "rgb8"),
        (np.array([[0, 255], [7, 9]], dtype=np.uint8), "mono8"),
        (np.array([[0.5, np.nan], [1.25, 0.0]], dtype=np.float32), "32FC1"),
    ],
)
def test_images_round_trip(array, encoding):
    msg = convert.image_msg(array, encoding, 1.5, "cam")
    assert msg.encoding == encoding and msg.header.frame_id == "cam"
    assert msg.header.stamp.to_sec() == pytest.approx(1.5)
    np.testing.assert_array_equal(convert.image_array(msg), array)


def test_what_rgbd_drivers_publish_is_taken_as_the_sim_sends_it():
    # A real camera's colour comes as bgr8 or with alpha, its depth in millimetres (REP 118's
    # 16UC1, 0 = no reading), rows possibly padded: the perception node reads them as the sim's
    # rgb8 and 32FC1 metres.
    rgb = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    alpha = np.full((2, 3, 1), 255, np.uint8)
    for encoding, array in (
        ("rgb8", rgb),
        ("bgr8", rgb[..., ::-1]),
        ("rgba8", np.concatenate([rgb, alpha], axis=2)),
        ("bgra8", np.concatenate([rgb[..., ::-1], alpha], axis=2)),
    ):
        msg = convert.image_msg(array, encoding, 0.0, "cam")
        np.testing.assert_array_equal(convert.color_array(msg), rgb)
    metres = np.array([[0.5, np.nan], [1.25, 0.0]], dtype=np.float32)
    sim = convert.depth_array(convert.image_msg(metres, "32FC1", 0.0, "cam"))
    np.testing.assert_array_equal(sim, metres)  # as sent: the sim's depth is not touched
    mm = np.array([[500, 0], [1250, 65535]], dtype=np.uint16)
    depth = convert.depth_array(convert.image_msg(mm, "16UC1", 0.0, "cam"))
    assert depth.dtype == np.float32
    np.testing.assert_allclose(depth, [[0.5, np.nan], [1.25, 65.535]])
    # Big-endian data and rows padded to 8 bytes.
    msg = convert.image_msg(mm, "16UC1", 0.0, "cam")
    msg.is_bigendian, msg.step = 1, 8
    msg.data = b"".join(row.astype(">u2").tobytes() + b"\0\0\0\0" for row in mm)
    np.testing.assert_allclose(convert.depth_array(msg), [[0.5, np.nan], [1.25, 65.535]])


def test_a_frame_with_lens_distortion_is_rectified_for_perception():
    # camera_info's D (a real camera's) is taken out before perception; the sim's zeros leave
    # the images as they are (perception.rectify, tests/perception/test_rectify.py).
    intr = CameraIntrinsics(
        K=np.array([[60.0, 0, 15.5], [0, 60.0, 11.5], [0, 0, 1]]), width=32, height=24
    )
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
    depth = rng.uniform(0.9, 1.1, (24, 32)).astype(np.float32)
    color_msg = convert.image_msg(rgb, "rgb8", 0.0, "cam")
    depth_msg = convert.image_msg(depth, "32FC1", 0.0, "cam")
    info = convert.camera_info_msg(intr, 0.0, "cam")
    out_rgb, out_depth, out_intr = convert.camera_images(color_msg, depth_msg, info)
    np.testing.assert_array_equal(out_rgb, rgb)
    np.testing.assert_array_equal(out_depth, depth)
    np.testing.assert_array_equal(out_intr.K, intr.K)
    info.D = [-0.3, 0.1, 0.0, 0.0, 0.0]
    out_rgb, out_depth, out_intr = convert.camera_images(color_msg, depth_msg, info)
    assert not np.array_equal(out_rgb, rgb)
    assert np.isin(out_depth[np.isfinite(out_depth)], depth).all()  # picked, not blended
    np.testing.assert_array_equal(out_intr.K, intr.K)  # the same K, now without distortion
    info.distortion_model = "equidistant"
    with pytest.raises(FoldbotError, match="cannot rectify distortion model 'equidistant'"):
        convert.camera_images(color_msg, depth_msg, info)


def test_a_depth_camera_beside_the_colour_one_is_registered_onto_it():
    # A wall 0.1 m ahead. The depth sensor sits 25 mm to the colour camera's left (its own
    # frame, a coarser K and image size, as a real RGB-D camera's): registered, every colour
    # pixel it reaches reads the wall's depth, and the right-hand strip it cannot see (25 mm at
    # 60 px / 0.1 m: 15 px) reads NaN. perception.register's own tests use rendered towels.
    color_intr = CameraIntrinsics(
        K=np.array([[60.0, 0, 15.5], [0, 60.0, 11.5], [0, 0, 1]]), width=32, height=24
    )
    depth_intr = CameraIntrinsics(
        K=np.array([[30.0, 0, 7.5], [0, 30.0, 5.5], [0, 0, 1]]), width=16, height=12
    )
    rgb = np.full((24, 32, 3), 200, np.uint8)
    color_msg = convert.image_msg(rgb, "rgb8", 0.0, "color")
    depth_msg = convert.image_msg(np.full((12, 16), 100, np.uint16), "16UC1", 0.0, "depth")
    info = convert.camera_info_msg(color_intr, 0.0, "color")
    depth_info = convert.camera_info_msg(depth_intr, 0.0, "depth")
    T_color_depth = np.eye(4)
    T_color_depth[0, 3] = -0.025
    _, z, intr = convert.camera_images(color_msg, depth_msg, info, depth_info, T_color_depth)
    assert z.shape == (24, 32) and intr.width == 32
    np.testing.assert_allclose(z[:, :16], 0.1, atol=1e-6)
    assert np.isnan(z[:, 18:]).all()
    # Another frame and no transform known: named, not guessed.
    with pytest.raises(FoldbotError, match="frame 'depth' is not the colour camera's 'color'"):
        convert.camera_images(color_msg, depth_msg, info, depth_info)
    # The same camera_info for both (the simulated camera): the depth is taken as it is.
    same = convert.image_msg(np.full((24, 32), 0.7, np.float32), "32FC1", 0.0, "color")
    _, z, _ = convert.camera_images(
        color_msg, same, info, convert.camera_info_msg(color_intr, 0.0, "color")
    )
    assert np.all(z == np.float32(0.7))
    assert convert.same_camera(info, convert.camera_info_msg(color_intr, 5.0, "color"))
    assert not convert.same_camera(info, depth_info)
    # A depth camera_info describes the depth images of its own frame only: a driver's depth
    # already aligned to the colour frame is not registered again by the raw sensor's.
    assert convert.info_for(depth_msg, depth_info) is depth_info
    assert convert.info_for(same, depth_info) is None
    assert convert.info_for(depth_msg, None) is None


def test_a_camera_image_of_the_wrong_kind_is_named():
    depth = convert.image_msg(np.zeros((2, 2), np.float32), "32FC1", 0.0, "cam")
    with pytest.raises(FoldbotError, match="colour image encoding '32FC1'; allowed: rgb8, bgr8"):
        convert.color_array(depth)
    color = convert.image_msg(np.zeros((2, 2, 3), np.uint8), "rgb8", 0.0, "cam")
    with pytest.raises(FoldbotError, match="depth image encoding 'rgb8'; allowed: 32FC1, 16UC1"):
        convert.depth_array(color)
    short = convert.image_msg(np.zeros((2, 3), np.uint16), "16UC1", 0.0, "cam")
    short.step = 4  # under the 6 bytes a row of three needs
    with pytest.raises(FoldbotError, match="needs rows of at least 6 bytes"):
        convert.depth_array(short)


def test_unknown_encoding_is_named():
    with pytest.raises(FoldbotError, match="bgr16"):
        convert.image_msg(np.zeros((2, 2, 3), np.uint16), "bgr16", 0.0, "cam")


def test_camera_info_keeps_K():
    K = np.array([[880.0, 0, 320.5], [0, 881.0, 240.25], [0, 0, 1]])
    intr = CameraIntrinsics(K=K, width=640, height=480)
    back = convert.intrinsics_of(convert.camera_info_msg(intr, 0.0, "cam"))
    np.testing.assert_array_equal(back.K, K)
    assert (back.width, back.height) == (640, 480)


def test_transform_round_trip():
    T = np.eye(4)
    c, s = np.cos(0.3), np.sin(0.3)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = [0.1, -0.2, 1.7]
    np.testing.assert_allclose(
        convert.matrix_of(convert.transform_msg(T, "world", "cam", 0.0)), T, atol=1e-12
    )


def test_cloth_state_round_trip_and_pose_array_order():
    mask = np.zeros((4, 5), bool)
    mask[1:3, 1:4] = True
    kp = {
        "far_left": (np.array([0.6, 0.1, 0.76]), 0.9),
        "near_left": (np.array([0.3, 0.1, 0.76]), 1.0),
        "near_right": (np.array([0.3, -0.1, 0.76]), 1.0),
        "far_right": (np.array([0.6, -0.1, 0.76]), 0.5),
    }
    state = ClothState(
        True, "", kp, mask, 0.06, 0.002, np.zeros((0, 3)), np.array([0, 0, 1, -0.75]), 3.25
    )
    back = convert.state_from(convert.state_json(state), mask.astype(np.uint8) * 255)
    assert back.detected and back.stamp == 3.25
    np.testing.assert_array_equal(back.mask, mask)
    for label, (xyz, conf) in kp.items():
        np.testing.assert_array_equal(back.keypoints[label][0], xyz)
        assert back.keypoints[label][1] == conf
    poses = convert.keypoints_msg(state, 3.25, "world").poses
    xs = [(p.position.x, p.position.y) for p in poses]
    assert xs == [(0.3, 0.1), (0.3, -0.1), (0.6, -0.1), (0.6, 0.1)]  # CORNER_LABELS order
    assert json.loads(convert.state_json(state))["keypoints"]["far_right"][3] == 0.5


def test_trajectory_round_trip_and_bad_points():
    t = np.array([0.0, 0.1, 0.2])
    q = np.arange(18, dtype=float).reshape(3, 6) / 10
    v = np.ones((3, 6))
    msg = convert.trajectory_msg([f"j{i}" for i in range(6)], t, q, v, 0.0, "")
    t2, q2, v2 = convert.trajectory_arrays(msg)
    np.testing.assert_allclose(t2, t)
    np.testing.assert_array_equal(q2, q)
    np.testing.assert_array_equal(v2, v)
    msg.points[1].positions = [0.0] * 5
    with pytest.raises(FoldbotError, match="6 positions"):
        convert.trajectory_arrays(msg)


def test_point_cloud_round_trip():
    pts = np.array([[0.1, 0.2, 0.75], [0.4, -0.3, 0.76]])
    np.testing.assert_allclose(
        convert.cloud_array(convert.cloud_msg(pts, 0.0, "world")), pts, atol=1e-7
    )


def test_corners_from_pose_array_need_all_four():
    kp = {
        label: (np.array([i, -i, 0.76]), 1.0)
        for i, label in enumerate(("near_left", "near_right", "far_right", "far_left"))
    }
    state = ClothState(True, "", kp, np.zeros((2, 2), bool))
    msg = convert.keypoints_msg(state, 0.0, "world")
    corners = convert.corners_of_pose_array(msg)
    for label, (xyz, _c) in kp.items():
        np.testing.assert_array_equal(corners[label], xyz)
    msg.poses.pop()
    with pytest.raises(FoldbotError, match="got 3 poses"):
        convert.corners_of_pose_array(msg)
