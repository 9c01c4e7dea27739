"""A calibration run on any cell: hold the board at each view, read the tool's pose from the
joints and the board's corners from the image, solve, and write what came of it.

`CalibrationCell` is what a cell gives the run (the simulated cell in process,
`calibration.sim_cell`; a running cell over ROS, `foldbot.ros.calibrate_node`); the run itself
never sees where the camera is.
"""

from __future__ import annotations

import abc
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import imageio.v3 as iio
import numpy as np
from scipy.spatial.transform import Rotation

from foldbot.calibration.board import CalibrationBoard, board_pose, find_corners
from foldbot.calibration.hand_eye import MIN_VIEWS, HandEyeSolution, solve_eye_to_hand
from foldbot.calibration.views import CalibrationView
from foldbot.errors import ConfigError, OutputError, PerceptionError, UnreachableTargetError
from foldbot.operator import ArmMove, OperatorGate

CAMERA_FRAME = "camera_color_optical_frame"
WORLD_FRAME = "world"
OUTLIER_PX = 1.0
"""A solve whose corners reproject worse than this (px RMS; a sound one reprojects within a few
tenths) looks for a view to drop: a board seen mid-swing, a joint reading off, a corner found on
the wrong edge."""
TRIAL_EVALUATIONS = 40
"""Residual evaluations a trial solve (one view left out) may take: a sound one converges in a
handful, one of views that disagree takes ~200 (a second) and is bad whichever way it ends."""
MAX_RMS_PX = 2.0
"""A solve that still reprojects worse than this (px RMS) after dropping views is refused, not
written: its views disagree (wrong corner order, wrong intrinsics, a board that slipped)."""


VIEW_WORDS = "joint move holding the board up to the camera"
"""What a view's move does, as the operator is told (`--confirm`)."""


class CalibrationCell(abc.ABC):
    """What a calibration needs from a cell: the camera's intrinsics, an arm that goes where it
    is told, and a frame with the tool's pose at it."""

    @abc.abstractmethod
    def intrinsics(self) -> tuple[np.ndarray, np.ndarray, int, int]:
        """K (3 × 3), distortion coefficients, image width and height (px)."""

    @abc.abstractmethod
    def move_to(self, view: CalibrationView) -> None:
        """Move the tool to the view's pose and let it come to rest; UnreachableTargetError,
        before moving, where the arm cannot go there."""

    @abc.abstractmethod
    def frame(self) -> tuple[np.ndarray, np.ndarray]:
        """A colour image (H × W × 3 uint8) and the tool's pose at it (4 × 4 T_world_tcp, from
        the joints read back)."""

    def finish(self) -> None:  # noqa: B027 - optional
        """Take the arm back out of the way (its home)."""

    gate: OperatorGate | None = None
    """Where set (`--confirm`), the operator is asked before each move (confirm_move)."""
    arm_index: int = 0
    """The arm that holds the board (0, or 1 of two), as the operator is told."""

    def rest_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Where the arm stands now and where `finish` takes it back to (joint angles, rad)."""
        raise NotImplementedError(f"{type(self).__name__} plans no dry run")

    planner: Any = None
    """The ArmExecutor on the arm's kinematic twin every move is planned on (IK, the table and
    the layout's obstacles checked, time-parametrised); `planner.model` is the twin."""

    def confirm_move(self, label: str, what: str, seconds: float) -> None:
        """Before a move: with a gate, what it will do is said and the operator's answer awaited
        (OperatorStopped on stop); without one, nothing."""
        if self.gate is not None:
            self.gate.ask([ArmMove(label, (self.arm_index,), what, seconds)])


@dataclass
class Capture:
    """What one view gave."""

    view: CalibrationView
    T_world_tcp: np.ndarray | None = None
    rgb: np.ndarray | None = None
    corners: np.ndarray | None = None
    """The board's corners seen (N × 2 px)."""
    T_camera_board: np.ndarray | None = None
    corner_ids: np.ndarray | None = None
    """Which of the board's corners `corners` are (indices into its object_points); None: all."""
    dropped: str = ""
    """Why the view is not in the solve ("" if it is)."""


