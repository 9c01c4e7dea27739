"""The chessboard: its checks, and corners and pose found in an image of a known board pose
(drawn through the board's homography, the way a pinhole camera sees a plane)."""

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from foldbot.calibration.board import (
    MIN_CHARUCO_CORNERS,
    CharucoBoard,
    Chessboard,
    board_image,
    board_pose,
    detect_corners,
    find_corners,
)
from foldbot.errors import ConfigError

K = np.array([[880.0, 0.0, 319.5], [0.0, 880.0, 239.5], [0.0, 0.0, 1.0]])
PX_PER_M = 4000.0


def board_picture(board: Chessboard | CharucoBoard) -> tuple[np.ndarray, np.ndarray]:
    """The printed board as an image, and the board-frame → picture-pixel map (3 × 3)."""
    x0, _, y0, _ = board.plate_bounds()
    # Pixel centres at integers: a square's edge at column u0 lies at u0 − 0.5.
    to_px = np.array(
        [[PX_PER_M, 0, -x0 * PX_PER_M - 0.5], [0, PX_PER_M, -y0 * PX_PER_M - 0.5], [0, 0, 1]]
    )
    return board_image(board, PX_PER_M), to_px


def seen(board: Chessboard | CharucoBoard, T_camera_board: np.ndarray) -> np.ndarray:
    """The camera's RGB image of the board at T_camera_board, on a grey background."""
    img, to_px = board_picture(board)
    R, t = T_camera_board[:3, :3], T_camera_board[:3, 3]
    H = K @ np.column_stack([R[:, 0], R[:, 1], t]) @ np.linalg.inv(to_px)
    out = cv2.warpPerspective(img, H, (640, 480), flags=cv2.INTER_AREA, borderValue=120)
    return np.repeat(out[..., None], 3, axis=2)


@pytest.mark.parametrize(
    ("turn", "tilt"),
    [
        (0.0, (0.0, 0.0)),
        (180.0, (0.0, 0.0)),  # turned about its normal by 180°: the same corner order
        (180.0, (20.0, -10.0)),
        (30.0, (15.0, 10.0)),
        (150.0, (-15.0, 20.0)),
        (-90.0, (12.0, 12.0)),
    ],
)
def test_corners_and_pose_of_a_board_seen_at_a_known_pose(turn, tilt):
    board = Chessboard()
    T = np.eye(4)
    R = Rotation.from_euler("xyz", [*tilt, turn], degrees=True)
    T[:3, :3], T[:3, 3] = R.as_matrix(), [-0.07, -0.03, 0.9]
    corners = detect_corners(seen(board, T), board)
    assert corners is not None
    obj = board.object_points()
    expected = (K @ (T[:3, :3] @ obj.T + T[:3, 3:4])).T
    expected = expected[:, :2] / expected[:, 2:]
    assert np.abs(corners - expected).max() < 0.5
    if tilt != (0.0, 0.0):  # PnP on a board square to the camera trades tilt for depth
        T_found = board_pose(corners, board, K)
        assert np.linalg.norm(T_found[:3, 3] - T[:3, 3]) < 1e-3
        # A small board's tilt from one view is good to a degree or so; the hand–eye solve
        # refines on every corner of every view, not on these poses.
        assert Rotation.from_matrix(T_found[:3, :3].T @ T[:3, :3]).magnitude() < np.deg2rad(1.5)


def test_no_board_no_corners():
    assert detect_corners(np.full((480, 640, 3), 120, np.uint8), Chessboard()) is None


def test_object_points_follow_the_detectors_order():
    board = Chessboard(squares_x=6, squares_y=5, square_m=0.03)
    pts = board.object_points()
    assert board.pattern_size == (5, 4) and pts.shape == (20, 3)
    assert pts[1].tolist() == pytest.approx([0.03, 0.0, 0.0])
    assert pts[5].tolist() == pytest.approx([0.0, 0.03, 0.0])


