"""The sim node as a real cell's drivers (`--arm-interface actions`): FollowJointTrajectory and
GripperCommand goals from a client that knows nothing of foldbot but the joint names, the way
ur_robot_driver and a gripper driver answer them."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from ros_helpers import free_port, requires_ros

from foldbot.errors import FoldbotError

pytestmark = requires_ros

LAUNCH = """<launch>
  <param name="/use_sim_time" value="true"/>
  <param name="/foldbot/fold_args" value="--out {out} --resolution 5 --video-fps 2"/>
  <param name="/foldbot/camera_rate" value="2"/>
  <param name="/foldbot/arm_interface" value="actions"/>
  <param name="/foldbot/real_time_factor" value="2.0"/>
  <node pkg="foldbot_ros" type="sim_node" name="foldbot_sim" output="screen" required="true"/>
</launch>
"""


def test_tolerances_follow_control_msgs_conventions():
    from foldbot.ros.drivers import tolerances

    def tol(name, position):
        return SimpleNamespace(name=name, position=position)

    got = tolerances([tol("b", 0.1), tol("a", -1.0), tol("c", 0.0)], ["a", "b", "c"])
    assert got.tolist() == [float("inf"), 0.1, float("inf")]  # −1 erased, 0 unset: no limit
    with pytest.raises(FoldbotError, match="names joint 'x'"):
        tolerances([tol("x", 0.1)], ["a", "b"])


@pytest.mark.slow
def test_the_sim_node_answers_as_a_real_arms_drivers(tmp_path):
    from foldbot.commands.ros_fold import ros_env

    port = free_port()
    launch = tmp_path / "sim.launch"
    launch.write_text(LAUNCH.format(out=tmp_path / "unused"))
    env = ros_env(port)
    sim = subprocess.Popen(
        ["roslaunch", "-p", str(port), str(launch)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        probe = subprocess.run(
            [sys.executable, str(Path(__file__).with_name("driver_probe.py"))],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
    finally:
        os.killpg(sim.pid, signal.SIGINT)
        log = sim.communicate(timeout=60)[0]
    lines = [ln for ln in probe.stdout.splitlines() if ln.startswith("PROBE ")]
    assert lines, probe.stdout[-2000:] + probe.stderr[-3000:] + log[-3000:]
    out = json.loads(lines[0][len("PROBE ") :])
    ok = out["succeeded"]
    # A joint the arm does not have: refused with INVALID_JOINTS, nothing moves.
    state, code, text, _ = out["bad_joints"]
    assert state != ok and code == -2 and "must be this arm's joints" in text
    # Joints in another order, the first point a second away: followed, with feedback, to the
    # point asked for.
    state, code, _, feedback = out["move"]
    assert (state, code) == (ok, 0) and feedback > 10
    assert out["moved_to"] < 0.01
    # A path tolerance no real arm holds: aborted with PATH_TOLERANCE_VIOLATED, naming the joint.
    state, code, text, _ = out["tight_path"]
    assert state != ok and code == -4 and "path tolerance" in text
    # The cell runs on by itself at the real-time factor asked for (2), or slower on a loaded
    # machine.
    assert 0.2 < out["rate"] < 2.3
    # The jaws closed on nothing above the table: no stall, the goal reached; open likewise.
    assert out["close"][:3] == [ok, False, True]
    assert out["open"][:3] == [ok, False, True]
    assert out["bad"][0] != ok and "must be a gap" in out["bad"][3]
    # A close sent while the arm moves (as the task node sends it, --gripper-lead) starts as
    # the motion ends, not before and not a round trip later (/joint_states every 0.02 s).
    sent, arrived, jaws, state = out["ahead"]
    assert state == ok and sent < arrived - 0.1
    assert arrived - 0.03 <= jaws <= arrived + 0.05, (arrived, jaws)
