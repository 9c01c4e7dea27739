"""Score a fold made on the simulated cell as a real one (`foldbot ros-fold --cell real`, on
`foldbot ros-cell`) from that cell's ground truth: the settled start it latched on
ground_truth/cloth before anything moved, and the cloth now, asked for on
ground_truth/request. For comparison only: the fold never saw either (its task node neither
subscribes nor publishes there). Prints one JSON line: the episode's metrics as
metrics.score_episode gives them, and how far into the episode the comparison is valid; for a
crumpled start (`--start crumpled` on both), the crumpled cloth's coverage and the cloth's now
only, since the flattened cloth the fold began from was never latched.

    .venv/bin/python scripts/score_on_sim_cell.py EPISODE_DIR --port 11311
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import json
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

from foldbot.commands.ros_fold import master_running, ros_env
from foldbot.metrics import coverage, score_episode

WAIT_S = 60.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("episode", type=Path, help="the folder `ros-fold --cell real` wrote")
    parser.add_argument("--port", type=int, required=True, help="the cell's ROS master port")
    args = parser.parse_args(argv)
    result = json.loads((args.episode / "result.json").read_text())
    if result.get("cell") != "real":
        parser.error(f"{args.episode} is not a `--cell real` episode (cell {result.get('cell')!r})")
    env = ros_env(args.port)
    if not master_running(env, wait_s=5.0):  # rospy would retry registering for ever
        sys.exit(
            f"score_on_sim_cell: no ROS master answers at {env['ROS_MASTER_URI']}: the cell "
            "has stopped (its log says why) or runs on another --port"
        )
    os.environ.update(env)
    import rospy
    from sensor_msgs.msg import PointCloud2
    from std_msgs.msg import Empty, String

    from foldbot.ros import TOPICS, convert

    rospy.init_node("foldbot_score_on_sim_cell", anonymous=True, disable_signals=True)
    clouds: list[PointCloud2] = []
    got = threading.Condition()

    def on_cloud(msg: PointCloud2) -> None:
        with got:
            clouds.append(msg)
            got.notify_all()

    def wait_for(n: int, what: str) -> PointCloud2:
        with got:
            if not got.wait_for(lambda: len(clouds) >= n, timeout=WAIT_S):
                sys.exit(f"score_on_sim_cell: no {what} on {TOPICS['ground_truth']}")
            return clouds[n - 1]

    rospy.Subscriber(TOPICS["ground_truth"], PointCloud2, on_cloud)
    mesh = json.loads(rospy.wait_for_message(TOPICS["ground_truth_mesh"], String, WAIT_S).data)
    start = wait_for(1, "latched start")
    request = rospy.Publisher(TOPICS["ground_truth_request"], Empty, queue_size=1)
    deadline = time.monotonic() + WAIT_S
    while request.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    request.publish(Empty())
    now = wait_for(2, "cloth after the request")
    faces = np.array(mesh["faces"], dtype=np.int64)
    stamps = {"start_stamp": start.header.stamp.to_sec(), "scored_at": now.header.stamp.to_sec()}
    if "flatten" in result["perceived"]:
        # A crumpled start: the fold's goals are the flattened cloth's, which the cell never
        # latched; the crumpled start's coverage and the cloth's now are what it can give.
        found = {
            "coverage_start": coverage(convert.cloud_array(start), faces, mesh["flat_area"]),
            "coverage": coverage(convert.cloud_array(now), faces, mesh["flat_area"]),
            "fold_error_mm": None,
            "why": "a crumpled start: the flattened cloth the fold began from was not latched",
        }
    else:
        found = score_episode(
            convert.cloud_array(start),
            convert.cloud_array(now),
            faces,
            result["fold_lines"],
            float(mesh["thickness"]),
        ).as_dict()
    print(json.dumps({"episode": str(args.episode), **stamps, **found}))
    rospy.signal_shutdown("scored")
    return 0


if __name__ == "__main__":
    sys.exit(main())