@pytest.mark.parametrize(
    ("fields", "needle"),
    [
        ({"squares_x": 8, "squares_y": 6}, "odd in all"),
        ({"squares_x": 5, "squares_y": 8}, "more along x"),
        ({"squares_x": 2, "squares_y": 1}, "squares_x must be an integer in [3, 30]"),
        ({"square_m": 0.0}, "square_m must be in"),
        ({"square_m": float("nan")}, "square_m must be in"),
        ({"margin_m": -0.01}, "margin_m must be in"),
    ],
)
def test_a_board_with_an_ambiguous_or_impossible_shape_is_refused(fields, needle):
    with pytest.raises(ConfigError, match=needle.replace("[", r"\[").replace("]", r"\]")):
        Chessboard(**fields)


def test_the_printed_board_has_its_squares_where_the_board_frame_says():
    board = Chessboard(square_m=0.02, margin_m=0.01)
    img = board_image(board, 1000.0)  # a pixel a millimetre
    assert img.shape == (5 * 20 + 20, 8 * 20 + 20)
    # Square (0, 0), around the origin's upper left, is black; (1, 0) beside it white.
    assert img[10 + 10, 10 + 10] == 0 and img[10 + 10, 10 + 30] == 255
    assert img[0, 0] == 255  # the margin
    with pytest.raises(ConfigError, match="resolution must be in"):
        board_image(board, 10.0)


def at(turn: float, tilt: tuple[float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [*tilt, turn], degrees=True).as_matrix()
    T[:3, 3] = [-0.08, -0.05, 0.8]
    return T


def expected_px(board, T: np.ndarray) -> np.ndarray:
    cam = T[:3, :3] @ board.object_points().T + T[:3, 3:4]
    uv = K @ cam
    return (uv[:2] / uv[2]).T


def test_the_printed_charuco_board_is_opencvs():
    board = CharucoBoard()
    img = board_image(board, PX_PER_M)
    m = round(board.margin_m * PX_PER_M)
    ref = board._board().generateImage(
        (round(6 * board.square_m * PX_PER_M), round(4 * board.square_m * PX_PER_M)),
        marginSize=0,
        borderBits=1,
    )
    assert (img[m : m + ref.shape[0], m : m + ref.shape[1]] == ref).all()
    assert (img[:m] == 255).all()  # the margin
    assert len(board.black_rects()) == 112  # 12 squares, each marker in 6–10 boxes


@pytest.mark.parametrize("turn", [0.0, 180.0, 75.0])
def test_charuco_corners_are_named_whole_and_in_part(turn):
    board = CharucoBoard()
    T = at(turn, (12.0, -8.0))
    img = seen(board, T)
    ids, px = find_corners(img, board)
    assert sorted(ids) == list(range(15))
    assert np.abs(px - expected_px(board, T)[ids]).max() < 0.5
    # Half the board hidden (the arm in front, the image's edge): the rest named rightly.
    u = expected_px(board, T)[:, 0]
    cut = float(np.percentile(u, 80))
    hidden = img.copy()
    hidden[:, round(cut) :] = 120
    ids, px = find_corners(hidden, board)
    assert MIN_CHARUCO_CORNERS <= len(ids) < 15
    assert (u[ids] < cut).all()
    assert np.abs(px - expected_px(board, T)[ids]).max() < 0.5
    T_found = board_pose(px, board, K, ids=ids)
    assert np.linalg.norm(T_found[:3, 3] - T[:3, 3]) < 2e-3


def test_too_little_of_a_charuco_board_is_not_enough():
    board = CharucoBoard()
    T = at(0.0, (0.0, 0.0))
    img = seen(board, T)
    u = expected_px(board, T)[:, 0]
    hidden = img.copy()
    hidden[:, round(float(np.sort(u)[3]) + 3) :] = 120  # a column of corners left, or so
    assert find_corners(hidden, board) is None
    assert find_corners(np.full((480, 640, 3), 120, np.uint8), board) is None


@pytest.mark.parametrize(
    ("fields", "needle"),
    [
        ({"squares_x": 4, "squares_y": 5}, "at least as many along x"),
        ({"marker_m": 0.035}, "marker_m must be 0.4–0.9 of the square"),
        ({"dictionary": "7x7_1000"}, "dictionary must be one of"),
        ({"squares_x": 11, "squares_y": 10}, "needs 55 markers, more than dictionary 4x4_50's 50"),
    ],
)
def test_a_charuco_board_that_cannot_be_is_refused(fields, needle):
    with pytest.raises(ConfigError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        CharucoBoard(**fields)
