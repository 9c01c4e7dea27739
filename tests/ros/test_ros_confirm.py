"""`foldbot ros-fold --confirm`: the task node asks on the terminal ros-fold was started from
(roslaunch hands its stdin and stdout down to the node) before each pick-and-place; a stop ends
the fold named over ROS, as in process (tests/test_operator.py)."""

from __future__ import annotations

import json
import subprocess
import sys

from ros_helpers import free_port, requires_ros

pytestmark = requires_ros


def test_the_operator_lets_one_carry_run_and_stops_the_next_over_ros(tmp_path):
    out = tmp_path / "ep"
    proc = subprocess.run(
        [
            sys.executable, "-m", "foldbot.cli", "ros-fold", "--confirm", "--resolution", "9",
            "--video-fps", "0", "--out", str(out), "--port", str(free_port()),
        ],
        input="\ns\n", capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert proc.stdout.count("next: far_left with arm 0: grasp (") == 1
    assert proc.stdout.count("next: far_right with arm 0: grasp (") == 1
    assert "error: over ROS: stopped by the operator before far_right" in proc.stderr
    assert not out.exists()
    failure = json.loads((tmp_path / "ep.failed" / "error.json").read_text())
    assert failure["error_type"] == "OperatorStopped"
