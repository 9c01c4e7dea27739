"""A two-arm cell through its drivers' actions (`--arms 2 --arm-interface actions`): each arm's
FollowJointTrajectory and GripperCommand under its own namespace, as two UR5s' and grippers'
drivers serve them, a pair's two goals stamped to start together: the sim node serving them,
and a fold through them on a running two-arm cell, as on a real one."""

import json

import pytest
from ros_helpers import probe_drivers, requires_ros, wait_for_master
from test_ros_fold import foldbot, score_on_cell, start_cell, stop_cell

pytestmark = [requires_ros, pytest.mark.slow]


def test_each_arms_drivers_answer_under_its_namespace_and_start_together(tmp_path):
    out = probe_drivers(tmp_path, "driver_probe_two_arms.py", "--arms 2")
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
    # Two gripper goals at once (a pair's): both answered, both arms' jaws moved.
    assert out["both"] == [ok, ok] and min(out["both_moved"]) > 1e-3


def test_a_fold_on_a_running_two_arm_cell_as_on_a_real_one(tmp_path):
    # `ros-cell --arms 2` serves both arms' drivers; `ros-fold --cell real --arms 2` folds on it
    # through them alone, unscored, and the cell's ground truth scores it afterwards. A pair's
    # goals are stamped to start 0.4 s ahead (--together-lead): none reaches its driver late.
    cell, port = start_cell("--arms", "2", "--resolution", "8", "--camera-rate", "2")
    out = tmp_path / "episode"
    try:
        wait_for_master(port)
        proc = foldbot(
            "ros-fold", "--cell", "real", "--arms", "2", "--resolution", "8",
            "--video-fps", "2", "--out", str(out), "--port", str(port),
            "--together-lead", "0.4",
        )  # fmt: skip
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        score = score_on_cell(out, port)
    finally:
        log = stop_cell(cell)
    assert score.returncode == 0, score.stderr[-3000:] + log[-3000:]
    result = json.loads((out / "result.json").read_text())
    assert result["cell"] == "real" and result["scored"] is False and result["arms"] == 2
    assert result["together_lead_s"] == 0.4
    assert "after the start it is stamped with" not in log
    assert result["perceived"]["verified"]
    # The half fold's two far corners carried together, each by the arm on its side, through
    # its own drivers; each arm's tracking from its driver's feedback, on the planner's model.
    actions = result["actions"]
    assert [(a["label"], a["arm"]) for a in actions] == [("far_left", 0), ("far_right", 1)]
    assert all(a["together"] and a["grasp_success"] for a in actions)
    assert all(0.0 < a["max_tracking_error_m"] < 0.01 for a in actions)
    truth = json.loads(score.stdout.strip().splitlines()[-1])
    assert truth["coverage"] < 0.8 and truth["fold_error_mm"] < 20.0, truth
