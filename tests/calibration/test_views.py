"""Where the arm holds the board: over the workspace, its face towards the rough camera, turned
about more than one axis; impossible requests refused by name."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from foldbot.calibration.board import Chessboard
from foldbot.calibration.views import MAX_VIEWS, BoardMount, calibration_views
from foldbot.errors import ConfigError
from foldbot.sim.layout import DEFAULT_LAYOUT

EYE = (1.05, 0.0, 1.75)


def board_poses(views, mount):
    out = []
    for v in views:
        R_tcp = Rotation.from_quat(v.quaternion)
        R_board = R_tcp * Rotation.from_rotvec(mount.rotvec_rad)
        origin = v.position + R_tcp.apply(mount.offset_m)
        out.append((origin, R_board))
    return out


def test_the_board_faces_the_camera_from_over_the_workspace():
    board, mount = Chessboard(), BoardMount()
    views = calibration_views(DEFAULT_LAYOUT, EYE, board, mount)
    assert len(views) == MAX_VIEWS
    cx, cy = DEFAULT_LAYOUT.workspace_center_xy
    normals = []
    for origin, R in board_poses(views, mount):
        face = -R.apply([0.0, 0.0, 1.0])  # out of the printed face
        to_camera = np.subtract(EYE, origin)
        assert face @ to_camera / np.linalg.norm(to_camera) > np.cos(np.deg2rad(45.0))
        assert abs(origin[0] - cx) < 0.4 and abs(origin[1] - cy) < 0.4
        assert DEFAULT_LAYOUT.table_height + 0.1 < origin[2] < DEFAULT_LAYOUT.table_height + 0.45
        normals.append(R)
    # Turned about more than one axis between views: the relative rotations' axes spread.
    axes = [(normals[0].inv() * r).as_rotvec() for r in normals[1:]]
    axes = np.array([a / np.linalg.norm(a) for a in axes])
    assert np.linalg.svd(axes, compute_uv=False)[1] > 0.5


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"count": 3}, "views must be an integer in [4, 12]"),
        ({"count": 13}, "views must be an integer in [4, 12]"),
        ({"look_from": (1.0, 0.0, 1.0)}, "must be above the held board"),
        ({"look_from": (1.0, float("nan"), 1.8)}, "3 finite numbers"),
    ],
)
def test_impossible_requests_are_refused_by_name(kwargs, needle):
    args = {"look_from": EYE, "count": 6} | kwargs
    with pytest.raises(ConfigError, match=needle.replace("[", r"\[").replace("]", r"\]")):
        calibration_views(
            DEFAULT_LAYOUT, args["look_from"], Chessboard(), BoardMount(), args["count"]
        )


def test_a_mount_must_be_finite():
    with pytest.raises(ConfigError, match="offset_m must be 3 finite numbers"):
        BoardMount(offset_m=(0.0, float("inf"), 0.0))
