"""`foldbot ros-fold`: fold a towel, T-shirt or pants over ROS 1 topics, with one arm or two —
roslaunch brings up the sim, perception, planner and task nodes (and roscore when none runs) —
and write the same episode folder as `foldbot fold`. `--record BAG` records the run with rosbag.
`--cell real` folds on a cell that is already running (a real UR5's and gripper's drivers and an
RGB-D camera, or `foldbot ros-cell`): no sim node, and the fold is not scored.

Needs ROS 1 from Debian (scripts/install_ros.sh)."""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from foldbot import errors
from foldbot.calibration.capture import calibration_pose_words
from foldbot.commands import fold
from foldbot.dry_run import PLAN_FILE, DryRun, check_dry_run_config, check_dry_run_output
from foldbot.errors import ConfigError, FoldbotError, OutputError
from foldbot.io.episode import (
    ERROR_FILE,
    EpisodeWriter,
    failed_dir,
    is_episode_dir,
    is_unscored_episode_dir,
)
from foldbot.io.staging import output_path
from foldbot.layout_check import check_cell_fits
from foldbot.pipeline import injected_faults
from foldbot.ros.node_args import (
    ARM_INTERFACES,
    CELLS,
    GRIPPER_LEAD_S,
    MAX_CLOTH_THICKNESS,
    MAX_GRIPPER_EFFORT_N,
    SLIP_FINGER_TRAVEL,
    TOGETHER_LEAD_S,
    finger_joint_names,
)
from foldbot.verdict import unscored_outcome

DEFAULT_PORT = 11311
MASTER_WAIT_S = 15.0
"""How long `--cell real` waits for the running cell's ROS master to answer."""
MAX_MASTER_WAIT_S = 3600.0
"""The longest --master-wait taken: a cell that has not answered in an hour is not coming up."""
ROS_PACKAGE_DIR = Path(__file__).resolve().parents[3] / "ros"
"""The repository's ROS package folder (holds foldbot_ros/)."""


STOP_WAIT_S = 30.0
"""How long an interrupted roslaunch is given to stop its nodes (and roscore) before it is
killed."""


