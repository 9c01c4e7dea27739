"""`foldbot export-bag`: write an episode folder as a ROS 1 bag (camera frames, camera_info,
camera pose, ground-truth cloth before and after, grasp and place points, result.json) with the
pure-Python rosbags library; no ROS installation needed. `rosbag play` plays it back."""

from __future__ import annotations

import argparse
from pathlib import Path

from foldbot.io.staging import output_path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("episode", type=Path, help="episode folder (from foldbot fold / ros-fold)")
    parser.add_argument("--out", type=output_path, required=True, help="the .bag file to write")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing bag")


def run(args: argparse.Namespace) -> int:
    from foldbot.ros.bag_export import export_episode

    counts = export_episode(args.episode, args.out, overwrite=args.overwrite)
    for topic, n in counts.items():
        print(f"  {topic}: {n} message{'s' if n != 1 else ''}")
    print(f"bag written to {args.out}")
    return 0
