"""Eye-to-hand calibration: a fixed camera's pose in the world from a board the arm holds.

Each view i gives the tool's pose A_i = T_world_tcp (the arm's joint readings through its
kinematics) and the board's pose B_i = T_camera_board (PnP on its corners). With X = T_world_camera
and Y = T_tcp_board both unknown and fixed, X·B_i = A_i·Y for every view. Pairs of views remove Y
(A_j·A_i⁻¹·X = X·B_j·B_i⁻¹, the classic AX = XB, solved as Park and Martin do: rotation from the
rotation vectors, translation by least squares), then both are refined together on every corner's
reprojection error (scipy least squares through OpenCV's projection, the camera's distortion
included).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from foldbot.calibration.board import CalibrationBoard
from foldbot.errors import require

MIN_VIEWS = 4
"""Views the solve needs (three already fix it; one more lets it disagree with itself)."""
MIN_TURN_RAD = np.deg2rad(5.0)
"""Pairs of views whose tools turned less than this between them say too little of the rotation."""


@dataclass(frozen=True)
class HandEyeSolution:
    """The camera's pose in the world and the board's on the tool, and how well they agree with
    what was seen."""

    T_world_camera: np.ndarray
    """4 × 4: OpenCV camera coordinates → world."""
    T_tcp_board: np.ndarray
    """4 × 4: board → the tool (TCP) frame it is fixed to."""
    reprojection_rms_px: float
    """RMS distance between every detected corner and its reprojection through the solution."""
    view_rms_px: tuple[float, ...]
    """The same for each view."""
    board_disagreement_m: tuple[float, ...]
    """For each view, how far apart the board's origin is as the camera sees it (X·B_i) and as
    the arm holds it (A_i·Y): the solution's consistency, measurable on a real cell."""
    board_disagreement_rad: tuple[float, ...]
    """The same for the board's orientation."""


