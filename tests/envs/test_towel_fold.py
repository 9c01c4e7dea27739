"""TowelFold: Gymnasium's checker on the real environment, the goal from the towel's true
corners, the reward as the fold error's decrease, the recipe's carries folding a small towel,
the same seed giving the same episode, a divergence reported, and bad input refused. Towels of
5 vertices a side (every corner a mesh point the jaws find) keep each episode to seconds."""

import json
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from foldbot.envs import (
    TowelFlattenEnv,
    TowelFoldConfig,
    TowelFoldEnv,
    TowelFoldPairConfig,
    TowelFoldPairEnv,
)
from foldbot.envs.policies import RandomPolicy, RecipePolicy
from foldbot.envs.towel_fold import fold_episode_config
from foldbot.errors import ConfigError, FoldbotError
from foldbot.planning.actions import edge_middle
from foldbot.planning.recipes import carries_stack, folded_as, plan_stage, recipe_stages

SMALL = {"resolution": 5, "image_size": (48, 64)}
SQUARE = {"near_left": (0.3, 0.15), "near_right": (0.3, -0.15), "far_right": (0.6, -0.15),
          "far_left": (0.6, 0.15)}  # fmt: skip


@pytest.fixture
def env():
    environment = TowelFoldEnv(**SMALL)
    yield environment
    environment.close()


def run_recipe(env, seed):
    """The recipe policy's carries on `seed`'s towel: (first info, rewards, last info)."""
    _obs, first = env.reset(seed=seed)
    policy, info, rewards = RecipePolicy(env), first, []
    while (action := policy(info)) is not None:
        _obs, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        if terminated or truncated:
            break
    return first, rewards, info


def test_registered_with_gymnasium():
    made = gym.make("foldbot/TowelFold-v0", resolution=5, recipe="quarter")
    try:
        assert isinstance(made.unwrapped, TowelFoldEnv)
        assert made.unwrapped.config == TowelFoldConfig(resolution=5, recipe="quarter")
    finally:
        made.close()


def test_gymnasium_checker_passes(env):
    check_env(env, skip_render_check=True)


def test_a_flat_towel_starts_far_from_its_goal(env):
    obs, info = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    assert info["recipe"] == "half" and info["seed"] == 1 and info["steps"] == 0
    # towel_loop's towel for seed 1, flat: it covers its own area, and half of it lies a fold
    # away from its goal.
    assert info["coverage"] == pytest.approx(1.0, abs=0.02)
    assert 50.0 < info["fold_error_mm"] < 200.0
    assert info["normalized_performance"] == pytest.approx(0.0, abs=0.01)
    assert not info["is_success"]
    width, height = info["towel_size_m"]
    assert 0.25 <= width <= 0.45 and 0.25 <= height <= 0.45


def test_the_recipes_carries_fold_the_towel_and_the_reward_is_the_errors_decrease(env):
    """The recipe policy's half fold of seed 1's towel, planned from the camera: two corner
    carries, each holding the corner, bring the cloth most of the way to its goal."""
    first, rewards, last = run_recipe(env, seed=1)
    assert len(rewards) == 2 and last["grasp_success"] and last["infeasible"] is None
    assert sum(rewards) == pytest.approx((first["fold_error_mm"] - last["fold_error_mm"]) / 1000)
    assert last["fold_error_mm"] < 0.4 * first["fold_error_mm"]
    assert last["normalized_performance"] > 0.7
    assert last["coverage"] < 0.65  # half of it lies on the other half


def test_the_same_seed_gives_the_same_fold(env):
    one, two = run_recipe(env, seed=3), run_recipe(env, seed=3)
    assert one[1] == two[1] and one[2]["fold_error_mm"] == two[2]["fold_error_mm"]


# A fresh interpreter settles seed 1's flat towel as an episode's own process does (the first
# simulation in its process, so to the bit) and prints each recipe's goal error for it: the
# recipe's fold lines on the settled towel's true corners, composed into every vertex's goal.
GOAL = """
import json, sys
from foldbot.envs.towel_fold import TowelFoldConfig, fold_episode_config
from foldbot.metrics import fold_error_mm, fold_goal
from foldbot.pipeline import build_sim_cell, true_start_keypoints
from foldbot.planning.recipes import recipe_fold_lines
from foldbot.sim.cloth import settle
from foldbot.sim.world import SimWorld

seed, recipes = int(sys.argv[1]), sys.argv[2:]
cfg = fold_episode_config(TowelFoldConfig(resolution=5), seed)
with SimWorld(cfg.sim) as world:
    parts = build_sim_cell(cfg, world)
    try:
        settle(world, parts.cloth)
        flat = parts.oracle.cloth_vertices()
        corners = true_start_keypoints(cfg, parts.mesh, flat)
        out = {}
        for recipe in recipes:
            lines = recipe_fold_lines(recipe, corners)
            goal, _layers = fold_goal(flat, lines, parts.cloth.thickness)
            out[recipe] = {"fold_error_mm": fold_error_mm(flat, goal), "lines": len(lines)}
    finally:
        parts.model_world.close()
print(json.dumps(out))
"""


