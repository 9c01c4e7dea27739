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
    del kp["left_leg_inner"]
    req = {"kind": "garment", "recipe": "leg_over_leg", "keypoints": kp}
    with pytest.raises(FoldbotError, match="left_leg_inner"):
        planner.handle({**req, "place_lift": 0.004, "thickness": 0.01})


def test_park_goes_where_the_episode_parks(planner):
    home = planner.robot.home_q.tolist()
    traj = planner.handle({"kind": "park", "q": home})["trajectory"]
    assert np.allclose(traj["positions"][-1], planner.robot.out_of_view_q, atol=1e-6)
    assert planner.handle({"kind": "park", "q": planner.robot.out_of_view_q.tolist()}) == {
        "trajectory": None
    }


def test_a_slowed_episode_is_planned_slower(planner):
    # ros-fold --speed-scale reaches the planner node through the fold options it parses:
    # every trajectory it times takes 1/s as long (here the park; a step's "time" alike).
    from foldbot.ros.planner_node import MotionPlanner

    slow = MotionPlanner("--garment pants --out /tmp/unused --park out_of_view --speed-scale 0.5")
    try:
        home = planner.robot.home_q.tolist()
        full = planner.handle({"kind": "park", "q": home})["trajectory"]
        half = slow.handle({"kind": "park", "q": home})["trajectory"]
        assert half["times"][-1] == pytest.approx(2 * full["times"][-1], rel=0.02)
        assert np.allclose(half["positions"][-1], full["positions"][-1], atol=1e-9)
    finally:
        slow.world.close()


def test_unknown_request_kind_lists_the_allowed_ones(planner):
    with pytest.raises(FoldbotError, match="allowed: stage, garment, action"):
        planner.handle({"kind": "dance", "q": planner.robot.home_q.tolist()})


# --- a two-arm cell -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def two_arm_planner():
    from foldbot.ros.planner_node import MotionPlanner

    p = MotionPlanner("--arms 2 --out /tmp/unused")
    yield p
    p.world.close()


def _action(grasp_xy, place_xy, z=0.752):
    return {
        "label": "corner",
        "layers": 1,
        "grasp": [*grasp_xy, z],
        "place": [*place_xy, z],
        "fold_line": [0.45, -0.2, 0.0, 0.4],
    }


def _homes(planner):
    return [r.home_q.tolist() for r in planner.robots]


def test_two_arms_are_named_left_and_right(two_arm_planner):
    names = two_arm_planner.joint_names
    assert [n[0] for n in names] == ["left_shoulder_pan_joint", "right_shoulder_pan_joint"]
    assert len(names[0]) == len(names[1]) == 6


def test_a_pair_is_planned_together_from_each_arms_joints(two_arm_planner):
    p = two_arm_planner
    qs = _homes(p)
    pairs = [
        {"arm": 0, "action": _action((0.33, 0.12), (0.57, 0.12))},
        {"arm": 1, "action": _action((0.33, -0.12), (0.57, -0.12))},
    ]
    steps = p.handle({"kind": "together", "pairs": pairs, "qs": qs})["steps"]
    assert len(steps) == 2 and len(steps[0]) == len(steps[1]) > 4
    for arm, arm_steps in enumerate(steps):
        np.testing.assert_allclose(arm_steps[0]["path"][0], qs[arm])
        grasp_step = next(s for s in arm_steps if s["gripper"] == "close")
        # The jaws close over the arm's own grasp point (FK on the planner's own model).
        tcp = p.robots[arm].fk_tcp(np.array(grasp_step["path"][-1]))[0]
        assert np.linalg.norm(tcp[:2] - pairs[arm]["action"]["grasp"][:2]) < 0.005


def test_a_pair_that_would_meet_is_refused(two_arm_planner):
    from foldbot.errors import ArmsWouldCollideError

    p = two_arm_planner
    # Both grippers to (nearly) the same point.
    pairs = [
        {"arm": 0, "action": _action((0.45, 0.01), (0.55, 0.01))},
        {"arm": 1, "action": _action((0.45, -0.01), (0.55, -0.01))},
    ]
    with pytest.raises(ArmsWouldCollideError, match="would"):
        p.handle({"kind": "together", "pairs": pairs, "qs": _homes(p)})


def test_one_arms_action_keeps_clear_of_the_other_where_it_stands(two_arm_planner):
    from foldbot.errors import UnreachableTargetError

    p = two_arm_planner
    qs = _homes(p)
    # The right arm reaches across, right under the left arm's parked gripper.
    under_left = p.robots[0].fk_tcp(np.array(qs[0]))[0][:2]
    req = {"kind": "action", "arm": 1, "qs": qs}
    with pytest.raises(UnreachableTargetError, match="arm 1: segment"):
        p.handle({**req, "action": _action(under_left, (0.55, -0.1))})
    # On its own side it plans.
    assert p.handle({**req, "action": _action((0.4, -0.15), (0.55, -0.15))})["steps"]


def test_arms_timed_together_share_one_clock(two_arm_planner):
    p = two_arm_planner
    qs = _homes(p)
    steps = []
    for arm, dz in ((0, -0.05), (1, -0.2)):  # the right arm goes four times as far
        start = p.robots[arm].fk_tcp(np.array(qs[arm]))[0]
        path = p.handle({"kind": "lift", "arm": arm, "qs": qs, "height": dz})["steps"][0]
        assert np.allclose(path["points"][0], start)
        steps.append({"arm": arm, **path})
    short = p.handle({"kind": "time", **steps[0]})["trajectory"]
    traj = p.handle({"kind": "time_together", "name": "down", "steps": steps})["trajectory"]
    assert traj["joint_names"] == p.joint_names[0] + p.joint_names[1]
    pos, vel = np.array(traj["positions"]), np.array(traj["velocities"])
    n = len(short["times"])
    assert len(traj["times"]) > n
    # The left arm's samples are its own trajectory's, then held at rest at its end.
    np.testing.assert_allclose(pos[:n, :6], short["positions"])
    np.testing.assert_allclose(pos[n:, :6], np.repeat(pos[n - 1 : n, :6], len(pos) - n, axis=0))
    assert not vel[n:, :6].any()
    with pytest.raises(FoldbotError, match="distinct arms in order"):
        p.handle({"kind": "time_together", "steps": steps[::-1]})


