"""The eye-to-hand solve on views made from a known camera and board mount: it finds both, its
residuals say how well, and too few or too alike views are refused."""

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from foldbot.calibration.board import Chessboard
from foldbot.calibration.hand_eye import pose_error, solve_eye_to_hand
from foldbot.errors import ConfigError

K = np.array([[880.0, 0.0, 319.5], [0.0, 880.0, 239.5], [0.0, 0.0, 1.0]])


def T(rotvec, t) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    out[:3, 3] = t
    return out


X_TRUE = T([2.6, 0.1, -0.2], [1.0, 0.1, 1.7])  # world → camera, looking down at the table
Y_TRUE = T([0.02, -0.03, 0.05], [-0.24, -0.03, -0.06])  # board on the tool


def views(n: int, noise_px: float, turn_deg: float = 25.0, seed: int = 0, dist=None):
    """Tool poses that hold the board in front of the camera, and what the camera sees of it."""
    rng = np.random.default_rng(seed)
    board = Chessboard()
    A, B, corners = [], [], []
    for _ in range(n):
        # The board 0.9 m in front of the camera, turned a little, and the tool from it.
        board_in_cam = T(
            Rotation.from_euler("xyz", rng.uniform(-1, 1, 3) * np.deg2rad(turn_deg)).as_rotvec(),
            [rng.uniform(-0.1, 0.0), rng.uniform(-0.1, 0.0), rng.uniform(0.8, 1.0)],
        )
        a = X_TRUE @ board_in_cam @ np.linalg.inv(Y_TRUE)
        rvec = cv2.Rodrigues(board_in_cam[:3, :3])[0]
        px = cv2.projectPoints(board.object_points(), rvec, board_in_cam[:3, 3], K, dist)[0]
        px = px.reshape(-1, 2) + rng.normal(0.0, noise_px, (len(px), 2))
        A.append(a)
        B.append(board_in_cam)
        corners.append(px)
    return board, A, B, corners


def test_the_camera_and_the_mount_are_found_from_noisy_corners():
    board, A, B, corners = views(10, noise_px=0.2)
    # The PnP poses are what the views give: start the solve from poses a little off.
    B_seen = [
        b @ T(np.random.default_rng(i).normal(0, 0.01, 3), [0, 0, 0.003]) for i, b in enumerate(B)
    ]
    sol = solve_eye_to_hand(A, B_seen, corners, board, K)
    dt, dr = pose_error(sol.T_world_camera, X_TRUE)
    assert dt < 1e-3 and np.rad2deg(dr) < 0.05
    dt, dr = pose_error(sol.T_tcp_board, Y_TRUE)
    assert dt < 1e-3 and np.rad2deg(dr) < 0.1
    assert 0.24 < sol.reprojection_rms_px < 0.32  # the noise put in: 0.2 px each way, √2·0.2
    assert len(sol.view_rms_px) == 10 and max(sol.board_disagreement_m) < 0.01


def test_a_lens_distortion_given_is_taken_into_account():
    # A real camera's camera_info carries its plumb_bob coefficients; the corners are found in
    # the distorted image, and the solve projects through the same model.
    dist = np.array([-0.12, 0.08, 0.001, -0.0005, 0.0])
    board, A, B, corners = views(8, noise_px=0.1, dist=dist)
    sol = solve_eye_to_hand(A, B, corners, board, K, dist)
    dt, dr = pose_error(sol.T_world_camera, X_TRUE)
    assert dt < 5e-4 and np.rad2deg(dr) < 0.05 and sol.reprojection_rms_px < 0.2
    # Left out, the camera lands several times further off (1.5 mm here).
    off, _ = pose_error(solve_eye_to_hand(A, B, corners, board, K).T_world_camera, X_TRUE)
    assert off > 3 * dt


def test_a_wrong_tool_pose_shows_in_the_residuals():
    board, A, B, corners = views(8, noise_px=0.1)
    A[3] = A[3] @ T([0.0, 0.0, 0.0], [0.01, 0.0, 0.0])  # one joint reading 1 cm off at the tool
    sol = solve_eye_to_hand(A, B, corners, board, K)
    assert int(np.argmax(sol.view_rms_px)) == 3
    assert sol.view_rms_px[3] > 2 * np.median(sol.view_rms_px)


def test_too_few_or_too_alike_views_are_refused():
    board, A, B, corners = views(3, noise_px=0.1)
    with pytest.raises(ConfigError, match="at least 4 views"):
        solve_eye_to_hand(A, B, corners, board, K)
    board, A, B, corners = views(6, noise_px=0.1, turn_deg=0.5)
    with pytest.raises(ConfigError, match="turn the tool too little"):
        solve_eye_to_hand(A, B, corners, board, K)
    with pytest.raises(ConfigError, match="every view needs"):
        solve_eye_to_hand(A, B[:-1], corners, board, K)


def test_views_that_saw_part_of_the_board_are_solved_on_the_corners_they_saw():
    board, A, B, corners = views(8, noise_px=0.1, seed=5)
    rng = np.random.default_rng(1)
    ids = [
        np.sort(rng.choice(len(c), size=rng.integers(8, len(c)), replace=False)) for c in corners
    ]
    sol = solve_eye_to_hand(
        A, B, [c[i] for c, i in zip(corners, ids, strict=True)], board, K, None, ids
    )
    dt, dr = pose_error(sol.T_world_camera, X_TRUE)
    assert dt < 1e-3 and np.rad2deg(dr) < 0.05
    # The ids must match the corners given, view by view.
    with pytest.raises(ConfigError, match="view 0: 28 corners seen for 8 corner ids"):
        solve_eye_to_hand(A, B, corners, board, K, None, [np.arange(8)] + ids[1:])
    with pytest.raises(ConfigError, match="corner_ids must name each view's corners, got 7 for 8"):
        solve_eye_to_hand(A, B, corners, board, K, None, ids[1:])