def stop_launch(proc: subprocess.Popen) -> None:
    """Stop a roslaunch as Ctrl-C does (SIGINT: it takes its nodes and roscore down first), then
    wait STOP_WAIT_S for it; killed only if it has not ended by then (killing it at once would
    leave its nodes running)."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=STOP_WAIT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def ros_missing() -> str | None:
    """Why ROS 1 cannot run here, or None when it can."""
    try:
        import rosbag  # noqa: F401
        import rospy  # noqa: F401
    except ImportError as exc:
        return f"ROS 1 Python packages are not importable ({exc}); run scripts/install_ros.sh"
    for tool in ("roslaunch", "roscore", "rosbag"):
        if shutil.which(tool) is None:
            return f"`{tool}` is not on PATH; run scripts/install_ros.sh"
    if not (ROS_PACKAGE_DIR / "foldbot_ros" / "package.xml").is_file():
        return f"the foldbot_ros package is not at {ROS_PACKAGE_DIR} (use a source checkout)"
    return None


def ros_env(port: int | None) -> dict[str, str]:
    """Environment for ROS processes: our package on ROS_PACKAGE_PATH, this interpreter's bin
    first on PATH (the nodes' `python3`), the master on `port` (None: the environment's
    ROS_MASTER_URI where set, else port 11311)."""
    env = dict(os.environ)
    paths = [str(ROS_PACKAGE_DIR), "/usr/share"]
    if env.get("ROS_PACKAGE_PATH"):
        paths.append(env["ROS_PACKAGE_PATH"])
    env["ROS_PACKAGE_PATH"] = os.pathsep.join(paths)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    if port is not None or not env.get("ROS_MASTER_URI"):
        env["ROS_MASTER_URI"] = f"http://localhost:{DEFAULT_PORT if port is None else port}"
    env.setdefault("ROS_HOSTNAME", "localhost")
    env["PYTHONUNBUFFERED"] = "1"
    return env


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """`foldbot fold`'s options (`--suite` among them), plus the ROS ones."""
    fold.add_arguments(parser, camera_pose=False)
    parser.add_argument(
        "--record", type=output_path, default=None, help="record the run to this .bag"
    )
    parser.add_argument(
        "--camera-rate",
        type=float,
        default=None,
        help="camera frames per simulated second during motions (default: --video-fps); 0: "
        "no stream, only the resting frames the fold looks at (the lockstep cell, no video)",
    )
    add_master_port(parser, "started if none runs there")
    parser.add_argument(
        "--cell",
        choices=CELLS,
        default="sim",
        help="sim (default): start the sim node, which scores the fold; real: fold on a cell "
        "already running on the ROS master (a UR5's and gripper's drivers and an RGB-D camera, "
        "or `foldbot ros-cell`) through its drivers' actions, one arm or two (with --start "
        "crumpled, flattened first); the fold is not scored (no ground truth): result.json "
        "gives what the camera saw",
    )
    parser.add_argument(
        "--arm-interface",
        choices=ARM_INTERFACES,
        default=None,
        help="topics (default with --cell sim): the sim node's lockstep commands "
        "(repeatable); actions (--cell real's): control_msgs/FollowJointTrajectory and "
        "GripperCommand as a real arm's drivers serve them, the cell running on at real-time "
        "pace (with --arms 2, each arm's drivers under left/ and right/, a pair's two goals "
        "stamped to start together)",
    )
    add_real_time_factor(parser, "with --cell sim --arm-interface actions: ")
    parser.add_argument(
        "--together-lead",
        type=float,
        default=None,
        metavar="S",
        help="with --arms 2 and --arm-interface actions: seconds ahead of the cell's clock a "
        "motion both arms make is stamped to start, so that both goals reach their drivers "
        f"before it (default {TOGETHER_LEAD_S:g}; a goal that arrives late starts on arrival, "
        "out of step with the other arm)",
    )
    parser.add_argument(
        "--master-wait",
        type=float,
        default=None,
        metavar="S",
        help="with --cell real: seconds to wait for the running cell's ROS master to answer "
        f"before giving up (default {MASTER_WAIT_S:g}, at most {MAX_MASTER_WAIT_S:g}; a cell "
        "just started may still be bringing its roscore up)",
    )
    parser.add_argument(
        "--cloth-thickness",
        type=float,
        default=None,
        metavar="M",
        help="with --cell real: the towel's layer thickness in m (e.g. 0.003), the height the "
        "loop gives a laid layer where depth tells nothing of it (grasps and places on a "
        "stack); default: the simulated cloth's of the same size (two collision margins, "
        "about 10 mm on a 30 cm towel)",
    )
    parser.add_argument(
        "--camera-pose",
        type=Path,
        default=None,
        metavar="CALIBRATION.json",
        help="with --cell real: publish the camera's pose from this calibration (`foldbot "
        "ros-calibrate`'s calibration.json) as world → camera_color_optical_frame on /tf_static, "
        "for a cell that publishes none of its own; on the simulated cell: as `foldbot fold "
        "--camera-pose`, the camera placed where the calibration was solved and the pose it "
        "found published",
    )
    parser.add_argument(
        "--gripper-lead",
        type=gripper_lead,
        default=GRIPPER_LEAD_S,
        metavar="S|off",
        help="with --arm-interface actions: seconds before a motion's end the gripper goal that "
        f"follows it is sent, so the jaws act as the arm arrives (default {GRIPPER_LEAD_S}); "
        "off: after the motion's result, a round trip later",
    )
    add_finger_watch(parser)


