"""TowelSpread: the two-arm cell's spreads from two chosen grasp points, as a Gymnasium
environment: Gymnasium's checker, a spread that lifts and lays the towel, one the arms cannot
make reported without moving, and the suite it needs. Small towels keep episodes to seconds."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from foldbot.envs import TowelSpreadConfig, TowelSpreadEnv
from foldbot.envs.policies import SpreadPolicy
from foldbot.errors import ConfigError, FoldbotError


def test_registered_and_checked():
    made = gym.make("foldbot/TowelSpread-v0", resolution=6, image_size=(48, 64))
    try:
        env = made.unwrapped
        assert isinstance(env, TowelSpreadEnv) and env.ARMS == 2
        assert env.config.suite == "towel_crumpled_two_arms"
        check_env(env, skip_render_check=True)
    finally:
        made.close()


def test_a_spread_lifts_and_lays_the_towel():
    """Seed 0 at 8 vertices a side: the surest pair of corners, spread and laid, covers more."""
    env = TowelSpreadEnv(resolution=8, image_size=(48, 64))
    try:
        _obs, info = env.reset(seed=0)
        policy = SpreadPolicy(env)
        action = policy(info)
        _obs, reward, _term, _trunc, after = env.step(action)
        assert after["infeasible"] is None and after["grasp_success"] is True
        assert "between the jaws" in after["grasp_reason"]
        assert reward == pytest.approx(after["coverage"] - info["coverage"])
        # Both arms closed at the action's two points, the +y arm's first.
        a, b = env.action_to_world(action)
        grasps = np.asarray(after["grasp"]).reshape(2, 3)
        np.testing.assert_allclose(
            sorted(map(tuple, grasps[:, :2])), sorted(map(tuple, (a, b))), atol=1e-6
        )
        assert grasps[0, 1] >= grasps[1, 1]
        # It was laid across the workspace: both let go at the same x, a side apart.
        places = np.asarray(after["place"]).reshape(2, 3)
        assert places[0, 0] == pytest.approx(places[1, 0])
        assert places[0, 1] > places[1, 1]
    finally:
        env.close()


def test_a_spread_the_arms_cannot_make_moves_nothing():
    """Both grasps on one point: the two grippers would meet, so the step says why and the
    cloth lies as it was."""
    env = TowelSpreadEnv(resolution=5, image_size=(48, 64))
    try:
        obs, info = env.reset(seed=0)
        same = np.array([0.0, 0.0, 0.0, 0.0], np.float32)
        after, reward, terminated, truncated, step = env.step(same)
        assert step["infeasible"] and "cannot make this spread" in step["infeasible"]
        assert step["grasp_success"] is None and reward == 0.0
        assert step["coverage"] == info["coverage"] and step["steps"] == 1
        np.testing.assert_array_equal(after["rgb"], obs["rgb"])
        assert not terminated and not truncated
    finally:
        env.close()


def test_the_suite_must_have_two_arms_and_the_policies_their_env():
    with pytest.raises(ConfigError, match=r"has 1 arm; TowelSpread's spread is two arms'"):
        TowelSpreadEnv(suite="towel_crumpled")
    assert TowelSpreadConfig().suite == "towel_crumpled_two_arms"
    spread = TowelSpreadEnv(resolution=5)
    try:  # its errors name it, not the one-arm environment it extends
        with pytest.raises(ConfigError, match=r"^TowelSpreadEnv\.reset takes no options"):
            spread.reset(seed=0, options={"x": 1})
    finally:
        spread.close()
    with pytest.raises(ConfigError, match="allowed: suite, resolution"):
        TowelSpreadEnv(colour="red")
    from foldbot.envs import TowelFlattenEnv

    one_arm = TowelFlattenEnv(resolution=5)
    try:
        with pytest.raises(FoldbotError, match="SpreadPolicy drives TowelSpread, not"):
            SpreadPolicy(one_arm)
    finally:
        one_arm.close()
