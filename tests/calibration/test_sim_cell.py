"""The simulated calibration cell: the arm holds the board where a view asks, the camera's frame
shows it, and the board seen from the camera's true pose lies where the arm's kinematics and the
board's mount put it (the geometry every simulated calibration rests on)."""

import numpy as np
import pytest

from foldbot.calibration.board import Chessboard, board_pose, find_corners
from foldbot.calibration.sim_cell import SimCalibrationCell
from foldbot.calibration.views import BoardMount, calibration_views
from foldbot.sim.camera import CameraConfig
from foldbot.sim.layout import DEFAULT_LAYOUT
from foldbot.sim.world import SimConfig


@pytest.fixture(scope="module")
def cell():
    camera = CameraConfig()
    board, mount = Chessboard(), BoardMount()
    cell = SimCalibrationCell("ur5", camera, board, mount, SimConfig())
    views = calibration_views(DEFAULT_LAYOUT, tuple(camera.T_world_camera[:3, 3]), board, mount, 4)
    yield cell, camera, board, mount, views
    cell.close()


def test_the_board_held_where_a_view_asks_is_seen_where_the_arm_holds_it(cell):
    cell, camera, board, mount, views = cell
    K, dist, width, height = cell.intrinsics()
    np.testing.assert_allclose(K, camera.K)
    assert (width, height) == (camera.width, camera.height) and not dist.any()
    np.testing.assert_allclose(cell.true_T_world_camera, camera.T_world_camera)
    # Tilted views: a board seen square-on leaves PnP's rotation ill-posed (3.6° off at view 0).
    for view in views[1:4]:
        cell.move_to(view)
        rgb, T_world_tcp = cell.frame()
        assert rgb.shape == (height, width, 3)
        # The arm's tool reached the view.
        assert np.linalg.norm(T_world_tcp[:3, 3] - view.position) < 0.002
        found = find_corners(rgb, board)
        assert found is not None, view.name
        ids, corners = found
        assert len(corners) == len(board.object_points())  # the whole board in sight
        seen = camera.T_world_camera @ board_pose(corners, board, K, ids=ids)
        held = T_world_tcp @ mount.T_tcp_board()
        assert np.linalg.norm(seen[:3, 3] - held[:3, 3]) < 0.003, view.name
        turn = np.degrees(
            np.arccos(np.clip((np.trace(seen[:3, :3].T @ held[:3, :3]) - 1) / 2, -1, 1))
        )
        assert turn < 1.0, view.name


def test_finish_takes_the_arm_home(cell):
    cell, *_ = cell
    cell.finish()
    np.testing.assert_allclose(cell.robot.joint_positions(), cell.robot.home_q, atol=0.01)