def add_finger_watch(parser: argparse.ArgumentParser) -> None:
    """--finger-joints and --finger-travel: the watch for a slip through the drivers; and
    --gripper-effort, the force the gripper goals ask for."""
    parser.add_argument(
        "--finger-joints",
        default=None,
        metavar="NAMES|none",
        help="with --arm-interface actions: the gripper's joints on /joint_states watched for a "
        "slip, comma-separated, one arm's (two arms: each prefixed as the arm joints are; "
        "default: the robot model's, left_finger_joint,right_finger_joint for the ur5's); none: "
        "no watch",
    )
    parser.add_argument(
        "--finger-travel",
        type=float,
        default=None,
        metavar="X",
        help="with --arm-interface actions: how far a watched finger joint may move on the way "
        "it closed, in its own units (m for the robot model's prismatic fingers, rad for a "
        "revolute one), after the jaws stalled on cloth before the hold counts as lost (pushed "
        "open is no slip; default: for the robot model's "
        f"fingers a quarter of the cloth's thickness, at most {SLIP_FINGER_TRAVEL:g} m; for "
        f"--finger-joints NAMES {SLIP_FINGER_TRAVEL:g})",
    )
    parser.add_argument(
        "--gripper-effort",
        type=float,
        default=None,
        metavar="N",
        help="with --arm-interface actions: the max_effort (N) of every GripperCommand goal "
        f"(0–{MAX_GRIPPER_EFFORT_N:g}; default 0, control_msgs' 'no limit', which some drivers "
        "read otherwise: Robotiq's 2F action server clamps it to its weakest grip)",
    )


def gripper_lead(text: str) -> float | None:
    """`--gripper-lead`'s value: seconds ≥ 0, or off (None)."""
    if text.strip().lower() == "off":
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise argparse.ArgumentTypeError(f"must be seconds in [0, 1] or off, got {text!r}")
    return value


def add_master_port(parser: argparse.ArgumentParser, started: str) -> None:
    parser.add_argument(
        "--port",
        type=int,
        default=None,
        help=f"ROS master port on this machine ({started}; default: ROS_MASTER_URI where set "
        f"with --cell real, else {DEFAULT_PORT})",
    )


def add_real_time_factor(parser: argparse.ArgumentParser, where: str) -> None:
    parser.add_argument(
        "--real-time-factor",
        type=float,
        default=None,
        help=f"{where}simulated seconds per wall second (default 1)",
    )


def check_finger_watch(args: argparse.Namespace, interface: str) -> list[str]:
    """roslaunch's finger_joints, finger_travel and gripper_effort arguments from
    --finger-joints, --finger-travel and --gripper-effort (none where not given); ConfigError
    where they cannot apply or are bad."""
    given = [
        f for f, v in (("--finger-joints", args.finger_joints), ("--finger-travel", args.finger_travel))
        if v is not None
    ]  # fmt: skip
    if given and interface != "actions":
        raise ConfigError(
            f"{' and '.join(given)}: the fingers are watched for a slip through the drivers' "
            f"actions (--arm-interface actions, --cell real's); got --arm-interface {interface}"
        )
    effort = args.gripper_effort
    if effort is not None and interface != "actions":
        raise ConfigError(
            "--gripper-effort: the effort goes in the drivers' GripperCommand goals "
            f"(--arm-interface actions, --cell real's); got --arm-interface {interface}"
        )
    if effort is not None and not (math.isfinite(effort) and 0 <= effort <= MAX_GRIPPER_EFFORT_N):
        raise ConfigError(
            f"--gripper-effort must be newtons in [0, {MAX_GRIPPER_EFFORT_N:g}] (0: no limit), "
            f"got {effort!r}"
        )
    words = []
    if args.finger_joints is not None:
        finger_joint_names(args.finger_joints, ())
        words.append(f"finger_joints:={args.finger_joints}")
    travel = args.finger_travel
    if travel is not None:
        if not (math.isfinite(travel) and travel > 0):
            raise ConfigError(f"--finger-travel must be > 0, got {travel!r}")
        words.append(f"finger_travel:={travel!r}")
    if effort is not None:
        words.append(f"gripper_effort:={effort!r}")
    return words


def check_port(port: int | None) -> None:
    if port is not None and not (1 <= port <= 65535):
        raise ConfigError(f"--port must be in 1–65535, got {port}")


