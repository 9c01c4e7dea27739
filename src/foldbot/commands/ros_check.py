"""`foldbot ros-check`: is this running cell ready to fold? Before `foldbot ros-fold --cell real`
on a newly brought-up cell (a real arm's and gripper's drivers and an RGB-D camera, or `foldbot
ros-cell`), ask it for everything the fold will need, and say what is there and what is not,
all at once rather than the first thing missing:

  - each arm's FollowJointTrajectory and GripperCommand action servers;
  - /joint_states naming every arm joint, each within the robot's limits;
  - the camera's colour image, depth image and camera_info, in encodings perception reads;
  - world → base_link on /tf_static where the layout puts the arm's base;
  - world → the camera on /tf_static (or the pose a calibration found: --camera-pose);
  - the table top as the camera's depth sees it through that pose: at the layout's height and
    level (a pose or a layout that is off shows here);
  - every workspace point reached by an arm gripper down, and inside the camera's image
    (as `foldbot check-layout`);
  - the cloth (--garment, a towel by default; none: not looked for) as the fold's first look
    will see it: found, whole in the image, every keypoint over the workspace.

Moves nothing. Writes, into --out: ros_check.json (every check and what it found) and
ros_check.png (the camera's image with the workspace drawn where the camera's pose puts it:
the outline should lie on the table's workspace; the cloth's outline and keypoints as
perception found them). Exit code 0 when every check passes, 1 when
one fails, 2 when the cell cannot be asked (no master, bad options). Needs ROS 1
(scripts/install_ros.sh); the master at ROS_MASTER_URI, or --port.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from foldbot.commands.ros_fold import (
    add_running_cell_master,
    check_port,
    master_wait_s,
    run_node,
    running_cell_env,
)
from foldbot.garments import GARMENTS
from foldbot.io.staging import commit_output, output_path, prepare_output
from foldbot.sim.layout import load_layout
from foldbot.sim.robots import ROBOT_NAMES


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=output_path, required=True, help="output folder")
    parser.add_argument("--robot", default="ur5", choices=ROBOT_NAMES, help="arm (default ur5)")
    parser.add_argument(
        "--arms", type=int, default=1, choices=(1, 2), help="arms in the cell (default 1)"
    )
    parser.add_argument(
        "--layout",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="the cell's layout, the world frame the fold will plan in (default: the default cell)",
    )
    parser.add_argument(
        "--camera-pose",
        type=Path,
        default=None,
        metavar="CALIBRATION.json",
        help="the camera's pose from a calibration, where the cell publishes none (as "
        "`ros-fold --cell real --camera-pose` publishes it)",
    )
    parser.add_argument(
        "--garment",
        choices=(*GARMENTS, "none"),
        default="towel",
        help="the cloth the fold will find on the table, looked for as perception will (default "
        "towel); none: a cell checked before the cloth is laid",
    )
    add_running_cell_master(parser)


def run(args: argparse.Namespace) -> int:
    if args.layout is not None:
        load_layout(args.layout)  # named before the cell is asked anything
    if args.camera_pose is not None:
        from foldbot.calibration.capture import calibration_camera

        calibration_camera(args.camera_pose)
    check_port(args.port)
    master_wait_s(args.master_wait)
    stage = prepare_output(args.out)  # a bad --out named before the cell is waited for
    try:
        env = running_cell_env(args, "a real one, or `foldbot ros-cell`")
        cmd = ["--stage", str(stage), "--robot", args.robot, "--arms", str(args.arms)]
        cmd += ["--garment", args.garment]
        if args.layout is not None:
            cmd += ["--layout", str(Path(args.layout).resolve())]
        if args.camera_pose is not None:
            cmd += ["--camera-pose", str(Path(args.camera_pose).resolve())]
        print(f"ros-check: asking the cell at {env['ROS_MASTER_URI']}", flush=True)
        run_node("foldbot.ros.check_node", cmd, env, "the check", ok=(0, 1))
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    commit_output(stage, args.out)
    record = json.loads((args.out / "ros_check.json").read_text())
    failed = [c["name"] for c in record["checks"] if not c["ok"]]
    picture = " and ros_check.png" if (args.out / "ros_check.png").exists() else ""
    print(
        "ros-check: the cell is ready to fold"
        if not failed
        else f"ros-check: {len(failed)} of {len(record['checks'])} checks failed: "
        + ", ".join(failed)
    )
    print(f"ros-check: wrote {args.out}/ros_check.json{picture}")
    return 0 if not failed else 1
