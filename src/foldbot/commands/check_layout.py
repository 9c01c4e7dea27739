"""`foldbot check-layout`: can this cell fold everywhere in its workspace? Before a cloth is laid
in a new cell (a layout file) or onto a real arm, every point of the workspace on a grid is
checked: the arm reaches it gripper down where it grasps and places (the jaws 10 mm over the
table, the approach 80 mm up) with every link clear of the table, and the camera's image covers
it on the table top; a point not reached 250 mm up (a carry's top) is reported apart. Kinematics
only: nothing is simulated, a check takes seconds.

The camera is the simulated cell's (moved with the layout's workspace) unless --camera-pose
gives a calibration (`foldbot ros-calibrate` on the real cell: its pose, and the intrinsics it
was solved with). Prints what it found; with --out also writes

  layout_check.json   every point's verdict, why an arm cannot reach it, the camera's view
  layout_check.png    the cell from above: the table, the workspace's points coloured by
                      reach, the camera's image on the table, the arms' bases

Exit code 0 when every point is reached and seen, 1 when not, 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from foldbot.errors import ConfigError, OutputError
from foldbot.io.staging import commit_output, output_path, prepare_output
from foldbot.layout_check import (
    DEFAULT_GRID,
    GRID_RANGE,
    CameraPlacement,
    LayoutCheck,
    check_layout,
    check_picture,
)
from foldbot.sim.camera import CameraConfig, camera_for_layout
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout, load_layout
from foldbot.sim.robots import ROBOT_NAMES


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "layout",
        type=Path,
        nargs="?",
        default=None,
        metavar="LAYOUT.toml",
        help="the cell's layout file (as for foldbot fold --layout; default: the default cell)",
    )
    parser.add_argument("--robot", default="ur5", choices=ROBOT_NAMES, help="arm (default ur5)")
    parser.add_argument(
        "--arms", type=int, default=1, choices=(1, 2), help="arms in the cell (default 1)"
    )
    parser.add_argument(
        "--camera-pose",
        type=Path,
        default=None,
        metavar="CALIBRATION.json",
        help="the camera a calibration found (foldbot ros-calibrate or calibrate); default: the "
        "simulated camera, placed for the layout",
    )
    lo, hi = GRID_RANGE
    parser.add_argument(
        "--grid",
        type=int,
        default=DEFAULT_GRID,
        help=f"points along each side of the workspace, {lo}–{hi} (default {DEFAULT_GRID})",
    )
    parser.add_argument(
        "--out",
        type=output_path,
        default=None,
        help="write layout_check.json and .png into this folder",
    )


def camera_placement(path: Path | None, layout: CellLayout) -> CameraPlacement:
    """The camera --camera-pose names (with where it truly stood, for a calibration solved on the
    simulated cell), or the simulated one placed for `layout`."""
    default = camera_for_layout(CameraConfig(), layout)
    if path is None:
        where = "the simulated camera" + (
            ", moved with the workspace" if any(layout.workspace_shift()) else ""
        )
        return CameraPlacement(
            default.T_world_camera, default.K, default.width, default.height, where
        )
    from foldbot.calibration.capture import calibration_camera, calibration_truth

    T, intrinsics = calibration_camera(path)
    truth = calibration_truth(path)
    if intrinsics is None:
        return CameraPlacement(
            T,
            default.K,
            default.width,
            default.height,
            f"{path}; its file has no intrinsics: the simulated camera's",
            truth,
        )
    K, width, height = intrinsics
    return CameraPlacement(T, K, width, height, str(path), truth)


def run(args: argparse.Namespace) -> int:
    lo, hi = GRID_RANGE
    if not lo <= args.grid <= hi:  # before anything is printed or loaded
        raise ConfigError(f"--grid must be {lo}–{hi} points a side, got {args.grid}")
    layout = DEFAULT_LAYOUT if args.layout is None else load_layout(args.layout)
    camera = camera_placement(args.camera_pose, layout)
    stage = None if args.out is None else prepare_output(args.out)
    try:
        start = time.perf_counter()
        name = "the default cell" if args.layout is None else str(args.layout)
        print(f"check-layout: {name}, {args.arms} × {args.robot}, {args.grid} × {args.grid} points")
        check = check_layout(
            layout,
            camera,
            robot=args.robot,
            arms=args.arms,
            grid=args.grid,
            progress=lambda done, total: print(
                f"check-layout: arm {done} of {total} checked ({time.perf_counter() - start:.1f} s)"
            ),
        )
        for line in check.lines():
            print(line)
        if stage is not None:
            _write(stage, check)
            commit_output(stage, args.out)
            stage = None
            print(f"check-layout: wrote {args.out}/layout_check.json and layout_check.png")
    finally:
        if stage is not None:
            import shutil

            shutil.rmtree(stage, ignore_errors=True)
    return 0 if check.ok else 1


def _write(stage: Path, check: LayoutCheck) -> None:
    import imageio.v3 as iio

    try:
        (stage / "layout_check.json").write_text(json.dumps(check.record(), indent=2) + "\n")
        iio.imwrite(stage / "layout_check.png", check_picture(check))
    except OSError as exc:
        raise OutputError(f"cannot write the check into {stage}: {exc}") from exc