def pose_matrix(position: np.ndarray, quaternion: np.ndarray) -> np.ndarray:
    """4 × 4 from a position and an (x, y, z, w) quaternion."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(quaternion).as_matrix()
    T[:3, 3] = position
    return T


def plan_views(
    cell: CalibrationCell,
    views: list[CalibrationView],
    progress: Callable[[str], None] = lambda line: None,
) -> dict[str, Any]:
    """A dry run (`--dry-run`): every view's move planned in turn from where the arm stands, as
    capture_views would make it (IK seeded from the view before, the joint move checked against
    the table and the layout's obstacles, its time under the joint limits), then the move back;
    nothing moves. plan.json's content: each view feasible with its seconds, or why not."""
    planner = cell.planner
    q, back_to = cell.rest_positions()
    entries: list[dict[str, Any]] = []
    for view in views:
        entry: dict[str, Any] = {"view": view.name, "tcp_m": [float(v) for v in view.position]}
        try:
            q_next = planner.model.solve_ik(view.position, view.quaternion, q_seed=q)
            planner.check_joint_move(q, q_next)
            seconds = planner.joint_move_trajectory(q, q_next).duration
        except UnreachableTargetError as exc:
            entries.append(entry | {"feasible": False, "reason": str(exc)})
            progress(f"{view.name}: NOT feasible: {exc}")
            continue
        entries.append(entry | {"feasible": True, "seconds": seconds})
        progress(f"{view.name}: {seconds:.1f} s of motion")
        q = q_next
    back = planner.joint_move_trajectory(q, back_to).duration
    feasible = sum(e["feasible"] for e in entries)
    return {
        "dry_run": True,
        "views": entries,
        "views_feasible": feasible,
        "back_seconds": back,
        "motion_seconds": sum(e.get("seconds", 0.0) for e in entries) + back,
        "feasible": feasible == len(entries),
    }


def capture_views(
    cell: CalibrationCell,
    views: list[CalibrationView],
    board: CalibrationBoard,
    progress: Callable[[str], None] = lambda line: None,
) -> list[Capture]:
    """Hold the board at every view in turn; each view's image, tool pose and corners, or why
    it was dropped (out of reach, the board not seen)."""
    K, dist, _, _ = cell.intrinsics()
    captures = []
    for view in views:
        cap = Capture(view)
        try:
            cell.move_to(view)
        except UnreachableTargetError as exc:
            cap.dropped = f"out of reach: {exc}"
            captures.append(cap)
            progress(f"{view.name}: {cap.dropped}")
            continue
        cap.rgb, cap.T_world_tcp = cell.frame()
        found = find_corners(cap.rgb, board)
        if found is None:
            cap.dropped = board.unseen_reason
        else:
            cap.corner_ids, cap.corners = found
            cap.T_camera_board = board_pose(cap.corners, board, K, dist, cap.corner_ids)
        total = len(board.object_points())
        seen = (
            ""
            if found is None or len(found[0]) == total
            else f" ({len(found[0])} of {total} corners)"
        )
        progress(f"{view.name}: {cap.dropped or 'board seen' + seen}")
        captures.append(cap)
    cell.finish()
    return captures


def solve_captures(
    captures: list[Capture], board: CalibrationBoard, K: np.ndarray, dist: np.ndarray
) -> HandEyeSolution:
    """The solve over every view that saw the board. While its corners reproject worse than
    OUTLIER_PX, the view without which the rest agree best is dropped (marked so) if that at
    least halves the error: one bad view spreads its error over all the others."""
    used = [c for c in captures if not c.dropped]
    if len(used) < MIN_VIEWS:
        reasons = "; ".join(f"{c.view.name}: {c.dropped}" for c in captures if c.dropped)
        raise PerceptionError(
            f"only {len(used)} of {len(captures)} views saw the board (at least {MIN_VIEWS} "
            f"needed){': ' + reasons if reasons else ''}"
        )

    def solve(views: list[Capture], max_evaluations: int | None = None) -> HandEyeSolution:
        return solve_eye_to_hand(
            [c.T_world_tcp for c in views],
            [c.T_camera_board for c in views],
            [c.corners for c in views],
            board,
            K,
            dist,
            [c.corner_ids for c in views],
            max_evaluations,
        )

    def drop_worst(
        views: list[Capture], solution: HandEyeSolution, must_halve: bool
    ) -> tuple[HandEyeSolution, list[tuple[Capture, str]]]:
        """While the solve reprojects worse than OUTLIER_PX, drop the view without which the
        rest agree best (where `must_halve`, only if that at least halves the error); the
        trial solves cut short (TRIAL_EVALUATIONS: views that agree converge in a handful),
        the kept views solved in full."""
        drops = []
        while solution.reprojection_rms_px > OUTLIER_PX and len(views) > MIN_VIEWS:
            trials = [
                (solve(views[:k] + views[k + 1 :], TRIAL_EVALUATIONS), k) for k in range(len(views))
            ]
            best, k = min(trials, key=lambda trial: trial[0].reprojection_rms_px)
            if must_halve and best.reprojection_rms_px > 0.5 * solution.reprojection_rms_px:
                break
            why = (
                f"disagreed with the rest: {solution.reprojection_rms_px:.2f} px RMS with it, "
                f"{best.reprojection_rms_px:.2f} without"
            )
            drops.append((views[k], why))
            views, solution = views[:k] + views[k + 1 :], best
        return (solve(views) if drops else solution), drops

    first = solve(used)
    solution, drops = drop_worst(used, first, must_halve=True)
    if solution.reprojection_rms_px > MAX_RMS_PX:
        # Two or more views wrong together (a chessboard's corners ordered wrongly where it
        # runs off the image) halve nothing one at a time: the fewest views that agree.
        solution, drops = drop_worst(used, first, must_halve=False)
    if solution.reprojection_rms_px > MAX_RMS_PX:
        per_view = ", ".join(
            f"{c.view.name} {rms:.1f}" for c, rms in zip(used, first.view_rms_px, strict=True)
        )
        raise PerceptionError(
            f"no {MIN_VIEWS} or more views agree: the best solve reprojects the corners "
            f"{solution.reprojection_rms_px:.1f} px RMS (a sound one within a few tenths, at "
            f"most {MAX_RMS_PX:g} accepted); per view, px RMS: {per_view}. Check the camera's "
            "intrinsics and the board's size; a chessboard partly out of the image can be "
            "found in the wrong order (--board-pattern charuco names each corner)"
        )
    for cap, why in drops:
        cap.dropped = why
    return solution


def _quat(T: np.ndarray) -> list[float]:
    return Rotation.from_matrix(T[:3, :3]).as_quat().tolist()


def launch_text(T_world_camera: np.ndarray) -> str:
    """A roslaunch file that publishes the calibrated camera pose on /tf_static (foldbot's own
    static publisher; tf2_ros's static_transform_publisher takes the same arguments)."""
    args = " ".join(pose_words(T_world_camera, WORLD_FRAME, CAMERA_FRAME))
    return (
        "<launch>\n"
        "  <!-- The camera's pose from foldbot's calibration: world → the colour camera's optical\n"
        "       frame (x right, y down, z forward), as foldbot's perception node reads it. With\n"
        '       tf2_ros installed, pkg="tf2_ros" type="static_transform_publisher" takes the\n'
        "       same args. -->\n"
        '  <node pkg="foldbot_ros" type="camera_pose" name="foldbot_camera_pose"\n'
        f'        args="{args}"/>\n'
        "</launch>\n"
    )


def pose_words(T: np.ndarray, parent: str, child: str) -> list[str]:
    """A transform as static_transform_publisher's words."""
    x, y, z = (float(v) for v in T[:3, 3])
    qx, qy, qz, qw = Rotation.from_matrix(T[:3, :3]).as_quat()
    return [
        f"{x:.6f}",
        f"{y:.6f}",
        f"{z:.6f}",
        f"{qx:.8f}",
        f"{qy:.8f}",
        f"{qz:.8f}",
        f"{qw:.8f}",
        parent,
        child,
    ]


def _read_calibration(path: Path) -> tuple[dict[str, Any], np.ndarray]:
    """A calibration.json's record and its checked T_world_camera; ConfigError naming what is
    wrong with the file."""
    try:
        record = json.loads(path.read_text())
        raw_T = record["T_world_camera"]
        T = np.asarray(raw_T, dtype=float)
        frames = {name: record[name] for name in ("parent_frame", "child_frame")}
    except FileNotFoundError:
        raise ConfigError(f"{str(path)!r}: no such file") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(
            f"{str(path)!r} is not a calibration.json of `foldbot calibrate` or "
            f"`foldbot ros-calibrate` (T_world_camera, parent_frame, child_frame): {exc}"
        ) from None
    if not _is_rigid(T):
        raise ConfigError(
            f"{str(path)!r}: T_world_camera must be a rigid 4 × 4 transform, got "
            f"{json.dumps(raw_T)}"
        )
    for name, frame in frames.items():
        if not isinstance(frame, str) or not frame.strip():
            raise ConfigError(f"{str(path)!r}: {name} must name a frame, got {json.dumps(frame)}")
    return record, T


def _is_rigid(T: np.ndarray) -> bool:
    """T is a finite 4 × 4 rigid transform (orthonormal rotation, last row 0 0 0 1)."""
    if T.shape != (4, 4) or not np.isfinite(T).all():
        return False
    R = T[:3, :3]
    return bool(
        np.allclose(R @ R.T, np.eye(3), atol=1e-6)
        and abs(np.linalg.det(R) - 1.0) < 1e-6
        and np.allclose(T[3], [0, 0, 0, 1])
    )


def calibration_pose_words(path: str | Path) -> list[str]:
    """The camera pose a calibration.json (`foldbot calibrate`, `foldbot ros-calibrate`) holds,
    as static_transform_publisher's words; ConfigError naming what is wrong with the file,
    frames included: the nodes look the camera up as WORLD_FRAME → CAMERA_FRAME."""
    record, T = _read_calibration(Path(path))
    for name, frame in (("parent_frame", WORLD_FRAME), ("child_frame", CAMERA_FRAME)):
        if record[name] != frame:
            raise ConfigError(
                f"{str(path)!r}: {name} must be {frame!r} (the nodes look the camera up as "
                f"{WORLD_FRAME} → {CAMERA_FRAME}), got {record[name]!r}"
            )
    return pose_words(T, WORLD_FRAME, CAMERA_FRAME)


def calibration_camera(
    path: str | Path,
) -> tuple[np.ndarray, tuple[np.ndarray, int, int] | None]:
    """The camera a calibration.json found: T_world_camera, and (K, width, height) where the
    file records the intrinsics it was solved with (`camera_info`; files written before
    2026-11-30 have none: None)."""
    path = Path(path)
    record, T = _read_calibration(path)
    info = record.get("camera_info")
    if info is None:
        return T, None
    try:
        K = np.asarray(info["K"], dtype=float)
        size = info["width"], info["height"]
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(
            f"{str(path)!r}: camera_info must hold K (3 × 3), width and height: {exc}"
        ) from None
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in size):
        raise ConfigError(
            f"{str(path)!r}: camera_info's width and height must be whole numbers of pixels, "
            f"got {size[0]!r} × {size[1]!r}"
        )
    width, height = size
    if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ConfigError(f"{str(path)!r}: camera_info K must be a 3 × 3 camera matrix, got {K}")
    if width <= 0 or height <= 0:
        raise ConfigError(
            f"{str(path)!r}: camera_info's image size must be positive, got {width} × {height}"
        )
    return T, (K, width, height)


