"""`foldbot calibrate`: find the camera's pose in the cell from a board the arm holds (eye-to-hand
calibration), on the simulated cell, and measure it against the camera's true pose.

The arm holds the board (by default a chessboard of 8 × 5 squares of 24 mm; `--board-pattern
charuco`: a ChArUco board of 6 × 4 squares of 36 mm, found in part too; on a bracket beside the
jaws) at up to 12 poses over the workspace, turned towards where the camera roughly is
(`--look-from`); each pose's image gives the board's corners, the joints give the tool's pose,
and the two are solved for the camera's pose in the world and the board's on the tool
(calibration.hand_eye). Nothing in the solve reads the simulated camera's pose; it is compared
with the answer afterwards.

Writes, into --out:
  calibration.json    the camera's pose (world → camera_color_optical_frame), the board's on
                      the tool, the reprojection error, every view's fate, and the error against
                      the simulated camera's true pose (`truth`)
  camera_pose.launch  a static_transform_publisher for that pose, as a real cell publishes it
  views.png           every view: the corners found and where the solution puts them

`foldbot ros-calibrate` runs the same on a running cell (a real one, or `foldbot ros-cell
--calibration-board`) over ROS.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from foldbot.calibration.board import (
    ARUCO_DICTIONARIES,
    CalibrationBoard,
    CharucoBoard,
    Chessboard,
)
from foldbot.calibration.capture import (
    capture_views,
    plan_views,
    solve_captures,
    write_calibration,
)
from foldbot.calibration.hand_eye import pose_error
from foldbot.calibration.views import MAX_VIEWS, BoardMount, CalibrationView, calibration_views
from foldbot.dry_run import PLAN_FILE
from foldbot.errors import ConfigError
from foldbot.io.staging import commit_output, output_path, prepare_output
from foldbot.operator import OperatorGate
from foldbot.planning.motion import MIN_SPEED_SCALE, MotionConfig
from foldbot.sim.camera import CameraConfig, camera_for_layout
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout, load_layout
from foldbot.sim.robots import ROBOT_NAMES
from foldbot.sim.world import SimConfig

ARM_NAMES = ("left", "right")
"""A two-arm cell's arms, arm 0 first (foldbot.ros.ARM_PREFIXES' order)."""
TABLE_GRID = 5
"""The table-top error is measured on this many × this many points over the workspace."""


BOARD_PATTERNS = ("chessboard", "charuco")
MARKER_SHARE = 0.75
"""A ChArUco marker's side as a share of its square's, where --marker is not given."""


def board_from_args(args: argparse.Namespace) -> CalibrationBoard:
    """The board the options name (`--board-pattern`, `--board COLSxROWS`, `--square M`,
    `--marker M`, `--aruco-dictionary`); each pattern's own defaults where not given."""
    charuco = args.board_pattern == "charuco"
    default = CharucoBoard() if charuco else Chessboard()
    if args.board is None:
        cols, rows = default.squares_x, default.squares_y
    else:
        try:
            cols, rows = (int(v) for v in str(args.board).lower().split("x"))
        except ValueError:
            raise ConfigError(
                f"--board must be COLUMNSxROWS of squares (e.g. 8x5), got {args.board!r}"
            ) from None
    square = default.square_m if args.square is None else args.square
    if not charuco:
        if args.marker is not None or args.aruco_dictionary is not None:
            raise ConfigError("--marker and --aruco-dictionary are for --board-pattern charuco")
        return Chessboard(squares_x=cols, squares_y=rows, square_m=square)
    marker = round(MARKER_SHARE * square, 9) if args.marker is None else args.marker
    dictionary = args.aruco_dictionary or default.dictionary
    return CharucoBoard(
        squares_x=cols, squares_y=rows, square_m=square, marker_m=marker, dictionary=dictionary
    )


def board_words(args: argparse.Namespace) -> list[str]:
    """The board options as given, to hand on to another command's parser."""
    words = ["--board-pattern", args.board_pattern]
    for flag, value in (
        ("--board", args.board),
        ("--square", args.square),
        ("--marker", args.marker),
        ("--aruco-dictionary", args.aruco_dictionary),
    ):
        if value is not None:
            words += [flag, repr(value) if isinstance(value, float) else str(value)]
    return words


