"""The episode configuration every node shares: the options of `foldbot fold`, passed once as
the ROS parameter /foldbot/fold_args and parsed by each node with fold's own parser, so the sim,
planner and task nodes build the same EpisodeConfig (and seed) as an in-process fold."""

from __future__ import annotations

import argparse
import shlex

from foldbot.commands import fold
from foldbot.errors import ConfigError
from foldbot.pipeline import EpisodeConfig

FOLD_ARGS_PARAM = "/foldbot/fold_args"
CAMERA_RATE_PARAM = "/foldbot/camera_rate"
ARM_INTERFACE_PARAM = "/foldbot/arm_interface"
"""How the task node drives the arm: "topics" (the sim node's own lockstep commands) or "actions"
(control_msgs' FollowJointTrajectory and GripperCommand, as a real arm's drivers serve them)."""
ARM_INTERFACES = ("topics", "actions")
CELL_PARAM = "/foldbot/cell"
"""What the task node folds on: "sim" (the sim node: its ready report, lockstep or actions, and
its ground truth to score the fold) or "real" (any cell that serves the arm's and gripper's
driver actions, /joint_states and an RGB-D camera's topics: no handshake, no ground truth, the
fold left unscored)."""
CELLS = ("sim", "real")
GRIPPER_LEAD_PARAM = "/foldbot/gripper_lead"
"""With the actions interface: how long (s) before a motion's end the task node sends the
gripper goal that follows it; negative: only after the motion's result (a round trip later)."""
GRIPPER_LEAD_S = 0.05
"""The default lead: about the round trip a driver pair adds between a motion and its gripper
event (docs/ros.md, "A real arm's drivers")."""
TOGETHER_LEAD_PARAM = "/foldbot/together_lead"
"""With the actions interface and two arms: how far ahead of the cell's clock (s) the task node
stamps the common start of a motion both arms make together, so that both goals reach their
drivers before it (a driver starts a goal at its stamp, or on arrival when that has passed)."""
TOGETHER_LEAD_S = 0.25
"""The default: a goal's trip to a driver on one machine is milliseconds; a real cell's links
and its drivers' own latency may need more."""
CLOTH_THICKNESS_PARAM = "/foldbot/cloth_thickness"
"""On a real cell: the towel's layer thickness (m) the loop assumes where depth tells nothing of a
laid layer's height (the grasp and place heights on a stack); negative: the simulated cloth's of
the same size and options (task_node.real_cell_thickness)."""
MAX_CLOTH_THICKNESS = 0.05
"""Largest layer thickness (m) accepted, as for a simulated cloth (sim.cloth.ClothConfig)."""
FINGER_JOINTS_PARAM = "/foldbot/finger_joints"
"""With the actions interface: the gripper's joints on /joint_states the task node watches for a
slip, one arm's, comma-separated (two arms: each prefixed as the arm joints are); empty: the
robot model's own; "none": no watch (finger_joint_names)."""
FINGER_TRAVEL_PARAM = "/foldbot/finger_travel"
"""With the actions interface: how far a watched finger joint may move, in its own units, after
the jaws stalled on cloth before the hold counts as lost (drivers.ActionArm); negative: as
finger_travel_for chooses."""
SLIP_FINGER_TRAVEL = 0.002
"""The most a prismatic finger may move by default (m): 2 mm (the simulated UR5's fingers stop
about 4.5 mm each from closed on the simulated cloth); the only default for another gripper's
joints, whose units the task node does not know."""
GRIPPER_EFFORT_PARAM = "/foldbot/gripper_effort"
"""With the actions interface: the max_effort (N) every GripperCommand goal of the task node
carries; 0: control_msgs' "no limit", which some drivers read otherwise (Robotiq's 2F action
server clamps it to its smallest force, its weakest grip)."""
MAX_GRIPPER_EFFORT_N = 1000.0
"""Largest gripper effort accepted (N): industrial parallel grippers grip with at most a few
hundred newtons."""
DRY_RUN_PARAM = "/foldbot/dry_run"
"""Whether the task node only plans (foldbot.dry_run): one look, every stage and motion planned,
nothing moved, plan.json written instead of an episode."""
REAL_TIME_FACTOR_PARAM = "/foldbot/real_time_factor"
"""With the actions interface: simulated seconds per wall second the sim node runs at."""
CALIBRATION_BOARD_PARAM = "/foldbot/calibration_board"
"""The sim node: the arm (0, or 1 of two) whose tool holds the calibration chessboard
(calibration.board.Chessboard's default, on calibration.views.BoardMount's default bracket), for
`foldbot ros-calibrate`; negative: none."""
CALIBRATION_BOARD_PATTERN_PARAM = "/foldbot/calibration_board_pattern"
"""The sim node: the board that arm holds, "chessboard" (calibration.board.Chessboard's default)
or "charuco" (CharucoBoard's default)."""
PUBLISH_CAMERA_POSE_PARAM = "/foldbot/publish_camera_pose"
"""The sim node: whether it publishes world → the camera on /tf_static (False: a cell whose camera
is not calibrated yet; `foldbot ros-fold --cell real --camera-pose` then publishes one)."""
ERROR_FILE_PARAM = "/foldbot/error_file"
"""Where the task node writes its error (JSON: error, error_type) when the fold fails, for
`foldbot ros-fold` to report; empty: nowhere."""


def finger_joint_names(text: str, robot_fingers: tuple[str, ...]) -> tuple[str, ...]:
    """The finger joints a --finger-joints value names: empty, the robot model's own
    (`robot_fingers`); "none", none; else its comma-separated names."""
    text = text.strip()
    if not text:
        return tuple(robot_fingers)
    if text == "none":
        return ()
    names = tuple(n.strip() for n in text.split(","))
    if not all(names) or any(c.isspace() for n in names for c in n):
        raise ConfigError(
            f"finger joints must be comma-separated joint names, 'none', or empty, got {text!r}"
        )
    return names


def finger_travel_for(
    given: float | None, finger_joints: str, thickness: float
) -> tuple[float, str]:
    """How far a watched finger may move before the hold counts as lost, and where that came
    from: `given` (--finger-travel); else, for the robot model's own prismatic fingers
    (`finger_joints` empty), a quarter of the cloth's layer `thickness` (m), at most
    SLIP_FINGER_TRAVEL: a slip closes each finger by half the gap the cloth held, so a quarter
    is halfway, and a towel thinner than 8 mm is not missed; else SLIP_FINGER_TRAVEL."""
    if given is not None:
        return float(given), "given"
    if not finger_joints.strip():
        return min(SLIP_FINGER_TRAVEL, thickness / 4.0), "cloth thickness"
    return SLIP_FINGER_TRAVEL, "default"


def fold_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="foldbot ros-fold", add_help=False)
    fold.add_arguments(parser)
    return parser


def parse_fold_args(text: str) -> tuple[argparse.Namespace, EpisodeConfig]:
    """Parse `foldbot fold` options (a shell-quoted string); raises ConfigError on bad values."""
    args = fold_parser().parse_args(shlex.split(text))
    return args, fold.config_from_args(args)
