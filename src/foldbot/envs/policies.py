"""Baseline policies for TowelFlatten: what a learned policy is measured against.

- `RandomPolicy`: a uniform draw over the action space (seeded).
- `PullPolicy`: the flattening pulls `foldbot fold --start crumpled` runs with one arm
  (planning.flatten.plan_pulls), as a policy: it sees the camera's full frame
  (`env.unwrapped.observation`) and the towel's nominal size (`info["towel_size_m"]`), nothing
  of the simulator's state.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from foldbot.envs.towel_flatten import TowelFlattenEnv
from foldbot.perception.estimator import VisionEstimator
from foldbot.planning.flatten import cloth_surface, plan_pulls


class RandomPolicy:
    """Pick and place anywhere in the workspace, uniformly, from its own seeded generator."""

    def __init__(self, env: TowelFlattenEnv, seed: int = 0) -> None:
        self.space = env.unwrapped.action_space
        self.rng = np.random.default_rng(seed)  # its own: the env's space is shared

    def reset(self) -> None:
        """Nothing carries over between episodes."""

    def __call__(self, info: dict[str, Any]) -> np.ndarray:
        draw = self.rng.uniform(self.space.low, self.space.high)
        return draw.astype(self.space.dtype)


class PullPolicy:
    """The one-arm flattening pulls: fit the towel's rectangle to the cloth seen, pull the edge
    point nearest its worst-covered corner or edge midpoint out past it. After the first pull
    the rectangle keeps its yaw (FlattenConfig.keep_yaw), and a grasp that closed on no cloth
    is tried again `retry_step` further inside, as in the closed loop."""

    def __init__(self, env: TowelFlattenEnv) -> None:
        self.env = env.unwrapped
        self.cfg = self.env.flatten
        self.estimator = VisionEstimator()
        self.reset()

    def reset(self) -> None:
        """A new towel: fit its rectangle afresh."""
        self.yaw: float | None = None
        self.last: tuple[np.ndarray, np.ndarray] | None = None
        self.misses = 0

    def __call__(self, info: dict[str, Any]) -> np.ndarray | None:
        """The next action, or None when no point of the rectangle is short by `min_pull`."""
        obs = self.env.observation
        width, height = info["towel_size_m"]
        state = self.estimator.estimate(obs)
        fit, pulls = plan_pulls(
            state, width, height, self.cfg, cloth_surface(obs, state, self.cfg), self.yaw
        )
        if self.cfg.keep_yaw:
            self.yaw = fit.yaw
        if not pulls:
            return None
        pick, place = pulls[0].action.grasp[:2], pulls[0].action.place[:2]
        missed = info.get("grasp_success") is False
        same = self.last is not None and np.linalg.norm(pick - self.last[0]) < self.cfg.raster
        self.misses = self.misses + 1 if missed and same else 0
        self.last = (pick, place)
        inward = pick - place
        inward = inward / max(float(np.linalg.norm(inward)), 1e-9)
        step = min(self.misses * self.cfg.retry_step, self.cfg.max_inset)
        return self.env.world_to_action(pick + inward * step, place)
