"""`foldbot ros-fold --dry-run`: over ROS the task node looks once, the planner node plans every
stage and motion, and nothing moves; the plan is the in-process dry run's, on the simulated
cell the fold starts and on a running cell (`ros-cell`, as a real one), whose arm it leaves
where it stood."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from ros_helpers import free_port, requires_ros, start_cell, stop_cell, wait_for_master

pytestmark = requires_ros

SMALL = ["--resolution", "9", "--video-fps", "0"]


def foldbot(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "foldbot.cli", *args], capture_output=True, text=True, timeout=600
    )


def same_plan(a: dict, b: dict) -> None:
    """Two dry runs' plans agree: fold lines, grasps, places, steps and their seconds (the
    keypoints cross ROS as float64, to the last bits)."""
    assert len(a["stages"]) == len(b["stages"]) and len(a["actions"]) == len(b["actions"])
    for s, t in zip(a["stages"], b["stages"], strict=True):
        np.testing.assert_allclose(s["fold_line"], t["fold_line"], atol=1e-9)
    for x, y in zip(a["actions"], b["actions"], strict=True):
        keys = ("label", "feasible", "arm", "together", "layers", "descent_m")
        assert [x.get(k) for k in keys] == [y.get(k) for k in keys]
        np.testing.assert_allclose(x["grasp"], y["grasp"], atol=1e-9)
        np.testing.assert_allclose(x["place"], y["place"], atol=1e-9)
        assert [s["name"] for s in x["steps"]] == [s["name"] for s in y["steps"]]
        np.testing.assert_allclose(
            [s["seconds"] for s in x["steps"]], [s["seconds"] for s in y["steps"]], atol=1e-6
        )
        assert ("pair_seconds" in x) == ("pair_seconds" in y)
        if "pair_seconds" in x:
            assert x["pair_seconds"] == pytest.approx(y["pair_seconds"], abs=1e-6)


def test_a_dry_run_over_ros_plans_what_the_in_process_one_plans(tmp_path):
    # Two arms' quarter: stage 1's corners a pair the planner node plans together, the stack
    # one arm's carry by its edge's middle.
    quarter = ["--dry-run", "--arms", "2", "--recipe", "quarter", *SMALL]
    here = tmp_path / "in_process"
    assert foldbot("fold", *quarter, "--out", str(here)).returncode == 0
    over = tmp_path / "over_ros"
    proc = foldbot("ros-fold", *quarter, "--out", str(over), "--port", str(free_port()))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    said = "dry run over ROS: 2 stage(s), 3 pick-and-place(s) (1 pair(s) by two arms together)"
    assert said in proc.stdout
    plan = json.loads((over / "plan.json").read_text())
    assert plan["cell"] == "sim" and plan["feasible"]
    assert sorted(p.name for p in over.iterdir()) == [
        "overlay_plan1.png",
        "overlay_plan2.png",
        "plan.json",
    ]
    same_plan(plan, json.loads((here / "plan.json").read_text()))


def test_a_crumpled_towels_first_pull_over_ros_is_the_in_process_one(tmp_path):
    # The sim node crumples the towel as `foldbot fold` does; the task node plans the first
    # flattening pull from the heap it sees, through the planner node.
    crumpled = ["--dry-run", "--start", "crumpled", *SMALL]
    here = tmp_path / "in_process"
    assert foldbot("fold", *crumpled, "--out", str(here)).returncode == 0
    over = tmp_path / "over_ros"
    proc = foldbot("ros-fold", *crumpled, "--out", str(over), "--port", str(free_port()))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "dry run over ROS: the crumpled towel seen at coverage" in proc.stdout
    assert "the first pull, pull corner_d, feasible" in proc.stdout
    plan = json.loads((over / "plan.json").read_text())
    assert plan["cell"] == "sim" and plan["feasible"] and plan["start"] == "crumpled"
    assert sorted(p.name for p in over.iterdir()) == ["overlay_plan1.png", "plan.json"]
    local = json.loads((here / "plan.json").read_text())
    assert plan["flatten"]["perceived_coverage"] == pytest.approx(
        local["flatten"]["perceived_coverage"], abs=1e-9
    )
    same_plan(plan, local)


def test_a_dry_run_on_a_running_cell_leaves_its_arm_where_it_stood(tmp_path):
    cell, port = start_cell(*SMALL[:2], "--camera-rate", "2")
    out = tmp_path / "real"
    env = {**os.environ, "ROS_MASTER_URI": f"http://localhost:{port}"}
    try:
        wait_for_master(port)
        before = joints_now(env)
        proc = foldbot(
            "ros-fold", "--cell", "real", "--dry-run", *SMALL, "--out", str(out),
            "--port", str(port),
        )  # fmt: skip
        after = joints_now(env)
    finally:
        log = stop_cell(cell)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:] + log[-3000:]
    plan = json.loads((out / "plan.json").read_text())
    assert plan["cell"] == "real" and plan["feasible"] and len(plan["actions"]) == 2
    assert "dry run over ROS: 1 stage(s), 2 pick-and-place(s)" in proc.stdout
    # The cell's /joint_states: the arm where it stood, the fingers as they were (not opened).
    assert set(before) == set(after) and len(before) >= 8
    np.testing.assert_allclose([after[n] for n in before], list(before.values()), atol=1e-4)


JOINTS_SCRIPT = """
import json
import foldbot
import rospy
from sensor_msgs.msg import JointState

rospy.init_node("dry_run_probe", anonymous=True)
msg = rospy.wait_for_message("/joint_states", JointState, timeout=60)
print(json.dumps(dict(zip(msg.name, msg.position))))
"""


def joints_now(env: dict) -> dict[str, float]:
    """The running cell's /joint_states, every joint by name (its arm's and fingers')."""
    run = subprocess.run(
        [sys.executable, "-c", JOINTS_SCRIPT], env=env, capture_output=True, text=True,
        timeout=120, check=True,
    )  # fmt: skip
    return json.loads(run.stdout.strip().splitlines()[-1])