def _T(rotvec: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


def _params(T: np.ndarray) -> np.ndarray:
    return np.concatenate([Rotation.from_matrix(T[:3, :3]).as_rotvec(), T[:3, 3]])


def _initial(A: list[np.ndarray], B: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """X and Y from pairs of views (Park–Martin on AX = XB), Y averaged over the views."""
    alphas, betas, rows, rhs = [], [], [], []
    pairs = []
    for i, j in itertools.combinations(range(len(A)), 2):
        P = A[j] @ np.linalg.inv(A[i])
        Q = B[j] @ np.linalg.inv(B[i])
        a = Rotation.from_matrix(P[:3, :3]).as_rotvec()
        b = Rotation.from_matrix(Q[:3, :3]).as_rotvec()
        if np.linalg.norm(a) < MIN_TURN_RAD:
            continue
        alphas.append(a)
        betas.append(b)
        pairs.append((P, Q))
    require(
        len(alphas) >= 2,
        f"the views turn the tool too little between them to fix the camera's rotation (at "
        f"least two pairs must differ by {np.rad2deg(MIN_TURN_RAD):.0f}° or more)",
    )
    R_x, _ = Rotation.align_vectors(np.asarray(alphas), np.asarray(betas))
    Rx = R_x.as_matrix()
    for P, Q in pairs:
        rows.append(P[:3, :3] - np.eye(3))
        rhs.append(Rx @ Q[:3, 3] - P[:3, 3])
    tx = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = Rx, tx
    Ys = [np.linalg.inv(a) @ X @ b for a, b in zip(A, B, strict=True)]
    Y = np.eye(4)
    Y[:3, :3] = Rotation.from_matrix(np.array([y[:3, :3] for y in Ys])).mean().as_matrix()
    Y[:3, 3] = np.mean([y[:3, 3] for y in Ys], axis=0)
    return X, Y


def solve_eye_to_hand(
    T_world_tcp: list[np.ndarray],
    T_camera_board: list[np.ndarray],
    corners: list[np.ndarray],
    board: CalibrationBoard,
    K: np.ndarray,
    dist: np.ndarray | None = None,
    corner_ids: list[np.ndarray | None] | None = None,
    max_evaluations: int | None = None,
) -> HandEyeSolution:
    """The camera's pose in the world (and the board's on the tool) from views of the board the
    arm holds: the tool's pose, the board's PnP pose and its detected corners per view (which
    of the board's corners each view saw: `corner_ids`, None for all). `max_evaluations` cuts
    the least-squares refinement short (a trial solve)."""
    n = len(T_world_tcp)
    require(
        n == len(T_camera_board) == len(corners),
        f"every view needs a tool pose, a board pose and corners; got {n}, "
        f"{len(T_camera_board)} and {len(corners)}",
    )
    require(n >= MIN_VIEWS, f"a calibration needs at least {MIN_VIEWS} views of the board, got {n}")
    A = [np.asarray(a, dtype=float) for a in T_world_tcp]
    B = [np.asarray(b, dtype=float) for b in T_camera_board]
    X0, Y0 = _initial(A, B)
    ids = [None] * n if corner_ids is None else list(corner_ids)
    require(len(ids) == n, f"corner_ids must name each view's corners, got {len(ids)} for {n}")
    every = board.object_points()
    objs = [every if i is None else every[np.asarray(i, dtype=int)] for i in ids]
    K = np.asarray(K, dtype=float)
    d = np.zeros(5) if dist is None else np.asarray(dist, dtype=float)
    seen = [np.asarray(c, dtype=float).reshape(-1, 2) for c in corners]
    for k, (o, c) in enumerate(zip(objs, seen, strict=True)):
        require(len(o) == len(c), f"view {k}: {len(c)} corners seen for {len(o)} corner ids")
    views = list(zip(A, seen, objs, strict=True))

    def project(X: np.ndarray, Y: np.ndarray, a: np.ndarray, obj: np.ndarray) -> np.ndarray:
        T = np.linalg.inv(X) @ a @ Y  # board → camera as the arm holds it
        rvec = cv2.Rodrigues(T[:3, :3])[0]
        return cv2.projectPoints(obj, rvec, T[:3, 3], K, d)[0].reshape(-1, 2)

    def residuals(x: np.ndarray) -> np.ndarray:
        X, Y = _T(x[0:3], x[3:6]), _T(x[6:9], x[9:12])
        return np.concatenate([(project(X, Y, a, o) - c).ravel() for a, c, o in views])

    fit = least_squares(
        residuals,
        np.concatenate([_params(X0), _params(Y0)]),
        x_scale="jac",
        max_nfev=max_evaluations,
    )
    X, Y = _T(fit.x[0:3], fit.x[3:6]), _T(fit.x[6:9], fit.x[9:12])
    per_view = [
        float(np.sqrt(np.mean(np.sum((project(X, Y, a, o) - c) ** 2, axis=1)))) for a, c, o in views
    ]
    all_sq = np.concatenate([np.sum((project(X, Y, a, o) - c) ** 2, axis=1) for a, c, o in views])
    dist_m, dist_rad = [], []
    for a, b in zip(A, B, strict=True):
        by_camera, by_arm = X @ b, a @ Y
        dist_m.append(float(np.linalg.norm(by_camera[:3, 3] - by_arm[:3, 3])))
        turn = Rotation.from_matrix(by_camera[:3, :3].T @ by_arm[:3, :3]).magnitude()
        dist_rad.append(float(turn))
    return HandEyeSolution(
        T_world_camera=X,
        T_tcp_board=Y,
        reprojection_rms_px=float(np.sqrt(np.mean(all_sq))),
        view_rms_px=tuple(per_view),
        board_disagreement_m=tuple(dist_m),
        board_disagreement_rad=tuple(dist_rad),
    )


def pose_error(T_estimated: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """How far apart two poses are: translation (m) and rotation (rad)."""
    dt = float(np.linalg.norm(T_estimated[:3, 3] - T_true[:3, 3]))
    dr = Rotation.from_matrix(T_estimated[:3, :3].T @ T_true[:3, :3]).magnitude()
    return dt, float(dr)


def pose_error_record(T_estimated: np.ndarray, T_true: np.ndarray) -> dict[str, float]:
    """pose_error as a record keeps it: a calibrated camera pose against the true one, in mm
    and degrees."""
    dt, dr = pose_error(np.asarray(T_estimated, float), np.asarray(T_true, float))
    return {"calibration_error_mm": 1000.0 * dt, "calibration_error_deg": math.degrees(dr)}