def calibration_distortion(path: str | Path) -> np.ndarray | None:
    """The lens distortion coefficients a calibration.json was solved with (`camera_info`'s
    `distortion`, as the camera's camera_info gave them), or None where the file records none;
    ConfigError naming what is wrong with the file."""
    path = Path(path)
    record, _T = _read_calibration(path)
    info = record.get("camera_info")
    if not isinstance(info, dict) or info.get("distortion") is None:
        return None
    try:
        dist = np.asarray(info["distortion"], dtype=float).ravel()
    except (TypeError, ValueError) as exc:
        raise ConfigError(
            f"{str(path)!r}: camera_info's distortion must be a list of numbers: {exc}"
        ) from None
    if not np.isfinite(dist).all() or dist.size > 14:
        raise ConfigError(
            f"{str(path)!r}: camera_info's distortion must be at most 14 finite numbers, got "
            f"{info['distortion']!r}"
        )
    return dist


def calibration_truth(path: str | Path) -> np.ndarray | None:
    """Where the camera truly stood when a calibration.json was solved: `truth`'s T_world_camera,
    which only `foldbot calibrate` on the simulated cell knows (None for a real cell's);
    ConfigError naming what is wrong with the file."""
    path = Path(path)
    record, _T = _read_calibration(path)
    truth = record.get("truth")
    if truth is None:
        return None
    try:
        T = np.asarray(truth["T_world_camera"], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"{str(path)!r}: truth must hold T_world_camera (4 × 4): {exc}") from None
    if not _is_rigid(T):
        raise ConfigError(
            f"{str(path)!r}: truth's T_world_camera must be a rigid 4 × 4 transform, "
            f"got {T.tolist()}"
        )
    return T


