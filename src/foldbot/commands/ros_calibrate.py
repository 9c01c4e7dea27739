"""`foldbot ros-calibrate`: find the camera's pose on a running cell, a real one or `foldbot
ros-cell --calibration-board`, from a board the arm holds (eye-to-hand calibration).

Fix a printed board (`foldbot print-board`) to the tool (by default a chessboard of 8 × 5 squares
of 24 mm; `--board-pattern charuco`, a ChArUco board of 6 × 4 squares of 36 mm, counts views that
show it in part), on a bracket beside the jaws, its printed face up with the gripper pointing
down: see calibration.views.BoardMount; the calibration solves the board's real place on the
tool, the nominal one only aims the views.
The arm, through its driver's FollowJointTrajectory action, holds the board at up to 12 poses
over the workspace turned towards where the camera roughly is (`--look-from`), comes back to
where it started, and the views' corners (the colour camera's image and camera_info) and joints
(/joint_states) give world → camera.

Writes, into --out: calibration.json (the pose, the residuals, every view's fate),
camera_pose.launch (a static_transform_publisher of world → camera_color_optical_frame: include
it in the cell's launch file, and `foldbot ros-fold --cell real` reads it from /tf_static),
views.png (what each view saw). The cell's layout (--layout) is the world frame. Needs ROS 1
(scripts/install_ros.sh); the master at ROS_MASTER_URI, or --port.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from foldbot.commands.calibrate import (
    add_board_arguments,
    board_words,
    check_dry_run,
    dry_run_words,
    plan_from_args,
)
from foldbot.commands.ros_fold import (
    add_running_cell_master,
    check_port,
    master_wait_s,
    run_node,
    running_cell_env,
)
from foldbot.dry_run import PLAN_FILE
from foldbot.io.staging import commit_output, output_path, prepare_output


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=output_path, required=True, help="output folder")
    add_board_arguments(parser)
    add_running_cell_master(parser)


def run(args: argparse.Namespace) -> int:
    check_dry_run(args)
    plan = plan_from_args(args)  # every option checked before the cell is asked anything
    check_port(args.port)
    master_wait_s(args.master_wait)
    stage = prepare_output(args.out)  # a bad --out named before the cell is waited for
    try:
        env = running_cell_env(args, "a real one, or `foldbot ros-cell --calibration-board`")
        cmd = ["--stage", str(stage)]
        cmd += ["--robot", args.robot, *board_words(args)]
        cmd += ["--arms", str(args.arms), "--arm", args.arm]
        cmd += ["--board-offset", *(repr(v) for v in plan.mount.offset_m)]
        cmd += ["--board-turn", *(repr(v) for v in args.board_turn)]
        cmd += ["--views", str(args.views), "--look-from", *(repr(v) for v in plan.look_from)]
        cmd += ["--speed-scale", repr(plan.speed_scale)]
        if args.confirm:  # the node asks on this terminal (it inherits stdin and stdout)
            cmd += ["--confirm"]
        if args.layout is not None:
            cmd += ["--layout", str(Path(args.layout).resolve())]
        if args.dry_run:
            cmd += ["--dry-run"]
        # A dry run with a view out of reach exits 1 with its plan written.
        ok = (0, 1) if args.dry_run else (0,)
        code = run_node("foldbot.ros.calibrate_node", cmd, env, "the calibration", ok)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    commit_output(stage, args.out)
    if args.dry_run:
        planned = json.loads((args.out / PLAN_FILE).read_text())
        print(f"ros-calibrate: dry run: {dry_run_words(planned, plan.speed_scale)}")
        print(f"ros-calibrate: wrote {args.out}/{PLAN_FILE}")
        return code
    record = json.loads((args.out / "calibration.json").read_text())
    print(
        f"ros-calibrate: {record['views_used']} of {len(record['views'])} views, reprojection "
        f"{record['reprojection_rms_px']:.2f} px RMS; the board as the camera and the arm "
        f"place it {record['board_disagreement_mm']['median']:.2f} mm apart (median); the camera "
        f"at {[round(v, 4) for v in record['translation_m']]} m"
    )
    print(f"ros-calibrate: wrote {args.out}/calibration.json, camera_pose.launch, views.png")
    return 0