def add_board_shape_arguments(parser: argparse.ArgumentParser) -> None:
    """The board's pattern, squares and their size (`--board-pattern`, `--board COLSxROWS`,
    `--square M`, `--marker M`, `--aruco-dictionary`)."""
    parser.add_argument(
        "--board-pattern",
        choices=BOARD_PATTERNS,
        default="chessboard",
        help="chessboard (default; found only whole) or charuco (a ChArUco board: ArUco markers "
        "in the white squares name each corner, so a view that shows part of it counts)",
    )
    parser.add_argument(
        "--board",
        default=None,
        help="the board's squares, COLUMNSxROWS, more columns than rows (a chessboard's odd in "
        "all); default 8x5 for a chessboard, 6x4 for a ChArUco board",
    )
    parser.add_argument(
        "--square",
        type=float,
        default=None,
        help="a square's side in m (default 0.024 for a chessboard, 0.036 for a ChArUco board)",
    )
    parser.add_argument(
        "--marker",
        type=float,
        default=None,
        help=f"ChArUco: a marker's side in m, its black border included (default "
        f"{MARKER_SHARE:g} of the square)",
    )
    parser.add_argument(
        "--aruco-dictionary",
        choices=sorted(ARUCO_DICTIONARIES),
        default=None,
        help="ChArUco: the markers' ArUco dictionary (default 4x4_50, OpenCV's DICT_4X4_50)",
    )


def add_board_arguments(parser: argparse.ArgumentParser) -> None:
    """The options every calibration command shares: the board, the views, the rough camera."""
    parser.add_argument("--robot", default="ur5", choices=ROBOT_NAMES, help="arm to use")
    parser.add_argument(
        "--layout",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="the cell's layout (as for foldbot fold); the views are placed over its workspace",
    )
    parser.add_argument(
        "--arms", type=int, default=1, choices=(1, 2), help="arms in the cell (default 1)"
    )
    parser.add_argument(
        "--arm",
        default="left",
        choices=ARM_NAMES,
        help="with --arms 2: the arm that holds the board (default left, +y)",
    )
    add_board_shape_arguments(parser)
    parser.add_argument(
        "--confirm",
        action="store_true",
        help="before each move (to a view, and back) say what it will do and wait for the "
        "operator: Enter moves, s stops the calibration there (nothing is written); for a "
        "first run on a real arm",
    )
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help="plan every view's move from where the arm stands (IK, the table and the layout's "
        "obstacles checked, its time) and write DIR/plan.json; nothing moves (exit 1 where a "
        "view is out of reach)",
    )
    default = BoardMount()
    parser.add_argument(
        "--board-offset",
        type=float,
        nargs=3,
        default=default.offset_m,
        metavar=("X", "Y", "Z"),
        help="where the board's first inner corner sits in the tool (TCP) frame, m (default "
        f"{' '.join(f'{v:g}' for v in default.offset_m)}: beside the jaws, 6 cm up towards the "
        "flange, out along the tool's −x); only aims the views, the calibration solves the real one",
    )
    parser.add_argument(
        "--board-turn",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("RX", "RY", "RZ"),
        help="the board's axes in the tool frame as a rotation vector, degrees (default 0 0 0: "
        "the tool's own, the printed face up with the gripper down)",
    )
    parser.add_argument(
        "--views",
        type=int,
        default=MAX_VIEWS,
        help=f"poses to hold the board at, 4–{MAX_VIEWS} (default {MAX_VIEWS})",
    )
    parser.add_argument(
        "--speed-scale",
        type=float,
        default=1.0,
        metavar="S",
        help=f"fraction of full speed the arm moves at ({MIN_SPEED_SCALE:g}–1, default 1): the "
        "same moves, 1/S times as long",
    )
    parser.add_argument(
        "--look-from",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="roughly where the camera is (world, m; tens of cm off is fine): the board is "
        "turned towards it. Default: the default camera's place in the layout",
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=output_path, required=True, help="output folder")
    add_board_arguments(parser)
    parser.add_argument(
        "--camera-eye",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="put the simulated camera here (world, m) instead of the layout's default place; "
        "the calibration is not told (give --look-from for a far move)",
    )
    parser.add_argument(
        "--camera-target",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="the point the moved camera looks at (default: the workspace centre on the table)",
    )
    parser.add_argument(
        "--camera-noise",
        type=float,
        default=0.0,
        metavar="SIGMA",
        help="Gaussian noise on the simulated camera's colour image, σ in intensity levels "
        "0–255 (default 0), as a real sensor's",
    )


def mount_from_args(args: argparse.Namespace) -> BoardMount:
    """The board's nominal place on the tool (`--board-offset`, `--board-turn`)."""
    turn = [float(v) for v in args.board_turn]
    if not all(np.isfinite(turn)) or np.linalg.norm(turn) > 180.0:
        raise ConfigError(
            f"--board-turn must be a rotation vector of at most 180° (degrees), got {turn}"
        )
    mount = BoardMount(tuple(args.board_offset), tuple(np.deg2rad(turn)))
    if np.linalg.norm(mount.offset_m) > 0.5:
        raise ConfigError(
            f"--board-offset must put the board within 0.5 m of the tool, got "
            f"{list(mount.offset_m)} m"
        )
    return mount


