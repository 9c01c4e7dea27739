"""The calibration board: a printed chessboard, its corners found in a colour image and its pose
in the camera from them (OpenCV).

Board frame: the origin at the first inner corner, x along the board's longer row of inner
corners, y along the shorter, z into the board (away from its printed face), so a board facing
the camera has its z roughly along the camera's optical axis. Square (a, b) spans
x ∈ [(a − 1)·s, a·s], y ∈ [(b − 1)·s, b·s] and is black when a + b is even; with an odd number of
squares in all (`squares_x + squares_y`) the board looks different turned by 180°, so the corner
order is fixed by the square at the origin being black.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from foldbot.errors import require


@dataclass(frozen=True)
class Chessboard:
    """A chessboard of `squares_x` × `squares_y` squares of `square_m` metres, printed on a white
    plate with a `margin_m` border."""

    squares_x: int = 8
    """Squares along the board's x (its longer side)."""
    squares_y: int = 5
    """Squares along its y."""
    square_m: float = 0.024
    """A square's side (m)."""
    margin_m: float = 0.02
    """The white border around the squares (m): the detector needs it."""

    def __post_init__(self) -> None:
        for name in ("squares_x", "squares_y"):
            v = getattr(self, name)
            require(
                isinstance(v, int) and not isinstance(v, bool) and 3 <= v <= 30,
                f"board {name} must be an integer in [3, 30], got {v!r}",
            )
        require(
            (self.squares_x + self.squares_y) % 2 == 1 and self.squares_x > self.squares_y,
            f"board squares must be more along x than y and odd in all (e.g. 8 × 5) so its "
            f"corners have one order, got {self.squares_x} × {self.squares_y}",
        )
        for name, low, high in (("square_m", 0.005, 0.2), ("margin_m", 0.0, 0.2)):
            v = getattr(self, name)
            require(
                isinstance(v, int | float) and math.isfinite(v) and low < v <= high,
                f"board {name} must be in ({low}, {high}] m, got {v!r}",
            )

    @property
    def pattern_size(self) -> tuple[int, int]:
        """Inner corners along x and y, as OpenCV's detectors take them."""
        return self.squares_x - 1, self.squares_y - 1

    def object_points(self) -> np.ndarray:
        """The inner corners in the board frame (N × 3, m), in the detector's row-major order."""
        nx, ny = self.pattern_size
        j, i = np.mgrid[0:ny, 0:nx]
        pts = np.stack([i.ravel(), j.ravel(), np.zeros(nx * ny)], axis=1)
        return pts * self.square_m

    def squares(self) -> list[tuple[float, float, bool]]:
        """Every square's centre (x, y in the board frame, m) and whether it is black."""
        s = self.square_m
        return [
            ((a - 0.5) * s, (b - 0.5) * s, (a + b) % 2 == 0)
            for a in range(self.squares_x)
            for b in range(self.squares_y)
        ]

    def plate_bounds(self) -> tuple[float, float, float, float]:
        """The plate's extent in the board frame: x min, x max, y min, y max (m)."""
        s, m = self.square_m, self.margin_m
        return (-s - m, (self.squares_x - 1) * s + m, -s - m, (self.squares_y - 1) * s + m)


def detect_corners(rgb: np.ndarray, board: Chessboard) -> np.ndarray | None:
    """The board's inner corners in a colour image (N × 2 px, (u, v), in `object_points`' order),
    or None where the whole board is not seen."""
    gray = cv2.cvtColor(np.ascontiguousarray(rgb[..., :3], dtype=np.uint8), cv2.COLOR_RGB2GRAY)
    found, corners = cv2.findChessboardCornersSB(
        gray, board.pattern_size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_ACCURACY
    )
    if not found:
        return None
    nx, ny = board.pattern_size
    grid = corners.reshape(ny, nx, 2).astype(float)
    # A right-handed order: board x then y turn as the image's x then y (the board faces the
    # camera, z along the optical axis); the detector may start at either end of a column.
    ex, ey = grid[0, 1] - grid[0, 0], grid[1, 0] - grid[0, 0]
    if ex[0] * ey[1] - ex[1] * ey[0] < 0.0:
        grid = grid[::-1]
    # Turned by 180°: the square beyond the first corner is black, the next one along x white.
    ex, ey = grid[0, 1] - grid[0, 0], grid[1, 0] - grid[0, 0]
    black = _mean_around(gray, grid[0, 0] - 0.5 * ex - 0.5 * ey, ex, ey)
    white = _mean_around(gray, grid[0, 0] + 0.5 * ex - 0.5 * ey, ex, ey)
    if black > white:
        grid = grid[::-1, ::-1]
    return grid.reshape(-1, 2)


def _mean_around(gray: np.ndarray, centre: np.ndarray, ex: np.ndarray, ey: np.ndarray) -> float:
    """Mean intensity of the pixels within a quarter square of `centre` (a square's axes ex, ey)."""
    r = max(1, int(0.25 * min(np.linalg.norm(ex), np.linalg.norm(ey))))
    u, v = round(centre[0]), round(centre[1])
    h, w = gray.shape
    patch = gray[max(0, v - r) : min(h, v + r + 1), max(0, u - r) : min(w, u + r + 1)]
    return float(patch.mean()) if patch.size else 127.0


def board_pose(
    corners: np.ndarray, board: Chessboard, K: np.ndarray, dist: np.ndarray | None = None
) -> np.ndarray:
    """T_camera_board (4 × 4) from the detected corners: PnP on the planar board."""
    obj = board.object_points()
    img = np.asarray(corners, dtype=float).reshape(-1, 1, 2)
    d = np.zeros(5) if dist is None else np.asarray(dist, dtype=float)
    ok, rvec, tvec = cv2.solvePnP(obj, img, np.asarray(K, dtype=float), d, flags=cv2.SOLVEPNP_IPPE)
    if ok:
        ok, rvec, tvec = cv2.solvePnP(
            obj, img, K, d, rvec, tvec, useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE
        )
    require(bool(ok), "the board's pose could not be solved from its corners")
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(rvec)[0]
    T[:3, 3] = tvec.ravel()
    return T


def board_image(board: Chessboard, px_per_m: float) -> np.ndarray:
    """The board as printed: its plate white, its black squares, `px_per_m` pixels a metre
    (H × W uint8; the first inner corner where the board frame's origin is)."""
    require(
        math.isfinite(px_per_m) and 1000.0 <= px_per_m <= 100000.0,
        f"the board's resolution must be in [1000, 100000] px/m, got {px_per_m!r}",
    )
    x0, x1, y0, y1 = board.plate_bounds()
    width, height = round((x1 - x0) * px_per_m), round((y1 - y0) * px_per_m)
    img = np.full((height, width), 255, np.uint8)
    s = board.square_m
    for x, y, black in board.squares():
        if black:
            u0, u1 = round((x - s / 2 - x0) * px_per_m), round((x + s / 2 - x0) * px_per_m)
            v0, v1 = round((y - s / 2 - y0) * px_per_m), round((y + s / 2 - y0) * px_per_m)
            img[v0:v1, u0:u1] = 0
    return img
