"""Where the arm holds the board for a calibration: tool poses over the workspace that turn the
board towards where the camera roughly is, turned and tilted between views so the solve sees the
rotation about more than one axis.

Nothing here knows the camera's pose: only a rough point the user gives (`look_from`, tens of
centimetres off is fine) and the board's nominal mount on the tool. Views the arm cannot reach
are dropped before anything moves; views where the board is not seen are dropped after.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from foldbot.calibration.board import CalibrationBoard
from foldbot.errors import require
from foldbot.sim.layout import CellLayout

HOLD_HEIGHT = 0.25
"""The board's centre this far over the table top in the middle view (m)."""


@dataclass(frozen=True)
class BoardMount:
    """Where the board sits on the tool (TCP frame, m and rad): nominal, for aiming the views;
    the calibration solves the real one."""

    offset_m: tuple[float, float, float] = (-0.24, -0.036, -0.06)
    """The board's origin (its first inner corner) in the TCP frame: beside the jaws, 6 cm up
    towards the flange and out along the tool's −x (world +x, towards the default camera, with
    the gripper down at yaw 0) so the wrist hides none of it."""
    rotvec_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The board's axes in the TCP frame as a rotation vector: by default the tool's own (the
    printed face up when the gripper points down)."""

    def __post_init__(self) -> None:
        for name in ("offset_m", "rotvec_rad"):
            v = tuple(float(x) for x in getattr(self, name))
            require(
                len(v) == 3 and all(math.isfinite(x) for x in v),
                f"board mount {name} must be 3 finite numbers, got {getattr(self, name)!r}",
            )
            object.__setattr__(self, name, v)

    def T_tcp_board(self) -> np.ndarray:
        """4 × 4: board → TCP frame."""
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(self.rotvec_rad).as_matrix()
        T[:3, 3] = self.offset_m
        return T


@dataclass(frozen=True)
class CalibrationView:
    """One place to hold the board: the TCP's position (world, m) and orientation (x, y, z, w)."""

    name: str
    position: np.ndarray
    quaternion: np.ndarray


# The board's centre from the middle view (m: along the image's up, across it, and away from the
# camera), its turn about its own normal and its tilt about its own x and y (deg): a spread of
# places and rotations about three axes.
_PATTERN: tuple[tuple[float, float, float, float, float, float], ...] = (
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (0.08, 0.08, 0.0, 25.0, 0.0, 12.0),
    (0.08, -0.08, 0.0, -25.0, 12.0, 0.0),
    (-0.08, 0.08, 0.0, -15.0, -12.0, 0.0),
    (-0.08, -0.08, 0.0, 15.0, 0.0, -12.0),
    (0.0, 0.1, -0.06, 35.0, 8.0, 8.0),
    (0.0, -0.1, 0.06, -35.0, -8.0, 8.0),
    (0.1, 0.0, -0.05, 0.0, 15.0, -8.0),
    (-0.1, 0.0, -0.05, 10.0, -15.0, 8.0),
    (0.0, 0.0, 0.1, -10.0, 0.0, 18.0),
    (0.05, -0.04, -0.08, 30.0, -10.0, -10.0),
    (-0.05, 0.04, 0.08, -30.0, 10.0, 10.0),
)
MAX_VIEWS = len(_PATTERN)


def calibration_views(
    layout: CellLayout,
    look_from: tuple[float, float, float],
    board: CalibrationBoard,
    mount: BoardMount,
    count: int = MAX_VIEWS,
) -> list[CalibrationView]:
    """`count` tool poses that hold the board's centre over the workspace, its face towards
    `look_from` (world, m), each turned and tilted differently."""
    require(
        isinstance(count, int) and 4 <= count <= MAX_VIEWS,
        f"views must be an integer in [4, {MAX_VIEWS}], got {count!r}",
    )
    eye = np.asarray(look_from, dtype=float)
    require(
        eye.shape == (3,) and bool(np.isfinite(eye).all()),
        f"the camera's rough position must be 3 finite numbers (m), got {look_from!r}",
    )
    cx, cy = layout.workspace_center_xy
    # The middle view on the line from the camera to the workspace's centre (which it must
    # see), HOLD_HEIGHT over the table; the others about it, across that line and along it.
    centre_table = np.array([cx, cy, layout.table_height])
    require(
        eye[2] > layout.table_height + HOLD_HEIGHT + 0.1,
        f"the camera's rough position {eye.tolist()} must be above the held board (z > "
        f"{layout.table_height + HOLD_HEIGHT + 0.1:.2f} m): the board faces up at the camera",
    )
    ray = centre_table - eye
    ray /= np.linalg.norm(ray)
    middle = eye + ray * (eye[2] - centre_table[2] - HOLD_HEIGHT) / -ray[2]
    across = np.cross(ray, [0.0, 0.0, 1.0])
    across = (
        across / np.linalg.norm(across)
        if np.linalg.norm(across) > 1e-6
        else np.array([0.0, 1.0, 0.0])
    )
    up = np.cross(across, ray)
    T_mount = mount.T_tcp_board()
    x0, x1, y0, y1 = board.plate_bounds()
    centre_in_board = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0, 0.0])
    # The gripper down at yaw 0 (Ry(π)) holds the board's z down; turn it so z points away
    # from the camera, the least turn that does.
    down = Rotation.from_quat([0.0, 1.0, 0.0, 0.0]) * Rotation.from_matrix(T_mount[:3, :3])
    z_now = down.apply([0.0, 0.0, 1.0])
    views = []
    for k, (dx, dy, dz, turn, tilt_x, tilt_y) in enumerate(_PATTERN[:count]):
        centre = middle + dx * up + dy * across + dz * ray
        away = centre - eye
        away /= np.linalg.norm(away)
        axis = np.cross(z_now, away)
        angle = math.atan2(np.linalg.norm(axis), float(np.dot(z_now, away)))
        aim = Rotation.from_rotvec(axis / max(np.linalg.norm(axis), 1e-12) * angle)
        R_board = aim * down * Rotation.from_euler("xyz", [tilt_x, tilt_y, turn], degrees=True)
        R_tcp = R_board * Rotation.from_matrix(T_mount[:3, :3]).inv()
        origin = centre - R_board.apply(centre_in_board)
        position = origin - R_tcp.apply(T_mount[:3, 3])
        views.append(CalibrationView(f"view {k}", position, R_tcp.as_quat()))
    return views
