"""A slip seen through a real arm's drivers: the task node drives the sim node's cell through
FollowJointTrajectory and GripperCommand (`--arm-interface actions`), where no report of the
cell's own says that the cloth went; the gripper's fingers on /joint_states do, closing on
after they had stalled on the cloth, as a real gripper's do when what it held slips out."""

import json
import subprocess
import sys

import numpy as np
import pytest
from ros_helpers import free_port, requires_ros

from foldbot.sim.robots import robot_class

pytestmark = [requires_ros, pytest.mark.slow]


def test_a_slip_is_seen_on_the_fingers_and_recovered_through_the_drivers(tmp_path):
    """`ros-fold --arm-interface actions --fault-slip 0.3`: the first carry lets its corner go
    a third of the way along; the task node sees the fingers close on in /joint_states, takes
    it for a lost hold in that step (the chain's later steps moved empty jaws), lets go, lays
    the corner back and plans the stage again, as over topics and in process (5.9 mm here,
    5.9 over topics, 5.7 in process)."""
    from rosbags.highlevel import AnyReader

    out, bag = tmp_path / "episode", tmp_path / "run.bag"
    proc = subprocess.run(
        [sys.executable, "-m", "foldbot.cli", "ros-fold", "--arm-interface", "actions",
         "--recipe", "diagonal", "--width", "0.24", "--height", "0.24", "--resolution", "10",
         "--fault-slip", "0.3", "--video-fps", "0", "--camera-rate", "2", "--out", str(out),
         "--port", str(free_port()), "--record", str(bag), "--finger-travel", "0.003",
         "--gripper-effort", "40"],
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    result = json.loads((out / "result.json").read_text())
    assert result["faults"] == {"grasp_offset_m": 0.0, "slip_fraction": 0.3, "slipped": True}
    assert result["gripper_effort_n"] == 40.0  # the goals' max_effort (the model's own force)
    fingers = list(robot_class("ur5").FINGER_JOINT_NAMES)  # the robot model's, by default
    assert result["slip_watch"] == {
        "finger_joints": [fingers],
        "finger_travel": 0.003,
        "finger_travel_from": "given",
    }
    first, again = result["actions"]
    (slipped,) = first["attempts"]
    assert slipped["slipped"] is True and slipped["grasp_success"] is False
    # The task node's own word, from /joint_states: not the sim node's report (it has none
    # over the drivers' actions).
    reason = slipped["grasp_reason"]
    assert reason.startswith("the cloth slipped from the jaws in the carry (on /joint_states")
    assert slipped["laid_back"]["grasp_success"] is True and first["plan_again"] is True
    assert again["label"] == first["label"] and again["grasp_success"] is True
    assert result["success"] is True
    # The fingers as the bag holds them: stopped on the cloth (its thickness apart) while the
    # jaws held it, then closed on it, having let go of nothing.
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == "/joint_states"]
        rows = []
        for c, _t, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, c.msgtype)
            rows.append([m.position[list(m.name).index(n)] for n in fingers])
    gaps = np.array(rows).sum(axis=1)  # the finger joints' sum: the gap less the closed one
    # Closing on the cloth the fingers come down a few mm per sample and stop at its thickness
    # (8.9 mm here, the samples after a close); the slip takes them from there to closed in
    # one sample, once, with no gripper goal.
    jumps = np.flatnonzero((gaps[:-1] > 0.003) & (gaps[1:] < 0.001))
    assert len(jumps) == 1, np.round(gaps * 1000, 2)
    k = jumps[0]
    assert np.allclose(gaps[k - 10 : k + 1], gaps[k]), np.round(gaps[k - 10 : k + 2] * 1000, 2)