def test_the_goal_is_the_recipes_and_differs_by_recipe():
    """A quarter fold's goal lies further from the flat towel than a half fold's (two folds),
    and the recipe policy plans two stages for it. Each reset's fold error is the settled flat
    towel's distance to its recipe's goal (recipe_fold_lines on the true corners, fold_goal)."""
    out = subprocess.run(
        [sys.executable, "-c", GOAL, "1", "half", "quarter"],
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    goals = json.loads(out.stdout.strip().splitlines()[-1])
    assert goals["half"]["lines"] == 1 and goals["quarter"]["lines"] == 2
    errors, carries = {}, []
    for recipe in ("half", "quarter"):
        env = TowelFoldEnv(recipe=recipe, **SMALL)
        try:
            _obs, info = env.reset(seed=1)
            errors[recipe] = info["fold_error_mm"]
            if recipe == "quarter":  # its carries, stage by stage, as the policy plans them
                policy = RecipePolicy(env)
                while (action := policy(info)) is not None:
                    carries.append((policy.stage, [a.label for a in policy.last]))
                    _obs, _reward, terminated, truncated, info = env.step(action)
                    assert info.get("grasp_success"), info.get("grasp_reason") or info
                    assert not (terminated or truncated)
        finally:
            env.close()
    # The reset's fold error is the flat towel's distance to the recipe's own goal.
    for recipe in ("half", "quarter"):
        assert errors[recipe] == pytest.approx(goals[recipe]["fold_error_mm"], rel=1e-6)
    assert errors["quarter"] > errors["half"]
    # Quarter is folded as quarter_y: two stages, the first's two corners carried one by one,
    # the second's folded stack carried once, by its edge's middle.
    assert policy.recipe == folded_as("quarter") == "quarter_y"
    assert recipe_stages("quarter_y") == 2 and policy.stage == 2
    assert carries_stack("quarter_y", 1) and not carries_stack("quarter_y", 0)
    assert [stage for stage, _ in carries] == [1, 1, 2]
    assert all(len(labels) == 1 for _, labels in carries)
    # Which corners each stage carries is the recipe's (plan_stage on any square's corners).
    square = {n: np.array([x, y, 0.75]) for n, (x, y) in SQUARE.items()}
    stage_0 = plan_stage("quarter_y", 0, square).actions
    stage_1 = edge_middle(plan_stage("quarter_y", 1, square).actions)
    assert [labels[0] for _, labels in carries] == [a.label for a in stage_0] + [stage_1.label]
    assert info["fold_error_mm"] < 0.5 * errors["quarter"]  # the carries fold toward the goal


def test_a_carry_that_grasps_bare_table_misses_and_the_episode_truncates():
    env = TowelFoldEnv(max_steps=1, **SMALL)
    try:
        env.reset(seed=1)
        # The workspace's near right corner: no towel reaches there.
        corner = np.array([-0.97, -0.97, -0.9, -0.9], np.float32)
        _obs, reward, terminated, truncated, info = env.step(corner)
        assert info["grasp_success"] is False
        assert "no cloth between the jaws" in info["grasp_reason"]
        assert truncated and not terminated
        assert abs(reward) < 0.002  # nothing was carried
        pick, _place = env.action_to_world(corner)
        np.testing.assert_allclose(info["grasp"][:2], pick, atol=1e-6)
    finally:
        env.close()


def test_a_diverged_simulation_is_reported_not_scored():
    env = TowelFoldEnv(fault_diverge_s=0.5, **SMALL)
    try:
        _obs, info = env.reset(seed=1)
        _obs, reward, terminated, _truncated, info = env.step(RecipePolicy(env)(info))
        assert terminated and reward == 0.0 and "injected divergence" in info["diverged"]
        assert info["is_success"] is False
    finally:
        env.close()


def test_the_workspace_reaches_every_corner_of_the_suites_towels(env):
    x0, x1, y0, y1 = env.workspace
    pick, place = env.action_to_world(np.array([-1.0, -1.0, 1.0, 1.0]))
    np.testing.assert_allclose([*pick, *place], [x0, y0, x1, y1])
    # The largest towel (45 cm) at its extreme yaw (15°) and offset (3 cm) about (0.45, 0).
    yaw = np.radians(15.0)
    half = 0.225 * (np.cos(yaw) + np.sin(yaw)) + 0.03
    assert x0 < 0.45 - half and x1 > 0.45 + half and y0 < -half and y1 > half


def test_a_suite_laid_out_elsewhere_moves_the_workspace_and_still_folds(tmp_path):
    """towel_loop with layouts/pedestal.toml's cell as its [layout]: the action's workspace
    moves with the cell's (5 cm out, 6 cm left), and the recipe's carries, planned from the
    camera moved with it, fold seed 1's towel as in the default cell."""
    from pathlib import Path

    from foldbot.bench.suite import SUITES_DIR

    repo = Path(__file__).resolve().parents[2]
    suite = tmp_path / "towel_loop_pedestal.toml"
    layout = (repo / "layouts" / "pedestal.toml").read_text()
    suite.write_text((SUITES_DIR / "towel_loop.toml").read_text() + "\n[layout]\n" + layout)
    moved = TowelFoldEnv(suite=str(suite), **SMALL)
    try:
        default = TowelFoldConfig().workspace
        shift = (0.05, 0.05, 0.06, 0.06)
        assert moved.workspace == pytest.approx(
            [a + d for a, d in zip(default, shift, strict=True)]
        )
        first, rewards, last = run_recipe(moved, seed=1)
        assert len(rewards) == 2 and last["grasp_success"]
        assert last["fold_error_mm"] < 0.4 * first["fold_error_mm"]
    finally:
        moved.close()


def test_the_random_policy_drives_it(env):
    """A seeded uniform draw over the action space, stepped: one carry from its pick, rewarded
    with the fold error's decrease (m)."""
    _obs, first = env.reset(seed=1)
    action = RandomPolicy(env, seed=2)(first)
    assert env.action_space.contains(action)
    np.testing.assert_array_equal(action, RandomPolicy(env, seed=2)(first))  # its own seed's
    obs, reward, terminated, truncated, info = env.step(action)
    assert env.observation_space.contains(obs)
    assert info["steps"] == 1 and info["seed"] == 1
    assert reward == pytest.approx((first["fold_error_mm"] - info["fold_error_mm"]) / 1000)
    assert terminated == info["is_success"] and not truncated  # 1 of its 6 steps
    if info["infeasible"] is None:  # the arm went where the action says
        pick, _place = env.action_to_world(action)
        np.testing.assert_allclose(info["grasp"][:2], pick, atol=1e-6)


def test_the_recipe_policy_drives_only_towelfold():
    flatten = TowelFlattenEnv(**SMALL)
    try:
        with pytest.raises(FoldbotError, match="RecipePolicy drives TowelFold, not"):
            RecipePolicy(flatten)
    finally:
        flatten.close()


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"recipe": "pleat"}, r"recipe must be one of half, .*, got 'pleat'"),
        ({"workspace": (0.8, 0.2, -0.3, 0.3)}, r"workspace must be \(x min, x max, y min, y max\)"),
        ({"workspace": (0.2, 0.8)}, r"workspace must be .* got \(0.2, 0.8\)"),
        ({"suite": "towel_crumpled"}, r"starts its towels crumpled; TowelFold needs"),
        ({"suite": "towel_two_arms"}, r"has 2 arms; TowelFold's carries are one arm's"),
        ({"suite": "tshirt"}, r"starts its tshirts flat; TowelFold needs a towel"),
        ({"max_steps": 0}, r"max_steps must be an integer in \[1, 100\], got 0"),
        ({"goal_coverage": 0.9}, r"goal_coverage.*allowed: suite, resolution"),
    ],
)
def test_bad_configuration_is_refused(fields, message):
    with pytest.raises(ConfigError, match=message):
        TowelFoldEnv(**fields)