def check_real_time_factor(factor: float | None) -> None:
    if factor is not None and not (math.isfinite(factor) and factor > 0):
        raise ConfigError(f"--real-time-factor must be > 0, got {factor!r}")


def check_episode_output(out: Path, overwrite: bool) -> None:
    """Refuse, before anything starts, an episode folder the task node's EpisodeWriter would
    refuse once the fold is done (OutputError): a file, a folder holding something other than
    an episode, an episode without --overwrite, a place that cannot be written. The writer's
    own checks, as `foldbot fold` makes them: its staging folder is made and dropped again."""
    if out.is_dir() and (is_episode_dir(out) or is_unscored_episode_dir(out)) and not overwrite:
        raise OutputError(f"--out {out} already holds an episode; pass --overwrite to replace it")
    EpisodeWriter(out, overwrite=overwrite).abort()


def check_bag_target(bag: Path, overwrite: bool) -> None:
    """Refuse, before anything starts, a --record bag the recorder could not write: no .bag,
    a folder, a bag already there without --overwrite, a folder that cannot be made or
    written in (a file is made there and removed, as rosbag record will make its own)."""
    if bag.suffix != ".bag":
        raise ConfigError(f"--record must name a .bag file, got {str(bag)!r}")
    if bag.is_dir():
        raise OutputError(f"--record {bag} is a folder; allowed: a .bag file's path")
    if bag.exists() and not overwrite:
        raise OutputError(f"{bag} already exists; pass --overwrite to replace it")
    folder = bag.parent
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"--record {bag}: {str(folder)!r} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle, probe = tempfile.mkstemp(prefix=f".{bag.name}.", dir=folder)
        os.close(handle)
        os.unlink(probe)
    except OSError as exc:
        raise OutputError(
            f"--record {bag}: cannot write a bag in {str(folder)!r} ({exc.strerror or exc}); "
            "allowed: a .bag path in a folder that can be written"
        ) from None


def file_stamp(path: Path) -> int | None:
    """`path`'s modification time (ns) where it is a file, else None: a file the run writes
    is told from the one that was there before it."""
    return path.stat().st_mtime_ns if path.is_file() else None


def drop_stopped_record(out: Path, before: int | None) -> None:
    """Remove the `DIR.failed/` the task node left when the command was stopped (its error is
    the shutdown's, not the fold's): a stopped ros-fold, like a stopped fold, leaves nothing.
    `before`: its error.json's stamp at launch (an earlier run's record stays)."""
    stamp = file_stamp(failed_dir(out) / ERROR_FILE)
    if stamp is not None and stamp != before:
        shutil.rmtree(failed_dir(out), ignore_errors=True)


def check_bag_recorded(bag: Path, before: int | None) -> None:
    """FoldbotError unless the run left its bag at `bag`: a file that was not there (`before`
    None), or one written since (`before`: file_stamp of the bag --overwrite replaces)."""
    stamp = file_stamp(bag)
    if stamp is not None and stamp != before:
        return
    active = bag.with_name(bag.name + ".active")
    left = (
        f"; it left {active} unfinished (`rosbag reindex` may recover it)"
        if active.is_file()
        else ""
    )
    raise FoldbotError(
        f"--record {bag}: no bag was recorded (rosbag record failed: see its output above)" + left
    )


def master_running(env: dict[str, str], wait_s: float = MASTER_WAIT_S) -> bool:
    """Whether a ROS master answers at env's ROS_MASTER_URI within `wait_s` (a cell started
    a moment before may still be bringing its roscore up)."""
    import rosgraph

    master = rosgraph.Master("/foldbot_ros_fold", master_uri=env["ROS_MASTER_URI"])
    deadline = time.monotonic() + wait_s
    while not master.is_online():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.2)
    return True


