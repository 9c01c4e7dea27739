"""`foldbot ros-replay`: play a bag recorded by `foldbot ros-fold --record` through a fresh
perception node and check that it gives the same keypoints as the live run, frame by frame.
Exit code 0 when every frame matches, 1 when not. Needs ROS 1 (scripts/install_ros.sh)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from foldbot.commands.ros_fold import DEFAULT_PORT, check_port, ros_missing
from foldbot.errors import FoldbotError
from foldbot.ros.replay import MAX_RATE, MIN_RATE, PLAY_TIMEOUT_S, check_rate

if TYPE_CHECKING:
    from foldbot.ros.replay import ReplayReport


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", type=Path, help="bag recorded with foldbot ros-fold --record")
    parser.add_argument(
        "--port", type=int, default=DEFAULT_PORT, help=f"ROS master port (default {DEFAULT_PORT})"
    )
    parser.add_argument(
        "--rate",
        type=float,
        default=1.0,
        help=f"rosbag play rate, {MIN_RATE:g}–{MAX_RATE:g} (default 1); the bag must play "
        f"within {PLAY_TIMEOUT_S:g} s",
    )


def run(args: argparse.Namespace) -> int:
    """Check the options, replay the bag, print the comparison; 0 when the keypoints are the
    live run's, 1 when not."""
    check_port(args.port)
    check_rate(args.rate)
    missing = ros_missing()
    if missing:
        raise FoldbotError(missing)
    from foldbot.ros.replay import replay

    report = replay(args.bag, args.port, args.rate)
    for line in report_lines(report):
        print(line)
    return 0 if report.same else 1


def report_lines(report: ReplayReport) -> list[str]:
    """What `ros-replay` prints of a replay: the comparison, a hint where frames went without
    keypoints, and the verdict."""
    lines = [
        f"replayed {report.frames_compared} of {report.frames_in_bag} frames through the "
        f"perception node: largest keypoint difference {report.max_keypoint_difference_m:.3g} m "
        f"({report.max_sure_difference_m:.3g} m where the live run was sure of the keypoint), "
        f"labels {'equal' if report.labels_equal else 'DIFFER'}, "
        f"detections {'equal' if report.detected_equal else 'DIFFER'}"
    ]
    missing = report.frames_in_bag - report.frames_compared
    if missing > 0:
        lines.append(
            f"the perception node gave no keypoints for {missing} frame(s): its warnings above "
            "say what it waited for (the camera's pose on /tf_static, or for depth in its own "
            "frame the depth camera_info and the transform to the colour frame)"
        )
    lines.append(
        "same keypoints as the live run" if report.same else "NOT the same as the live run"
    )
    return lines
