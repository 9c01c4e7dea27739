"""`foldbot ros-fold --confirm`: the task node asks on the terminal ros-fold was started from
(roslaunch hands its stdin and stdout down to the node) before each pick-and-place; a stop ends
the fold named over ROS, as in process (tests/test_operator.py)."""

from __future__ import annotations

import contextlib
import json
import os
import queue
import subprocess
import sys
import threading
import time

import numpy as np
from ros_helpers import free_port, requires_ros

from foldbot.perception.overlay import GRASP_RGB, PLACE_RGB

pytestmark = requires_ros


def test_the_operator_lets_a_missed_carry_its_lift_and_park_run_and_stops_the_retry_over_ros(
    tmp_path,
):
    # The first grasp aimed 5 cm off the corner misses: the carry, the lift that lets go and the
    # park are let run (the planner node's lift and park, asked as in process), the retry stopped.
    out = tmp_path / "ep"
    proc = subprocess.run(
        [
            sys.executable, "-m", "foldbot.cli", "ros-fold", "--confirm", "--resolution", "9",
            "--video-fps", "0", "--fault-grasp-offset", "0.05", "--out", str(out),
            "--port", str(free_port()),
        ],
        input="\n\n\ns\n", capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stdout[-3000:] + proc.stderr[-3000:]
    asked = [line.split(":")[1].strip() for line in proc.stdout.splitlines() if "next: " in line]
    assert asked == [
        "far_left with arm 0",
        "lift after the missed grasp with arm 0",
        "park with arm 0",
        "far_left with arm 0",
    ], proc.stdout[-3000:]
    assert "next: lift after the missed grasp with arm 0: open the jaws, straight up 0.080 m, " in (
        proc.stdout
    )
    assert "error: over ROS: stopped by the operator before far_left" in proc.stderr
    assert not out.exists()
    failure = json.loads((tmp_path / "ep.failed" / "error.json").read_text())
    assert failure["error_type"] == "OperatorStopped"


OVERLAY_SCRIPT = """
import sys
import foldbot
import numpy as np
import rospy
from sensor_msgs.msg import Image
from foldbot.ros import convert

rospy.init_node("plan_overlay_probe", anonymous=True)
msg = rospy.wait_for_message("/task/plan_overlay", Image, timeout=120)
np.save(sys.argv[1], convert.color_array(msg))
print(msg.header.frame_id, msg.encoding, flush=True)
"""


def test_what_waits_for_the_operator_is_drawn_on_the_plan_overlay_topic(tmp_path):
    """task/plan_overlay (latched) holds the frame the waiting carry was planned from with its
    grasp and place drawn, for RViz and the operator; answered `s`, nothing moves."""
    port = free_port()
    env = {**os.environ, "ROS_MASTER_URI": f"http://localhost:{port}"}
    proc = subprocess.Popen(
        [
            sys.executable, "-m", "foldbot.cli", "ros-fold", "--confirm", "--resolution", "9",
            "--video-fps", "0", "--out", str(tmp_path / "ep"), "--port", str(port),
        ],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True).start()
    try:
        seen, deadline = "", time.monotonic() + 300
        while "next: far_left" not in seen:
            assert time.monotonic() < deadline and proc.poll() is None, seen[-3000:]
            with contextlib.suppress(queue.Empty):
                seen += lines.get(timeout=1.0)
        saved = tmp_path / "overlay.npy"
        probe = subprocess.run(
            [sys.executable, "-c", OVERLAY_SCRIPT, str(saved)], env=env, capture_output=True,
            text=True, timeout=180,
        )  # fmt: skip
        assert probe.returncode == 0, probe.stderr[-3000:]
        assert probe.stdout.split()[-2:] == ["camera_color_optical_frame", "rgb8"]
        proc.stdin.write("s\n")
        proc.stdin.flush()
        assert proc.wait(timeout=300) == 2
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    image = np.load(saved).astype(int)
    assert image.shape == (480, 640, 3)
    for rgb in (GRASP_RGB, PLACE_RGB):  # the carry's grasp (a cross) and place (a ring)
        assert int((np.abs(image - rgb) <= 30).all(-1).sum()) > 20, rgb