def add_running_cell_master(parser: argparse.ArgumentParser) -> None:
    """--port and --master-wait, for a command that asks a cell already running."""
    add_master_port(parser, "a cell must be running there")
    parser.add_argument(
        "--master-wait",
        type=float,
        default=None,
        metavar="S",
        help=f"how long to wait for the master to answer (default {MASTER_WAIT_S:g} s, at most "
        f"{MAX_MASTER_WAIT_S:g})",
    )


def master_wait_s(wait: float | None) -> float:
    """--master-wait's seconds (None: MASTER_WAIT_S); ConfigError unless in [0,
    MAX_MASTER_WAIT_S]."""
    if wait is None:
        return MASTER_WAIT_S
    if not (math.isfinite(wait) and 0.0 <= wait <= MAX_MASTER_WAIT_S):
        raise ConfigError(
            f"--master-wait must be seconds in [0, {MAX_MASTER_WAIT_S:g}], got {wait!r}"
        )
    return wait


def running_cell_env(args: argparse.Namespace, start: str) -> dict[str, str]:
    """The environment of a node that asks the cell already running at --port's master (or
    ROS_MASTER_URI's), once ROS is here and that master answers within --master-wait;
    FoldbotError naming what is missing, `start` saying how to bring a cell up."""
    check_port(args.port)
    wait_s = master_wait_s(args.master_wait)
    missing = ros_missing()
    if missing:
        raise FoldbotError(missing)
    env = ros_env(args.port)
    if not master_running(env, wait_s):
        raise FoldbotError(
            f"no ROS master answers at {env['ROS_MASTER_URI']} within {wait_s:g} s: start the "
            f"cell first ({start})"
        )
    return env


def run_node(
    module: str, node_args: list[str], env: dict[str, str], what: str, ok: tuple[int, ...] = (0,)
) -> int:
    """Run foldbot's node `module` (python -m) against the running cell; its exit code, or
    FoldbotError naming `what` failed with the node's last word on stderr."""
    cmd = [sys.executable, "-m", module, *node_args]
    proc = subprocess.run(cmd, env=env, stderr=subprocess.PIPE, text=True, check=False)
    if proc.returncode not in ok:
        lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
        raise FoldbotError(f"{what} failed: " + (lines[-1] if lines else f"exit {proc.returncode}"))
    return proc.returncode


def check_calibrated_camera(calibration: Path, env: dict[str, str]) -> None:
    """A real cell's camera is the one `calibration` was solved with (image size, K, distortion:
    ros-check's "the camera as calibrated"); FoldbotError naming how it differs, before anything
    is launched. A calibration that records no intrinsics is not compared."""
    cmd = [sys.executable, "-m", "foldbot.ros.check_node", "--camera-only"]
    cmd += ["--camera-pose", str(calibration)]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if proc.returncode == 0:
        if proc.stdout.strip():
            print(proc.stdout.strip().removeprefix("ok").strip())
        return
    fail = [ln for ln in proc.stdout.splitlines() if ln.startswith("FAIL ")]
    if proc.returncode == 1 and fail:
        raise FoldbotError(f"--camera-pose {calibration}: {fail[0].removeprefix('FAIL ')}")
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    raise FoldbotError(
        "checking the camera against the calibration failed: "
        + (lines[-1] if lines else f"exit {proc.returncode}")
    )


def fold_args_text(args: argparse.Namespace) -> str:
    """The episode's `foldbot fold` options as one shell-quoted string (the nodes parse it): every
    option that shapes the episode, so the nodes' EpisodeConfig is the command's. With --suite,
    the suite (its file's absolute path: the nodes run elsewhere) and the options that pick its
    episode."""
    if args.suite is not None:
        return shlex.join(suite_args_words(args))
    words = [
        *("--garment", args.garment, "--recipe", args.recipe or fold.DEFAULT_RECIPES[args.garment]),
        *("--robot", args.robot, "--arms", str(args.arms)),
        *("--perception", args.perception, "--seed", str(args.seed), "--park", args.park),
        *("--replicate", str(args.replicate), "--jaw-catch", args.jaw_catch),
        *("--start", args.start),
        *("--video-fps", repr(args.video_fps)),
        *("--out", str(Path(args.out).resolve())),
    ]
    if args.mass is not None:
        words += ["--mass", repr(args.mass)]
    words += ["--time-step", repr(args.time_step), "--speed-scale", repr(args.speed_scale)]
    words += option_words(args) + fault_words(args)
    if args.garment_edge_length is not None:
        words += ["--garment-edge-length", repr(args.garment_edge_length)]
    words += ["--garment-yaw", repr(args.garment_yaw)]
    words += towel_words(args)
    if args.layout is not None:  # its absolute path: the nodes run elsewhere
        words += ["--layout", str(Path(args.layout).resolve())]
    words += camera_words(args)
    if args.overwrite:
        words.append("--overwrite")
    if getattr(args, "confirm", False):  # ros-cell has none
        words.append("--confirm")
    return shlex.join(words)


