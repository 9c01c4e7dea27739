"""Carrying on a cell (foldbot.carry): which arm takes which corner in a two-arm cell, when two
grasps are too close for two grippers, and a pair whose arms would meet either way round."""

import json
import subprocess
import sys

import numpy as np
import pytest
from cloth_states import LINE

from foldbot.carry import MIN_ARM_SEPARATION, arms_apart, assign_arms, nearest_arm
from foldbot.planning.actions import FoldAction

BASES_Y = (0.3, -0.3)  # CellLayout.arm_layouts(2): arm 0 on the left (+y), arm 1 on the right


def corner_action(label, grasp_xy, place_xy):
    return FoldAction(
        grasp=np.array([*grasp_xy, 0.757]),
        place=np.array([*place_xy, 0.761]),
        fold_line=LINE,
        label=label,
    )


def test_each_corner_goes_to_the_arm_on_its_side():
    assert nearest_arm(np.array([0.6, 0.12, 0.76]), BASES_Y) == 0
    assert nearest_arm(np.array([0.6, -0.02, 0.76]), BASES_Y) == 1
    half = (
        corner_action("far_right", (0.6, -0.15), (0.3, -0.15)),
        corner_action("far_left", (0.6, 0.15), (0.3, 0.15)),
    )
    assert assign_arms(lambda p: nearest_arm(p, BASES_Y), half) == [1, 0]


def test_two_corners_on_one_side_still_get_one_arm_each_left_to_left():
    # A towel lying off-centre: both grasps nearer the left arm's base.
    pair = (
        corner_action("far_right", (0.6, 0.02), (0.3, 0.02)),
        corner_action("far_left", (0.6, 0.25), (0.3, 0.25)),
    )
    assert assign_arms(lambda p: nearest_arm(p, BASES_Y), pair) == [1, 0]


def test_corners_too_close_for_two_grippers_are_carried_one_after_the_other():
    apart = (
        corner_action("far_left", (0.6, 0.15), (0.3, 0.15)),
        corner_action("far_right", (0.6, -0.15), (0.3, -0.15)),
    )
    assert arms_apart(apart)
    gap = MIN_ARM_SEPARATION * 0.9
    close_grasps = (
        corner_action("a", (0.6, gap / 2), (0.3, 0.15)),
        corner_action("b", (0.6, -gap / 2), (0.3, -0.15)),
    )
    close_places = (
        corner_action("a", (0.6, 0.15), (0.3, gap / 2)),
        corner_action("b", (0.6, -0.15), (0.3, -gap / 2)),
    )
    assert not arms_apart(close_grasps)
    assert not arms_apart(close_places)


ARMS_MEET = """
import contextlib, json
import numpy as np
from foldbot.garments.towel import TowelSpec
from foldbot.carry import carry_pair
from foldbot.perception.estimator import VisionEstimator
from foldbot.pipeline import EpisodeConfig, SimCell, build_sim_cell, loop_config
from foldbot.planning.actions import FoldAction
from foldbot.sim.cloth import settle
from foldbot.sim.world import SimWorld

cfg = EpisodeConfig(seed=0, towel=TowelSpec(0.24, 0.24, 8), video_fps=0.0, arms=2)
lines, aimed = [], []
with SimWorld(cfg.sim) as world, contextlib.ExitStack() as stack:
    parts = build_sim_cell(cfg, world)
    stack.callback(parts.model_world.close)
    settle(world, parts.cloth)
    cell = SimCell(
        world, parts.robot, parts.executor, parts.camera, VisionEstimator(), cfg.motion,
        more_executors=parts.more_executors,
    )
    cell.park()
    state, obs = cell.observe()
    z = float(state.keypoints["near_right"][0][2])
    line = (0.36, -0.04, 1.0, 0.0)
    planned = tuple(
        FoldAction(np.array([x, -0.08, z]), np.array([x, 0.0, z]), line, label=f"x{x:.2f}")
        for x in (0.36, 0.50)
    )

    def aim(i, attempt, missed, seen, frame, previous):
        aimed.append([i, attempt, missed, seen is state, frame is obs])
        return previous

    before = parts.oracle.cloth_vertices().copy()
    t0 = cell.sim_time
    retries = loop_config(cfg, parts.cloth.thickness).retries
    pair = carry_pair(cell, planned, state, obs, aim, retries, lines.append, "the points")
    moved = float(np.abs(parts.oracle.cloth_vertices() - before).max())
print(json.dumps({
    "meet": pair.arms_would_meet, "attempts": pair.attempts, "outcomes": pair.outcomes,
    "carried": pair.carried, "same_state": pair.state is state, "moved_m": moved,
    "sim_s": cell.sim_time - t0, "aimed": aimed, "log": lines,
}))
"""


@pytest.mark.slow
def test_a_pair_whose_arms_would_meet_either_way_round_moves_nothing():
    """carry_pair tries the arms one way and the other; where both would meet it stops before
    anything moves and says why, for the caller to go on one arm at a time."""
    proc = subprocess.run(
        [sys.executable, "-c", ARMS_MEET], capture_output=True, text=True, timeout=900
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["meet"] is not None and "would" in report["meet"]
    assert report["carried"] is False and report["attempts"] == [] and report["outcomes"] == []
    # Both actions aimed once, at the frame it was given; nothing moved, the cloth included.
    assert report["aimed"] == [[0, 0, False, True, True], [1, 0, False, True, True]]
    assert report["same_state"] is True
    assert report["moved_m"] == 0.0 and report["sim_s"] == 0.0
    assert [line.split(" (")[0] for line in report["log"]] == [
        "  the arms would meet",
        "  the arms would meet",
    ]
    assert report["log"][0].endswith("trying them the other way round")
    assert report["log"][1].endswith("carrying the points one arm at a time")
