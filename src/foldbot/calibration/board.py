"""The calibration board: a printed chessboard or ChArUco board, its corners found in a colour
image and its pose in the camera from them (OpenCV).

A chessboard is found only whole; a ChArUco board (a chessboard with an ArUco marker in each
white square) names each corner by its markers, so a view where the arm, the image's edge or
glare hides part of it still counts.

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
from typing import Any

import cv2
import numpy as np

from foldbot.errors import require


def _check_grid(board: Chessboard | CharucoBoard) -> None:
    """ConfigError naming a board's squares or sizes that cannot be."""
    for name in ("squares_x", "squares_y"):
        v = getattr(board, name)
        require(
            isinstance(v, int) and not isinstance(v, bool) and 3 <= v <= 30,
            f"board {name} must be an integer in [3, 30], got {v!r}",
        )
    for name, low, high in (("square_m", 0.005, 0.2), ("margin_m", 0.0, 0.2)):
        v = getattr(board, name)
        require(
            isinstance(v, int | float) and math.isfinite(v) and low < v <= high,
            f"board {name} must be in ({low}, {high}] m, got {v!r}",
        )


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
        _check_grid(self)
        require(
            (self.squares_x + self.squares_y) % 2 == 1 and self.squares_x > self.squares_y,
            f"board squares must be more along x than y and odd in all (e.g. 8 × 5) so its "
            f"corners have one order, got {self.squares_x} × {self.squares_y}",
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

    pattern = "chessboard"

    def black_rects(self) -> list[tuple[float, float, float, float]]:
        """What is printed black: rectangles x min, x max, y min, y max (board frame, m)."""
        s = self.square_m
        return [
            (x - s / 2, x + s / 2, y - s / 2, y + s / 2) for x, y, black in self.squares() if black
        ]

    def record(self) -> dict[str, Any]:
        """The board as calibration.json names it."""
        return {
            "pattern": self.pattern,
            "squares": [self.squares_x, self.squares_y],
            "square_m": self.square_m,
        }

    def find(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The corners seen: their indices into `object_points` and pixels (N × 2), or None
        where the board is not seen whole."""
        px = detect_corners(rgb, self)
        return None if px is None else (np.arange(len(px)), px)

    @property
    def unseen_reason(self) -> str:
        """Why a view's corners were not enough."""
        return "the board was not seen whole"


ARUCO_DICTIONARIES = {
    "4x4_50": cv2.aruco.DICT_4X4_50,
    "4x4_100": cv2.aruco.DICT_4X4_100,
    "5x5_100": cv2.aruco.DICT_5X5_100,
    "6x6_250": cv2.aruco.DICT_6X6_250,
}
"""The ArUco dictionaries a ChArUco board may use, by name (OpenCV's DICT_4X4_50 and so on)."""
CHARUCO_REFINE_HALF_WINDOW = (2, 2)
"""cornerSubPix's half window for the ChArUco corners (px): 5 × 5 px about each."""
MIN_CHARUCO_CORNERS = 6
"""Fewest ChArUco corners a view needs (its pose from a planar PnP, and not all on one line)."""


@dataclass(frozen=True)
class CharucoBoard:
    """A ChArUco board: a chessboard of `squares_x` × `squares_y` squares of `square_m` metres
    with an ArUco marker of `marker_m` in each white square (OpenCV's layout: the square at the
    board's corner black), on a white plate with a `margin_m` border. Its frame is the
    chessboard's (module docstring of Chessboard): the origin at the first inner corner."""

    squares_x: int = 6
    """Squares along the board's x (its longer side, or as long)."""
    squares_y: int = 4
    """Squares along its y."""
    square_m: float = 0.036
    """A square's side (m)."""
    marker_m: float = 0.027
    """A marker's side (m), black border included: smaller than the square."""
    dictionary: str = "4x4_50"
    """The markers' ArUco dictionary (ARUCO_DICTIONARIES)."""
    margin_m: float = 0.02
    """The white border around the squares (m)."""

    pattern = "charuco"

    def __post_init__(self) -> None:
        _check_grid(self)
        require(
            self.squares_x >= self.squares_y,
            f"board squares must be at least as many along x as along y, got "
            f"{self.squares_x} × {self.squares_y}",
        )
        m = self.marker_m
        require(
            isinstance(m, int | float)
            and math.isfinite(m)
            and 0.4 * self.square_m <= m <= 0.9 * self.square_m,
            f"board marker_m must be 0.4–0.9 of the square ({self.square_m} m), got {m!r}",
        )
        require(
            self.dictionary in ARUCO_DICTIONARIES,
            f"board dictionary must be one of {sorted(ARUCO_DICTIONARIES)}, got "
            f"{self.dictionary!r}",
        )
        size = self._dictionary().bytesList.shape[0]
        markers = self.squares_x * self.squares_y // 2
        require(
            markers <= size,
            f"a {self.squares_x} × {self.squares_y} board needs {markers} markers, more than "
            f"dictionary {self.dictionary}'s {size}",
        )

    def _dictionary(self) -> cv2.aruco.Dictionary:
        return cv2.aruco.getPredefinedDictionary(ARUCO_DICTIONARIES[self.dictionary])

    def _board(self) -> cv2.aruco.CharucoBoard:
        return cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_m, self.marker_m, self._dictionary()
        )

    @property
    def pattern_size(self) -> tuple[int, int]:
        """Inner corners along x and y."""
        return self.squares_x - 1, self.squares_y - 1

    def object_points(self) -> np.ndarray:
        """The inner corners in the board frame (N × 3, m), in the ChArUco corner ids' order
        (row-major, as the chessboard's)."""
        s = self.square_m
        return np.asarray(self._board().getChessboardCorners(), dtype=float) - [s, s, 0.0]

    def plate_bounds(self) -> tuple[float, float, float, float]:
        """The plate's extent in the board frame: x min, x max, y min, y max (m)."""
        s, m = self.square_m, self.margin_m
        return (-s - m, (self.squares_x - 1) * s + m, -s - m, (self.squares_y - 1) * s + m)

    def black_rects(self) -> list[tuple[float, float, float, float]]:
        """What is printed black, as rectangles x min, x max, y min, y max (board frame, m): the
        black squares, each marker's border and its black cells (merged along each row)."""
        s = self.square_m
        rects = [
            ((a - 1) * s, a * s, (b - 1) * s, b * s)
            for a in range(self.squares_x)
            for b in range(self.squares_y)
            if (a + b) % 2 == 0
        ]
        board, dictionary = self._board(), self._dictionary()
        bits_n = dictionary.markerSize
        cells = bits_n + 2  # a one-cell black border around the marker's bits
        cell = self.marker_m / cells
        for corners, marker_id in zip(board.getObjPoints(), board.getIds().ravel(), strict=True):
            x0, y0 = np.asarray(corners, dtype=float)[0, :2] - s  # its top-left corner
            bits = cv2.aruco.Dictionary.getBitsFromByteList(
                dictionary.bytesList[int(marker_id)].reshape(1, -1, 4), bits_n
            )
            grid = np.zeros((cells, cells), bool)  # True: white
            grid[1:-1, 1:-1] = bits.astype(bool)
            for col0, col1, row0, row1 in _black_runs(grid):
                rects.append(
                    (x0 + col0 * cell, x0 + col1 * cell, y0 + row0 * cell, y0 + row1 * cell)
                )
        return rects

    def record(self) -> dict[str, Any]:
        """The board as calibration.json names it."""
        return {
            "pattern": self.pattern,
            "squares": [self.squares_x, self.squares_y],
            "square_m": self.square_m,
            "marker_m": self.marker_m,
            "dictionary": self.dictionary,
        }

    def find(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The corners seen (OpenCV's CharucoDetector): their ids (indices into
        `object_points`) and pixels (N × 2), or None where fewer than MIN_CHARUCO_CORNERS."""
        gray = cv2.cvtColor(np.ascontiguousarray(rgb[..., :3], dtype=np.uint8), cv2.COLOR_RGB2GRAY)
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        detector = cv2.aruco.CharucoDetector(self._board(), cv2.aruco.CharucoParameters(), params)
        corners, ids, _marker_corners, _marker_ids = detector.detectBoard(gray)
        if ids is None or len(ids) < MIN_CHARUCO_CORNERS:
            return None
        ids = np.asarray(ids, dtype=int).ravel()
        # Refined again in a 5 × 5 px window: the detector's own refinement, in a window sized
        # to the markers, is twice as far off on a low-resolution board (docs/experiments.md).
        refined = np.asarray(corners, dtype=np.float32).reshape(-1, 1, 2)
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
        cv2.cornerSubPix(gray, refined, CHARUCO_REFINE_HALF_WINDOW, (-1, -1), criteria)
        px = refined.reshape(-1, 2).astype(float)
        obj = self.object_points()[ids]
        # Corners all on one line give no pose.
        if np.linalg.matrix_rank(obj[:, :2] - obj[0, :2], tol=1e-9) < 2:
            return None
        return ids, px

    @property
    def unseen_reason(self) -> str:
        """Why a view's corners were not enough."""
        return f"fewer than {MIN_CHARUCO_CORNERS} of the board's corners were seen"


def _black_runs(white: np.ndarray) -> list[tuple[int, int, int, int]]:
    """A grid's black cells as few rectangles (columns col0–col1, rows row0–row1, ends
    excluded): each row's runs, a run merged with the one below it where they span the same
    columns (a marker's border and bits in 6–10 rectangles, not one a cell)."""
    open_runs: dict[tuple[int, int], int] = {}  # (col0, col1) → the row it started on
    done = []
    rows, cols = white.shape
    for row in range(rows + 1):
        runs = set()
        col = 0
        while row < rows and col < cols:
            if white[row, col]:
                col += 1
                continue
            end = col
            while end < cols and not white[row, end]:
                end += 1
            runs.add((col, end))
            col = end
        for run in list(open_runs):
            if run not in runs:
                done.append((*run, open_runs.pop(run), row))
        for run in runs:
            open_runs.setdefault(run, row)
    return sorted(done, key=lambda r: (r[2], r[0]))


CalibrationBoard = Chessboard | CharucoBoard
"""Either board; both give object_points, plate_bounds, black_rects, find and record."""


def find_corners(rgb: np.ndarray, board: CalibrationBoard) -> tuple[np.ndarray, np.ndarray] | None:
    """The board's corners seen in a colour image: indices into `board.object_points()` and
    pixels (N × 2), or None where too little of it is seen (`board.unseen_reason`)."""
    return board.find(rgb)


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
    corners: np.ndarray,
    board: CalibrationBoard,
    K: np.ndarray,
    dist: np.ndarray | None = None,
    ids: np.ndarray | None = None,
) -> np.ndarray:
    """T_camera_board (4 × 4) from the detected corners (those `ids` of the board's, or all):
    PnP on the planar board."""
    obj = board.object_points() if ids is None else board.object_points()[np.asarray(ids)]
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


MAX_BOARD_PIXELS = 600e6
"""Largest board image drawn (pixels, a byte each): a whole A0 sheet at 600 dpi is 558 million;
a larger image is a slip in the board's size or resolution, not a print."""


def board_image(board: CalibrationBoard, px_per_m: float) -> np.ndarray:
    """The board as printed: its plate white, its black squares (and markers), `px_per_m`
    pixels a metre (H × W uint8; the first inner corner where the board frame's origin is)."""
    require(
        math.isfinite(px_per_m) and 1000.0 <= px_per_m <= 100000.0,
        f"the board's resolution must be in [1000, 100000] px/m, got {px_per_m!r}",
    )
    x0, x1, y0, y1 = board.plate_bounds()
    width, height = round((x1 - x0) * px_per_m), round((y1 - y0) * px_per_m)
    require(
        width * height <= MAX_BOARD_PIXELS,
        f"the board, {x1 - x0:.3g} × {y1 - y0:.3g} m, would be {width} × {height} px at "
        f"{px_per_m:.6g} px/m: at most {MAX_BOARD_PIXELS / 1e6:g} megapixels; choose fewer or "
        "smaller squares, or a lower resolution",
    )
    img = np.full((height, width), 255, np.uint8)
    for a0, a1, b0, b1 in board.black_rects():
        u0, u1 = round((a0 - x0) * px_per_m), round((a1 - x0) * px_per_m)
        v0, v1 = round((b0 - y0) * px_per_m), round((b1 - y0) * px_per_m)
        img[v0:v1, u0:u1] = 0
    return img