def towel_words(args: argparse.Namespace) -> list[str]:
    """The towel options given (fold.TOWEL_OPTIONS), as fold's words; those not given keep
    fold's defaults in the nodes too."""
    words: list[str] = []
    for name in fold.TOWEL_OPTIONS:
        value = getattr(args, name)
        if isinstance(value, bool):
            words.append(fold.given_flag(name, value))
        elif value is not None:
            words += [fold.given_flag(name, value), repr(value)]
    return words


def camera_words(args: argparse.Namespace) -> list[str]:
    """`--camera-pose` with the calibration's absolute path, where the simulated cell's camera
    is placed by one (fold.calibrated_camera); else none."""
    path = getattr(args, "camera_calibration", None)
    return [] if path is None else ["--camera-pose", str(Path(path).resolve())]


def option_words(args: argparse.Namespace) -> list[str]:
    """The loop, cloth and flatten options given, as words."""
    words = []
    for flag, given in (
        ("--loop-option", args.loop_option),
        ("--cloth", args.cloth),
        ("--flatten-option", args.flatten_option),
    ):
        for option in given or ():
            words += [flag, option]
    return words


def fault_words(args: argparse.Namespace) -> list[str]:
    """The faults the simulated cell is to inject (--fault-slip, --fault-grasp-offset), where
    given."""
    words = []
    for name in fold.SUITE_FAULTS:
        value = getattr(args, name, 0.0)
        if value:
            words += ["--" + name.replace("_", "-"), repr(value)]
    return words


def suite_args_words(args: argparse.Namespace) -> list[str]:
    """`--suite PATH --episode ID` (the episode the options pick), the loop, cloth and flatten
    options set over the suite's own, the video rate and output folder."""
    from foldbot.bench.suite import resolve_suite_path

    words = ["--suite", str(resolve_suite_path(args.suite).resolve())]
    words += ["--episode", fold.pick_suite_episode(args).id, *option_words(args)]
    words += fault_words(args)
    words += camera_words(args)
    words += ["--video-fps", repr(args.video_fps), "--out", str(Path(args.out).resolve())]
    if args.overwrite:
        words.append("--overwrite")
    if getattr(args, "confirm", False):  # ros-cell has none
        words.append("--confirm")
    return words


def check_real_cell(args: argparse.Namespace, cfg, interface: str) -> None:
    """What a fold on a real cell cannot have, refused by name before anything starts."""
    refused = [
        (interface != "actions", f"--arm-interface {interface}: a real cell is driven "
         "through its drivers' actions (--arm-interface actions)"),
        (args.real_time_factor is not None, "--real-time-factor: a real cell runs at its own "
         "pace (`foldbot ros-cell --real-time-factor` sets the simulated cell's)"),
        (args.camera_rate is not None, "--camera-rate: a real cell's camera streams at its "
         "own rate (`foldbot ros-cell --camera-rate` sets the simulated cell's)"),
    ]  # fmt: skip
    for bad, text in refused:
        if bad:
            raise ConfigError(f"--cell real: {text}")


