"""The planner node's requests, answered without topics (MotionPlanner is the node's core)."""

import json
import math

import numpy as np
import pytest
from ros_helpers import requires_ros

from foldbot.errors import FoldbotError

pytestmark = requires_ros

UV = {  # a child's pants in its own frame (u right, v up from the leg ends), m
    "left_waist": (-0.12, 0.40),
    "right_waist": (0.12, 0.40),
    "left_leg_outer": (-0.13, 0.0),
    "left_leg_inner": (-0.03, 0.0),
    "right_leg_outer": (0.13, 0.0),
    "right_leg_inner": (0.03, 0.0),
    "crotch": (0.0, 0.24),
}


def pants_keypoints(yaw: float = math.pi + 0.1) -> dict[str, list[float]]:
    up = np.array([math.cos(yaw + math.pi / 2), math.sin(yaw + math.pi / 2)])
    right = np.array([up[1], -up[0]])
    return {
        n: [*(np.array([0.45, 0.0]) + u * right + v * up).tolist(), 0.752]
        for n, (u, v) in UV.items()
    }


@pytest.fixture(scope="module")
def planner():
    from foldbot.ros.planner_node import MotionPlanner

    p = MotionPlanner("--garment pants --out /tmp/unused --park out_of_view")
    yield p
    p.world.close()


def test_garment_plan_is_the_library_plan(planner):
    from foldbot.planning.garment_recipes import GarmentPlan, plan_garment

    kp = pants_keypoints()
    req = {"kind": "garment", "recipe": "leg_over_leg", "keypoints": kp}
    reply = planner.handle({**req, "place_lift": 0.004, "thickness": 0.01})
    got = GarmentPlan.from_dict(json.loads(json.dumps(reply["plan"])))
    want = plan_garment(
        "leg_over_leg", {k: np.array(v) for k, v in kp.items()}, 0.004, thickness=0.01
    )
    assert got.fold_lines == want.fold_lines
    assert [s.from_tip for s in got.stages] == [False, True]
    assert [[a.as_dict() for a in s.actions] for s in got.stages] == [
        [a.as_dict() for a in s.actions] for s in want.stages
    ]


def test_garment_plan_names_missing_keypoints(planner):
    kp = pants_keypoints()
    del kp["crotch"]
    req = {"kind": "garment", "recipe": "leg_over_leg", "keypoints": kp}
    with pytest.raises(FoldbotError, match="crotch"):
        planner.handle({**req, "place_lift": 0.004, "thickness": 0.01})


def test_park_goes_where_the_episode_parks(planner):
    home = planner.robot.home_q.tolist()
    traj = planner.handle({"kind": "park", "q": home})["trajectory"]
    assert np.allclose(traj["positions"][-1], planner.robot.out_of_view_q, atol=1e-6)
    assert planner.handle({"kind": "park", "q": planner.robot.out_of_view_q.tolist()}) == {
        "trajectory": None
    }


def test_unknown_request_kind_lists_the_allowed_ones(planner):
    with pytest.raises(FoldbotError, match="allowed: stage, garment, action"):
        planner.handle({"kind": "dance", "q": planner.robot.home_q.tolist()})
