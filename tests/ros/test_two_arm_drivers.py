"""A two-arm cell through its drivers' actions (`--arms 2 --arm-interface actions`): each arm's
FollowJointTrajectory and GripperCommand under its own namespace, as two UR5s' and grippers'
drivers serve them, a pair's two goals stamped to start together; the sim node serving them,
a fold through them, and a fold on a running two-arm cell as on a real one."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from ros_helpers import free_port, requires_ros, wait_for_master
from test_ros_fold import foldbot, score_on_cell, start_cell, stop_cell

from foldbot.io.episode import rescore

pytestmark = [requires_ros, pytest.mark.slow]

LAUNCH = """<launch>
  <param name="/use_sim_time" value="true"/>
  <param name="/foldbot/fold_args" value="--out {out} --resolution 5 --video-fps 2 --arms 2"/>
  <param name="/foldbot/camera_rate" value="2"/>
  <param name="/foldbot/arm_interface" value="actions"/>
  <param name="/foldbot/real_time_factor" value="2.0"/>
  <node pkg="foldbot_ros" type="sim_node" name="foldbot_sim" output="screen" required="true"/>
</launch>
"""


def test_each_arms_drivers_answer_under_its_namespace_and_start_together(tmp_path):
    from foldbot.commands.ros_fold import ros_env

    port = free_port()
    launch = tmp_path / "sim.launch"
    launch.write_text(LAUNCH.format(out=tmp_path / "unused"))
    env = ros_env(port)
    sim = subprocess.Popen(
        ["roslaunch", "-p", str(port), str(launch)],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    try:
        probe = subprocess.run(
            [sys.executable, str(Path(__file__).with_name("driver_probe_two_arms.py"))],
            env=env, capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
    finally:
        os.killpg(sim.pid, signal.SIGINT)
        log = sim.communicate(timeout=60)[0]
    lines = [ln for ln in probe.stdout.splitlines() if ln.startswith("PROBE ")]
    assert lines, probe.stdout[-2000:] + probe.stderr[-3000:] + log[-3000:]
    out = json.loads(lines[0][len("PROBE ") :])
    ok = out["succeeded"]
    assert [a for a, _g in out["actions"]] == [
        "left/scaled_pos_joint_traj_controller/follow_joint_trajectory",
        "right/scaled_pos_joint_traj_controller/follow_joint_trajectory",
    ]
    # The left arm's driver takes the left arm's joints only.
    state, code, text = out["crossed"]
    assert state != ok and code == -2 and "must be this arm's joints" in text
    # Two goals sent 0.1 s apart, stamped with one start: both arms start on the same
    # /joint_states sample (every 0.02 s), at the stamp, not on their goal's arrival.
    assert out["together"] == [[ok, 0], [ok, 0]]
    first = out["first_moved"]
    assert abs(first[0] - first[1]) < 0.015, first
    assert out["start"] - 1e-6 <= min(first) <= out["start"] + 0.05, (out["start"], first)
    assert all(abs(t - 0.15) < 0.01 for t in out["turned"])
    # A gripper goal moves its own arm's jaws only.
    assert out["left_close"] == [ok, True]
    assert out["fingers_moved"][0] > 1e-3 and out["fingers_moved"][1] < 1e-6


def test_two_arms_fold_through_their_drivers(tmp_path):
    # The half fold's two far corners carried together, each by its arm's driver, the cell
    # running on at real-time pace as a real one does (not repeatable to the digit: the fold is
    # checked, not its error to a reference).
    out = tmp_path / "episode"
    proc = foldbot(
        "ros-fold", "--arms", "2", "--arm-interface", "actions", "--resolution", "8",
        "--video-fps", "2", "--out", str(out), "--port", str(free_port()),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    result = json.loads((out / "result.json").read_text())
    assert result["arm_interface"] == "actions" and result["arms"] == 2
    assert rescore(out).fold_error_mm == pytest.approx(result["fold_error_mm"])
    actions = result["actions"]
    assert [(a["label"], a["arm"]) for a in actions] == [("far_left", 0), ("far_right", 1)]
    assert all(a["together"] and a["grasp_success"] for a in actions)
    # Each arm's tracking from its own driver's feedback, on the planner node's model.
    assert all(0.0 < a["max_tracking_error_m"] < 0.01 for a in actions)
    assert result["coverage"] < 0.8 and result["fold_error_mm"] < 20.0


def test_a_fold_on_a_running_two_arm_cell_as_on_a_real_one(tmp_path):
    # `ros-cell --arms 2` serves both arms' drivers; `ros-fold --cell real --arms 2` folds on it
    # through them alone, unscored, and the cell's ground truth scores it afterwards.
    cell, port = start_cell("--arms", "2", "--resolution", "8", "--camera-rate", "2")
    out = tmp_path / "episode"
    try:
        wait_for_master(port)
        proc = foldbot(
            "ros-fold", "--cell", "real", "--arms", "2", "--resolution", "8",
            "--video-fps", "2", "--out", str(out), "--port", str(port),
        )  # fmt: skip
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        score = score_on_cell(out, port)
    finally:
        log = stop_cell(cell)
    assert score.returncode == 0, score.stderr[-3000:] + log[-3000:]
    result = json.loads((out / "result.json").read_text())
    assert result["cell"] == "real" and result["scored"] is False and result["arms"] == 2
    assert result["perceived"]["verified"]
    assert [a["arm"] for a in result["actions"]] == [0, 1]
    assert all(a["together"] and a["grasp_success"] for a in result["actions"])
    truth = json.loads(score.stdout.strip().splitlines()[-1])
    assert truth["coverage"] < 0.8 and truth["fold_error_mm"] < 20.0, truth