def run(args: argparse.Namespace) -> int:
    """Validate, roslaunch the fold, then report from the episode folder the task node wrote."""
    if args.gui:
        raise ConfigError("--gui is not available over ROS; use `foldbot fold --gui`")
    real = args.cell == "real"
    # On the simulated cell a calibration places its camera (fold.calibrated_camera); on a real
    # one it is published as the camera's pose.
    args.camera_calibration = None if real else args.camera_pose
    # Bad values fail here, before anything starts.
    cfg = fold.config_from_args(args)
    if words := fold.perceived_pose_line(cfg.camera):
        print(words)
    if cfg.perception != "vision":
        raise ConfigError(
            f"--perception {cfg.perception!r} is not available over ROS: the perception node "
            "is vision (RGB-D) only; use `foldbot fold --perception oracle` for the oracle"
        )
    interface = args.arm_interface or ("actions" if real else "topics")
    if real:
        check_real_cell(args, cfg, interface)
    faulty = injected_faults(cfg)
    fold.check_confirm(args)
    if args.dry_run:
        check_dry_run_config(cfg.garment, cfg.start, faulty, cfg.arms)
    if faulty and real:
        raise ConfigError(
            f"{' and '.join(faulty)}: faults are the simulated cell's, injected on the cell "
            "ros-fold starts (--cell sim, through either arm interface); got --cell real"
        )
    if args.real_time_factor is not None and interface != "actions":
        raise ConfigError(
            "--real-time-factor paces the simulated cell's drivers: it applies with "
            f"--arm-interface actions (the topics interface runs in lockstep, as fast as it "
            f"can); got --arm-interface {interface}"
        )
    check_real_time_factor(args.real_time_factor)
    check_port(args.port)
    if args.master_wait is not None and not real:
        raise ConfigError(
            "--master-wait is for --cell real (with --cell sim, ros-fold starts its own master)"
        )
    wait_s = master_wait_s(args.master_wait)
    thickness = args.cloth_thickness
    if thickness is not None and not real:
        raise ConfigError(
            "--cloth-thickness is for --cell real (with --cell sim, the simulated cloth's own "
            "thickness is used: two collision margins, set by --cloth margin_divisor=N)"
        )
    camera_pose = ""
    if args.camera_pose is not None and real:
        camera_pose = " ".join(calibration_pose_words(args.camera_pose))
    if thickness is not None and not (
        math.isfinite(thickness) and 0.0 < thickness <= MAX_CLOTH_THICKNESS
    ):
        raise ConfigError(
            f"--cloth-thickness must be metres in (0, {MAX_CLOTH_THICKNESS:g}], got {thickness!r}"
        )
    finger_words = check_finger_watch(args, interface)
    together = args.together_lead
    if together is not None and not (cfg.arms == 2 and interface == "actions"):
        raise ConfigError(
            "--together-lead is for two arms through their drivers (--arms 2 --arm-interface "
            f"actions), got --arms {cfg.arms} and --arm-interface {interface}"
        )
    if together is not None and not (math.isfinite(together) and 0.0 <= together <= 5.0):
        raise ConfigError(f"--together-lead must be seconds in [0, 5], got {together!r}")
    rate = args.video_fps if args.camera_rate is None else args.camera_rate
    if real:
        rate = 0.0  # the cell's camera streams at its own rate
    elif not (math.isfinite(rate) and rate >= 0):
        raise ConfigError(f"--camera-rate must be ≥ 0 frames per simulated s, got {rate!r}")
    elif rate == 0 and interface == "actions":
        raise ConfigError(
            "--arm-interface actions folds from the camera's stream, as on a real cell: "
            "--camera-rate must be > 0 (it defaults to --video-fps)"
        )
    elif rate == 0 and args.video_fps > 0:
        raise ConfigError(
            f"--camera-rate 0 streams no frames for the video (--video-fps {args.video_fps:g}); "
            "pass --video-fps 0, or a camera rate > 0"
        )
    out = Path(args.out)
    if args.dry_run:
        check_dry_run_output(out, args.overwrite)
    else:
        check_episode_output(out, args.overwrite)
    # The arms reach the workspace and rest clear of the layout's obstacles: refused here by
    # name, where a node refusing it as it starts would end the launch unexplained.
    check_cell_fits(cfg.sim.layout, cfg.robot, cfg.arms, cfg.park)
    if args.record is not None:
        check_bag_target(args.record, args.overwrite)
    bag_before = None if args.record is None else file_stamp(args.record)
    missing = ros_missing()
    if missing:
        raise FoldbotError(missing)
    env = ros_env(args.port if args.port is not None or real else DEFAULT_PORT)
    if real and not master_running(env, wait_s):
        raise FoldbotError(
            f"no ROS master answers at {env['ROS_MASTER_URI']} within {wait_s:g} s: "
            "--cell real folds on a cell "
            "that is already running (its drivers, camera and roscore; or `foldbot ros-cell`); "
            "set ROS_MASTER_URI or --port to its master"
        )
    if real and args.camera_pose is not None:  # perceived through the intrinsics it was solved with
        check_calibrated_camera(Path(args.camera_pose), env)
    # A real cell's master is running: roslaunch waits for it rather than starting one.
    where = ["--wait"] if real else ["-p", env["ROS_MASTER_URI"].rsplit(":", 1)[1]]
    cmd = [
        "roslaunch",
        *where,
        "foldbot_ros",
        "fold.launch",
        f"fold_args:={fold_args_text(args)}",
        f"camera_rate:={rate}",
        f"record:={args.record.resolve() if args.record else ''}",
        f"cell:={args.cell}",
        f"arm_interface:={interface}",
        f"real_time_factor:={args.real_time_factor or 1.0!r}",
        f"gripper_lead:={-1.0 if args.gripper_lead is None else args.gripper_lead!r}",
        f"together_lead:={TOGETHER_LEAD_S if together is None else together!r}",
        f"cloth_thickness:={-1.0 if thickness is None else thickness!r}",
        f"camera_pose:={camera_pose}",
        f"dry_run:={'true' if args.dry_run else 'false'}",
        *finger_words,
    ]
    result_file = out / (PLAN_FILE if args.dry_run else "result.json")
    before = file_stamp(result_file)
    failed_before = file_stamp(failed_dir(out) / ERROR_FILE)
    with tempfile.TemporaryDirectory(prefix="foldbot-ros-") as tmp:
        error_file = Path(tmp) / "error.json"
        proc = subprocess.Popen([*cmd, f"error_file:={error_file}"], env=env)
        try:
            proc.wait()
        except BaseException:  # Ctrl-C, or `kill` (foldbot.cli.Terminated)
            stop_launch(proc)
            drop_stopped_record(out, failed_before)
            raise
        failure = json.loads(error_file.read_text()) if error_file.is_file() else None
    if file_stamp(result_file) in (None, before):
        if failure is not None:  # the task node's own error, as `foldbot fold` would name it
            raise errors.reported_error(failure, "over ROS")
        raise FoldbotError(
            f"the ROS fold wrote no {'plan' if args.dry_run else 'episode'} (roslaunch exit "
            f"code {proc.returncode}); see the nodes' output above"
        )
    result = json.loads(result_file.read_text())
    if args.dry_run:
        print(DryRun(result).summary().replace("dry run:", "dry run over ROS:", 1))
        print(f"plan written to {out}")
        return 0 if result["feasible"] else 1
    if result.get("scored", True):
        print(
            f"fold {'succeeded' if result['success'] else 'FAILED'} over ROS: "
            f"fold error {result['fold_error_mm']:.1f} mm, "
            f"normalized performance {result['normalized_performance']:.3f}, "
            f"{result['sim_seconds']:.1f} s simulated in {result['wall_seconds']:.1f} s"
        )
    else:
        print(f"{unscored_outcome(result['perceived'])}; {result['sim_seconds']:.1f} s")
    print(f"episode written to {out}")
    if args.record:
        check_bag_recorded(args.record, bag_before)
        print(f"bag recorded to {args.record}")
    return 0