def arm_index(args: argparse.Namespace) -> int:
    """The arm that holds the board: 0 in a one-arm cell, else --arm's."""
    if args.arms == 1:
        if args.arm != "left":
            raise ConfigError(f"--arm {args.arm} is for a two-arm cell (--arms 2)")
        return 0
    return ARM_NAMES.index(args.arm)


def layout_from_args(args: argparse.Namespace) -> CellLayout:
    return DEFAULT_LAYOUT if args.layout is None else load_layout(args.layout)


@dataclass(frozen=True)
class CalibrationPlan:
    """The calibration the options ask for, checked before anything moves: the board and its
    nominal place on the tool, the cell, the arm that holds it, where it is turned towards and
    the views."""

    board: CalibrationBoard
    mount: BoardMount
    layout: CellLayout
    robot: str
    arms: int
    arm: int
    look_from: tuple[float, float, float]
    views: list[CalibrationView]
    speed_scale: float = 1.0
    """Fraction of full speed the arm moves the board at (MotionConfig.speed_scale)."""

    def record(self) -> dict[str, Any]:
        """What calibration.json says of the run's set-up."""
        return {
            "robot": self.robot,
            "arms": self.arms,
            "arm": self.arm,
            "look_from_m": list(self.look_from),
            "speed_scale": self.speed_scale,
            "board_mount_given": {
                "offset_m": list(self.mount.offset_m),
                "rotvec_rad": list(self.mount.rotvec_rad),
            },
        }


def plan_from_args(
    args: argparse.Namespace, rough_camera: tuple[float, float, float] | None = None
) -> CalibrationPlan:
    """The options' calibration. The board is turned towards --look-from, else `rough_camera`
    (where a caller knows it), else the default camera's place in the layout (the simulated
    cell's camera, moved with its workspace)."""
    board = board_from_args(args)
    layout = layout_from_args(args)
    arm = arm_index(args)
    mount = mount_from_args(args)
    given = args.look_from if args.look_from is not None else rough_camera
    if given is None:
        given = camera_for_layout(CameraConfig(), layout).T_world_camera[:3, 3]
    x, y, z = (float(v) for v in given)
    look_from = (x, y, z)
    try:
        views = calibration_views(layout, look_from, board, mount, args.views)
    except ConfigError as exc:  # say which option gave the camera's rough position
        if args.look_from is not None:
            raise ConfigError(f"--look-from: {exc}") from None
        if rough_camera is not None and getattr(args, "camera_eye", None) is not None:
            raise ConfigError(f"--camera-eye (the board turns to it): {exc}") from None
        raise
    speed_scale = MotionConfig(speed_scale=args.speed_scale).speed_scale  # checked
    return CalibrationPlan(
        board, mount, layout, args.robot, args.arms, arm, look_from, views, speed_scale
    )


def sim_camera(args: argparse.Namespace, layout: CellLayout) -> CameraConfig:
    """The simulated camera: the layout's, or where --camera-eye/--camera-target put it."""
    noise = float(args.camera_noise)
    if not (np.isfinite(noise) and 0.0 <= noise <= 64.0):
        raise ConfigError(f"--camera-noise must be in [0, 64] intensity levels, got {noise!r}")
    camera = dataclasses.replace(camera_for_layout(CameraConfig(), layout), rgb_noise=noise)
    if args.camera_eye is None and args.camera_target is None:
        return camera
    if args.camera_eye is None:
        raise ConfigError("--camera-target needs --camera-eye (where the camera stands)")
    cx, cy = layout.workspace_center_xy
    target = args.camera_target or (cx, cy, layout.table_height)
    up = (-1.0, 0.0, 0.0)
    if abs(np.dot(np.subtract(target, args.camera_eye), up)) > 0.99 * np.linalg.norm(
        np.subtract(target, args.camera_eye)
    ):
        up = (0.0, 1.0, 0.0)
    return CameraConfig(eye=tuple(args.camera_eye), target=tuple(target), up=up, rgb_noise=noise)


def table_error_m(
    T_estimated: np.ndarray, T_true: np.ndarray, K: np.ndarray, layout: CellLayout
) -> float:
    """The largest distance on the table top, over the workspace, between a point and where the
    calibrated camera puts the pixel the true camera sees it at: the error a fold would meet."""
    cx, cy = layout.workspace_center_xy
    half = layout.workspace_size / 2.0
    g = np.linspace(-half, half, TABLE_GRID)
    xs, ys = np.meshgrid(cx + g, cy + g)
    pts = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, layout.table_height)], axis=1)
    cam = (np.linalg.inv(T_true) @ np.c_[pts, np.ones(len(pts))].T)[:3]
    pix = K @ (cam / cam[2])
    rays = np.linalg.inv(K) @ pix
    R, t = T_estimated[:3, :3], T_estimated[:3, 3]
    dirs = (R @ rays).T
    s = (layout.table_height - t[2]) / dirs[:, 2]
    seen = t + dirs * s[:, None]
    return float(np.max(np.linalg.norm(seen - pts, axis=1)))