def test_the_episode_is_the_suites_towel_with_the_recipe():
    cfg = fold_episode_config(TowelFoldConfig(recipe="thirds", resolution=5), 4)
    assert cfg.recipe == "thirds" and cfg.seed == 4 and cfg.start == "flat"
    assert cfg.towel_size_range == (0.25, 0.45) and cfg.video_fps == 0.0


# --- TowelFoldPair: two arms, two carries a step ------------------------------------------------


@pytest.fixture
def pair_env():
    environment = TowelFoldPairEnv(**SMALL)
    yield environment
    environment.close()


def test_the_pair_is_registered_and_passes_gymnasiums_checker(pair_env):
    made = gym.make("foldbot/TowelFoldPair-v0", resolution=5)
    try:
        assert isinstance(made.unwrapped, TowelFoldPairEnv)
        assert made.unwrapped.config == TowelFoldPairConfig(resolution=5)
        assert made.action_space.shape == (8,)
    finally:
        made.close()
    check_env(pair_env, skip_render_check=True)


def test_two_arms_carry_the_half_folds_corners_at_once(pair_env):
    """The recipe policy's half fold in the two-arm cell: one step, both far corners carried
    together, the cloth most of the way to its goal (one arm's two carries: 0.23 of the start)."""
    first, rewards, last = run_recipe(pair_env, seed=1)
    assert len(rewards) == 1 and last["grasp_success"] and last["infeasible"] is None
    assert len(last["grasp"]) == 6 and len(last["place"]) == 6  # a point per carry
    assert "; " in last["grasp_reason"]  # each arm's grasp, named
    assert last["fold_error_mm"] < 0.3 * first["fold_error_mm"]
    assert rewards[0] == pytest.approx((first["fold_error_mm"] - last["fold_error_mm"]) / 1000)


