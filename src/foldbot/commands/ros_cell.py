"""`foldbot ros-cell`: the simulated cell alone on a ROS 1 master, presenting itself as a real
one does — a UR5's and a gripper's driver actions (control_msgs FollowJointTrajectory on
scaled_pos_joint_traj_controller/follow_joint_trajectory, GripperCommand on
gripper_controller/gripper_cmd; with `--arms 2` each arm's under left/ and right/, its joints
prefixed left_ and right_), /joint_states, an RGB-D camera's images and camera_info, the
world → camera transform on /tf_static — running on at real-time pace until interrupted (Ctrl-C
or `kill`: roslaunch takes its nodes and roscore down first).

`foldbot ros-fold --cell real` then folds on it exactly as on a real cell: through those topics
and actions only. The cloth is the one `foldbot fold` would lay for the same options (size,
seed, pose, cloth options), crumpled as `foldbot fold` crumples it with `--start crumpled`.
Needs ROS 1 from Debian (scripts/install_ros.sh)."""

from __future__ import annotations

import argparse
import signal
import subprocess
import tempfile

from foldbot.commands import fold
from foldbot.commands.calibrate import ARM_NAMES, BOARD_PATTERNS
from foldbot.commands.ros_fold import (
    DEFAULT_PORT,
    add_master_port,
    add_real_time_factor,
    check_port,
    check_real_time_factor,
    fold_args_text,
    ros_env,
    ros_missing,
    stop_launch,
)
from foldbot.errors import ConfigError, FoldbotError
from foldbot.layout_check import check_cell_fits

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""What stops the cell cleanly: Ctrl-C, or `kill`. SIGINT is taken even where the cell
inherited it ignored (a script's `foldbot ros-cell … &`, where Python would not raise
KeyboardInterrupt for it)."""


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """`foldbot fold`'s options that lay the cloth (no --out), the camera's rate, the master's
    port and the pace."""
    fold.add_arguments(parser, output=False, faults=False)
    fold.add_slip_option(parser)  # a running cell that lets its first carry's cloth go
    parser.add_argument(
        "--camera-rate",
        type=float,
        default=10.0,
        help="camera frames per simulated second (default 10)",
    )
    add_master_port(parser, "roscore is started if none runs there")
    add_real_time_factor(parser, "")
    parser.add_argument(
        "--calibration-board",
        nargs="?",
        const="left",
        default=None,
        choices=ARM_NAMES,
        metavar="ARM",
        help="the arm holds the calibration board (a chessboard of 8 × 5 squares of 24 mm on "
        "a bracket beside the jaws; --calibration-board-pattern), for `foldbot ros-calibrate`; "
        "with --arms 2, the left arm's (the default) or the right's",
    )
    parser.add_argument(
        "--calibration-board-pattern",
        choices=BOARD_PATTERNS,
        default="chessboard",
        help="that board: chessboard (default) or charuco (6 × 4 squares of 36 mm with ArUco "
        "4x4_50 markers of 27 mm; `ros-calibrate --board-pattern charuco`)",
    )
    parser.add_argument(
        "--hide-camera-pose",
        action="store_true",
        help="publish no world → camera transform on /tf_static, as a cell whose camera is not "
        "calibrated yet (fold on it with `ros-fold --cell real --camera-pose CALIBRATION.json`)",
    )


FOLDING_OPTIONS = ("recipe", "perception", "park", "loop_option", "flatten_option", "video_fps")
"""`foldbot fold`'s options that ros-cell takes (the same options for the cell and the fold) but
that only the folding side reads: the planner and task nodes of `ros-fold --cell real`."""


def folding_options_given(args: argparse.Namespace) -> list[str]:
    """The FOLDING_OPTIONS given away from their defaults, as flags (--recipe, …)."""
    defaults = argparse.ArgumentParser(add_help=False)
    add_arguments(defaults)
    return [
        fold.given_flag(name, getattr(args, name))
        for name in FOLDING_OPTIONS
        if getattr(args, name) != defaults.get_default(name)
    ]


def run(args: argparse.Namespace) -> int:
    """Validate, then roslaunch the cell and keep it up until interrupted."""
    cfg = fold.config_from_args(args)
    if cfg.motion.speed_scale != 1.0:
        raise ConfigError(
            f"--speed-scale {args.speed_scale:g} is the folding side's: a cell moves its arm as "
            "its drivers are told; give it to `foldbot ros-fold --cell real` or `foldbot "
            "ros-calibrate`"
        )
    check_real_time_factor(args.real_time_factor)
    check_port(args.port)
    board_arm = -1 if args.calibration_board is None else ARM_NAMES.index(args.calibration_board)
    if board_arm >= cfg.arms:
        raise ConfigError(
            f"--calibration-board {args.calibration_board} is for a two-arm cell (--arms 2); "
            "a one-arm cell's arm holds it with --calibration-board alone"
        )
    if not args.camera_rate > 0:
        raise ConfigError(f"--camera-rate must be > 0 frames per s, got {args.camera_rate!r}")
    ignored = folding_options_given(args)
    if ignored:
        one = len(ignored) == 1
        print(
            f"ros-cell: {', '.join(ignored)} {'sets' if one else 'set'} how `foldbot ros-fold "
            f"--cell real` folds, not the cell, which ignores {'it' if one else 'them'} (give "
            f"{'it' if one else 'them'} to ros-fold)",
            flush=True,
        )
    check_cell_fits(cfg.sim.layout, cfg.robot, cfg.arms, cfg.park)  # before a node would
    missing = ros_missing()
    if missing:
        raise FoldbotError(missing)
    port = DEFAULT_PORT if args.port is None else args.port
    with tempfile.TemporaryDirectory(prefix="foldbot-cell-") as unused:
        args.out = unused  # the sim node parses `foldbot fold`'s options; it writes nothing
        cmd = [
            "roslaunch",
            "-p",
            str(port),
            "foldbot_ros",
            "cell.launch",
            f"fold_args:={fold_args_text(args)}",
            f"camera_rate:={args.camera_rate!r}",
            f"real_time_factor:={args.real_time_factor or 1.0!r}",
            f"calibration_board:={board_arm}",
            f"calibration_board_pattern:={args.calibration_board_pattern}",
            f"camera_pose:={'false' if args.hide_camera_pose else 'true'}",
        ]
        print(
            f"the simulated cell comes up on the ROS master at http://localhost:{port}; fold "
            f"on it with `foldbot ros-fold --cell real --port {port} --out DIR` and the same "
            "cloth options"
            + (" and --arms 2" if cfg.arms == 2 else "")
            + (f" and --layout {args.layout}" if args.layout is not None else "")
            + (" (with --start crumpled: flatten it first)" if cfg.start == "crumpled" else "")
            + (
                f"; find its camera with `foldbot ros-calibrate --port {port} --out DIR"
                + (f" --arms 2 --arm {args.calibration_board}" if cfg.arms == 2 else "")
                + (
                    " --board-pattern charuco"
                    if args.calibration_board_pattern == "charuco"
                    else ""
                )
                + "`"
                if args.calibration_board
                else ""
            )
            + "; Ctrl-C stops it",
            flush=True,
        )
        # Its own session: an interrupt is passed on once and waited out, so roslaunch takes
        # its nodes and roscore down with it rather than being killed and leaving them.
        proc = subprocess.Popen(cmd, env=ros_env(port), start_new_session=True)
        before = {s: signal.signal(s, _interrupt) for s in STOP_SIGNALS}
        try:
            code = proc.wait()
        except KeyboardInterrupt:
            stop_launch(proc)
            print("the simulated cell stopped", flush=True)
            return 0
        finally:
            for s, handler in before.items():
                signal.signal(s, handler)
    if code != 0:
        raise FoldbotError(f"the cell stopped (roslaunch exit code {code})")
    return 0