def check_dry_run(args: argparse.Namespace) -> None:
    """--dry-run with --confirm refused by name (nothing moves to ask about)."""
    if args.dry_run and args.confirm:
        raise ConfigError("--confirm asks before each move, and --dry-run makes none: drop one")


def write_view_plan(stage: Path, planned: dict[str, Any], record: dict[str, Any]) -> None:
    """A calibration's dry run as plan.json in `stage`: the views' moves and the run's set-up."""
    (stage / PLAN_FILE).write_text(json.dumps(planned | record, indent=2) + "\n")


def dry_run_words(planned: dict[str, Any], speed_scale: float) -> str:
    """The dry run's one-line verdict."""
    n, k = len(planned["views"]), planned["views_feasible"]
    return (
        f"{k} of {n} views reachable, {planned['motion_seconds']:.1f} s of arm motion at speed "
        f"scale {speed_scale:g} (the move back included); nothing moved"
    )


def run(args: argparse.Namespace) -> int:
    from foldbot.calibration.sim_cell import SimCalibrationCell

    check_dry_run(args)
    layout = layout_from_args(args)
    camera = sim_camera(args, layout)
    # Who moved the simulated camera knows roughly where it stands.
    plan = plan_from_args(args, tuple(args.camera_eye) if args.camera_eye else None)
    board, mount, views = plan.board, plan.mount, plan.views
    stage = prepare_output(args.out)
    try:
        t0 = time.monotonic()
        cell = SimCalibrationCell(
            args.robot,
            camera,
            board,
            mount,
            SimConfig(layout=layout),
            args.arms,
            plan.arm,
            plan.speed_scale,
        )
        gate = OperatorGate(task="the calibration") if args.confirm else None
        cell.gate = gate
        if args.dry_run:
            try:
                planned = plan_views(cell, views, lambda line: print(f"dry run: {line}"))
            finally:
                cell.close()
            write_view_plan(stage, planned, {"cell": "sim", **plan.record()})
            commit_output(stage, args.out)
            print(f"dry run: {dry_run_words(planned, plan.speed_scale)}")
            print(f"dry run: plan written to {args.out}/{PLAN_FILE}")
            return 0 if planned["feasible"] else 1
        try:
            captures = capture_views(
                cell, views, board, lambda line: print(f"calibrate: {line}", flush=True)
            )
            K, dist, _, _ = cell.intrinsics()
            solution = solve_captures(captures, board, K, dist)
            truth = cell.true_T_world_camera
        finally:
            cell.close()
        dt, dr = pose_error(solution.T_world_camera, truth)
        table = table_error_m(solution.T_world_camera, truth, K, layout)
        record = write_calibration(
            stage,
            captures,
            solution,
            board,
            K,
            dist,
            {
                "cell": "sim",
                **plan.record(),
                "truth": {
                    "T_world_camera": truth.tolist(),
                    "translation_error_mm": 1000.0 * dt,
                    "rotation_error_deg": float(np.rad2deg(dr)),
                    "table_error_mm": 1000.0 * table,
                },
                "wall_s": time.monotonic() - t0,
                **({} if gate is None else {"operator": gate.record()}),
            },
        )
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    commit_output(stage, args.out)
    print(
        f"calibrate: {record['views_used']} of {len(views)} views, reprojection "
        f"{record['reprojection_rms_px']:.2f} px RMS; the camera at "
        f"{np.round(record['translation_m'], 4).tolist()} m; against the simulated camera "
        f"{1000 * dt:.2f} mm, {np.rad2deg(dr):.3f}°, on the table ≤ {1000 * table:.2f} mm"
    )
    print(f"calibrate: wrote {args.out}/calibration.json, camera_pose.launch, views.png")
    print(
        f"calibrate: fold through it (this camera, perception given the pose found): "
        f"foldbot fold {shlex.join(fold_words(args))} --out DIR"
    )
    return 0


def fold_words(args: argparse.Namespace) -> list[str]:
    """The `foldbot fold` options that fold in the cell a calibration was made in, through it:
    the calibration, and the arm, the arms and the layout where they are not the default's."""
    words = ["--camera-pose", f"{args.out}/calibration.json"]
    if args.robot != "ur5":
        words += ["--robot", args.robot]
    if args.arms != 1:
        words += ["--arms", str(args.arms)]
    if args.layout is not None:
        words += ["--layout", str(args.layout)]
    return words