def test_park_moves_only_the_arms_away_from_their_park(two_arm_planner):
    p = two_arm_planner
    qs = _homes(p)
    assert p.handle({"kind": "park", "qs": qs}) == {"trajectory": None}  # parks at home
    moved = [qs[0], (np.array(qs[1]) + 0.1).tolist()]
    traj = p.handle({"kind": "park", "qs": moved})["trajectory"]
    assert traj["joint_names"] == p.joint_names[1]
    np.testing.assert_allclose(traj["positions"][-1], qs[1], atol=1e-6)
    with pytest.raises(FoldbotError, match="qs must give 2 arms"):
        p.handle({"kind": "park", "qs": qs[:1]})


def _spread_part(y: float, label: str) -> dict:
    """One arm's part of a spread (planning.spread), as the task node sends it."""
    from foldbot.planning.spread import SpreadAction, action_as_dict

    return action_as_dict(
        SpreadAction(
            grasp=np.array([0.50, y + 0.03, 0.77]),
            hold=np.array([0.60, y, 1.15]),
            touch=np.array([0.60, y, 1.055]),
            release=np.array([0.30, y, 0.77]),
            label=label,
        )
    )


def test_a_spread_is_planned_together_and_hangs_still(two_arm_planner):
    # A crumpled towel in the two-arm cell over ROS: both arms' parts of a spread planned
    # together, the hang timed as the in-process executor holds it (SpreadAction.hang_time).
    p = two_arm_planner
    qs = _homes(p)
    pairs = [
        {"arm": 0, "action": _spread_part(0.15, "spread far_left")},
        {"arm": 1, "action": _spread_part(-0.15, "spread far_right")},
    ]
    steps = p.handle({"kind": "together", "pairs": pairs, "qs": qs})["steps"]
    names = ["approach", "come_down", "descend", "lift", "spread", "lower", "lay", "retreat"]
    for arm_steps in steps:
        assert [s["name"] for s in arm_steps] == names
        assert [s["gripper"] for s in arm_steps][2] == "close"
        assert [s["gripper"] for s in arm_steps][6] == "open"
        assert [s["dwell"] for s in arm_steps] == [0, 0, 0, 0, 1.0, 0, 0, 0]
    spread = [{"arm": arm, **arm_steps[4]} for arm, arm_steps in enumerate(steps)]
    still = p.handle({"kind": "time", **spread[0], "dwell": 0.0})["trajectory"]
    hung = p.handle({"kind": "time", **spread[0]})["trajectory"]
    dt = p.world.time_step
    n, extra = len(still["times"]), round(1.0 / dt)
    assert len(hung["times"]) == n + extra
    pos, vel = np.array(hung["positions"]), np.array(hung["velocities"])
    np.testing.assert_allclose(pos[:n], still["positions"])
    np.testing.assert_allclose(pos[n:], np.repeat(pos[n - 1 : n], extra, axis=0))
    assert not vel[n:].any()
    both = p.handle({"kind": "time_together", "name": "spread", "steps": spread})["trajectory"]
    assert len(both["times"]) >= n + extra
    with pytest.raises(FoldbotError, match="dwell must be a number of seconds"):
        p.handle({"kind": "time", **spread[0], "dwell": "long"})


def test_a_bad_spread_part_is_named(two_arm_planner):
    p = two_arm_planner
    bad = {k: v for k, v in _spread_part(0.15, "spread far_left").items() if k != "hold"}
    pairs = [{"arm": 0, "action": bad}, {"arm": 1, "action": _spread_part(-0.15, "x")}]
    with pytest.raises(FoldbotError, match="spread action's 'hold' must be 3 finite numbers"):
        p.handle({"kind": "together", "pairs": pairs, "qs": _homes(p)})


def test_the_layouts_obstacles_keep_the_planner_nodes_motions_clear(tmp_path):
    from foldbot.errors import ConfigError, UnreachableTargetError
    from foldbot.ros.planner_node import MotionPlanner

    # A lamp hanging 31–41 cm over the table's far left: a grasp under it is refused by name.
    layout = tmp_path / "lamp.toml"
    lamp = '[[obstacles]]\nname = "lamp"\ncenter_xyz = [0.66, 0.12, 1.11]\n'
    layout.write_text(lamp + "size_xyz = [0.12, 0.12, 0.10]\n")
    p = MotionPlanner(f"--out /tmp/unused --layout {layout}")
    try:
        req = {"kind": "action", "arm": 0, "qs": _homes(p)}
        with pytest.raises(UnreachableTargetError, match=r"obstacle 'lamp' \(at least 20 mm"):
            p.handle({**req, "action": _action((0.66, 0.12), (0.4, 0.12))})
        assert p.handle({**req, "action": _action((0.45, -0.15), (0.3, -0.15))})["steps"]
    finally:
        p.world.close()
    # Where the arm rests, the node refuses to start.
    layout.write_text(
        lamp.replace("0.66, 0.12, 1.11", "0.55, 0.10, 1.10") + "size_xyz = [0.3, 0.3, 0.08]\n"
    )
    with pytest.raises(ConfigError, match=r"the arm's home posture meets an obstacle"):
        MotionPlanner(f"--out /tmp/unused --layout {layout}")