def contact_sheet(
    captures: list[Capture],
    solution: HandEyeSolution | None,
    board: CalibrationBoard,
    K: np.ndarray,
    dist: np.ndarray,
    columns: int = 4,
    width: int = 320,
) -> np.ndarray:
    """Every view's image, small: the corners found (green), where the solution puts them (red
    crosses), and why a view was dropped."""
    tiles = []
    obj = board.object_points()
    for cap in captures:
        if cap.rgb is None:
            tile = np.full((240, 320, 3), 40, np.uint8)
        else:
            tile = np.ascontiguousarray(cap.rgb[..., :3].copy())
            if cap.corners is not None and board.pattern == "chessboard":
                cv2.drawChessboardCorners(
                    tile, board.pattern_size, cap.corners.reshape(-1, 1, 2).astype(np.float32), True
                )
            elif cap.corners is not None:
                cv2.aruco.drawDetectedCornersCharuco(
                    tile,
                    cap.corners.reshape(-1, 1, 2).astype(np.float32),
                    np.asarray(cap.corner_ids, dtype=np.int32).reshape(-1, 1),
                    (0, 255, 0),
                )
            if solution is not None and cap.T_world_tcp is not None and not cap.dropped:
                T = np.linalg.inv(solution.T_world_camera) @ cap.T_world_tcp @ solution.T_tcp_board
                rvec = cv2.Rodrigues(T[:3, :3])[0]
                pts = cv2.projectPoints(obj, rvec, T[:3, 3], K, dist)[0].reshape(-1, 2)
                for u, v in pts:
                    cv2.drawMarker(tile, (round(u), round(v)), (255, 0, 0), cv2.MARKER_CROSS, 8, 1)
        scale = width / tile.shape[1]
        tile = cv2.resize(tile, (width, round(tile.shape[0] * scale)), interpolation=cv2.INTER_AREA)
        label = f"{cap.view.name}: {cap.dropped[:40] if cap.dropped else 'used'}"
        cv2.putText(
            tile, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 0), 1, cv2.LINE_AA
        )
        tiles.append(tile)
    h = max(t.shape[0] for t in tiles)
    tiles = [np.pad(t, ((0, h - t.shape[0]), (0, 0), (0, 0))) for t in tiles]
    while len(tiles) % columns:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.hstack(tiles[i : i + columns]) for i in range(0, len(tiles), columns)]
    return np.vstack(rows)