def test_a_carry_of_no_length_leaves_its_arm_parked(pair_env):
    """The triangle fold's one corner: arm b's carry is none (its pick on its place), so arm a
    carries alone; with neither carrying, nothing moves and the step says why."""
    pair_env.reset(seed=1)
    still = pair_env.world_to_action([np.array([0.45, 0.0]), None], [np.array([0.45, 0.0]), None])
    _obs, reward, terminated, _truncated, info = pair_env.step(still)
    assert "no carry" in info["infeasible"] and info["grasp"] == () and not terminated
    assert reward == pytest.approx(0.0, abs=1e-4)
    env = pair_env.unwrapped
    policy = RecipePolicy(env)
    policy.recipe = "diagonal"  # one corner, planned on the frame seen
    action = policy(info)
    picks, places = env.action_to_world(action)
    np.testing.assert_allclose(picks[1], places[1])  # b: no carry
    _obs, _reward, _terminated, _truncated, info = pair_env.step(action)
    assert info["grasp_success"] and len(info["grasp"]) == 3
    assert info["coverage"] < 0.9  # a triangle laid over the cloth (the goal is the half's)


def test_a_pair_action_is_eight_numbers(pair_env):
    with pytest.raises(ConfigError, match=r"an action is \(a pick x, .*b place y\), each finite"):
        pair_env.action_to_world(np.zeros(4))
    picks, places = pair_env.action_to_world(np.array([-1, -1, 1, 1, 1, 1, -1, -1.0]))
    x0, x1, y0, y1 = pair_env.workspace
    np.testing.assert_allclose(picks, [[x0, y0], [x1, y1]])
    np.testing.assert_allclose(places, [[x1, y1], [x0, y0]])


def test_the_pair_needs_a_two_arm_suite():
    with pytest.raises(ConfigError, match=r"has 1 arm; TowelFoldPair's carries are two arms'"):
        TowelFoldPairEnv(suite="towel_loop")


def test_a_pair_the_arms_cannot_make_is_carried_one_corner_at_a_time(pair_env):
    _obs, info = pair_env.reset(seed=1)
    policy = RecipePolicy(pair_env)
    env = pair_env.unwrapped
    picks, places = env.action_to_world(policy(info))
    assert np.linalg.norm(places[0] - picks[0]) > 0.1 and np.linalg.norm(places[1] - picks[1]) > 0.1
    # Told the pair moved nothing, the policy carries its corners singly, in order.
    for k in range(2):
        one, where = env.action_to_world(
            policy({"infeasible": "the arms would meet"} if k == 0 else {})
        )
        np.testing.assert_allclose(one[1], where[1])  # b: no carry
        np.testing.assert_allclose(one[0], picks[k], atol=1e-6)
        np.testing.assert_allclose(where[0], places[k], atol=1e-6)
    assert policy({}) is None  # the half fold's one stage is done