def calibration_record(
    captures: list[Capture], solution: HandEyeSolution, board: CalibrationBoard
) -> dict[str, Any]:
    """calibration.json's content: the camera's pose, the board's on the tool, the residuals
    and every view's fate."""
    X = solution.T_world_camera
    used = [c for c in captures if not c.dropped]
    return {
        "parent_frame": WORLD_FRAME,
        "child_frame": CAMERA_FRAME,
        "T_world_camera": X.tolist(),
        "translation_m": X[:3, 3].tolist(),
        "quaternion_xyzw": _quat(X),
        "T_tcp_board": solution.T_tcp_board.tolist(),
        "board": board.record(),
        "views_used": len(used),
        "views": [
            {
                "name": c.view.name,
                "used": not c.dropped,
                "dropped": c.dropped or None,
                "corners_seen": None if c.corners is None else len(c.corners),
            }
            for c in captures
        ],
        "reprojection_rms_px": solution.reprojection_rms_px,
        "view_rms_px": list(solution.view_rms_px),
        "board_disagreement_mm": {
            "median": 1000.0 * float(np.median(solution.board_disagreement_m)),
            "max": 1000.0 * float(np.max(solution.board_disagreement_m)),
        },
        "board_disagreement_deg": {
            "median": float(np.rad2deg(np.median(solution.board_disagreement_rad))),
            "max": float(np.rad2deg(np.max(solution.board_disagreement_rad))),
        },
    }


def write_calibration(
    stage: Path,
    captures: list[Capture],
    solution: HandEyeSolution,
    board: CalibrationBoard,
    K: np.ndarray,
    dist: np.ndarray,
    extra: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """calibration.json, camera_pose.launch and views.png into `stage`; the record written."""
    record = calibration_record(captures, solution, board)
    sizes = [c.rgb.shape[1::-1] for c in captures if c.rgb is not None]
    if sizes:  # the intrinsics the pose holds for (check-layout reads them back)
        record["camera_info"] = {
            "width": int(sizes[0][0]),
            "height": int(sizes[0][1]),
            "K": np.asarray(K, dtype=float).tolist(),
            "distortion": np.asarray(dist, dtype=float).ravel().tolist(),
        }
    record.update(extra or {})
    try:
        (stage / "calibration.json").write_text(json.dumps(record, indent=2) + "\n")
        (stage / "camera_pose.launch").write_text(launch_text(solution.T_world_camera))
        iio.imwrite(stage / "views.png", contact_sheet(captures, solution, board, K, dist))
    except OSError as exc:
        raise OutputError(f"cannot write the calibration into {stage}: {exc}") from exc
    return record
