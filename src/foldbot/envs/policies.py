"""Baseline policies for TowelFlatten and TowelSpread: what a learned policy is measured against.

- `RandomPolicy`: a uniform draw over the action space (seeded), for either environment.
- `PullPolicy`: the flattening pulls `foldbot fold --start crumpled` runs with one arm
  (planning.flatten.plan_pulls), as a policy: it sees the camera's full frame
  (`env.unwrapped.observation`) and the towel's nominal size (`info["towel_size_m"]`), nothing
  of the simulator's state.
- `SpreadPolicy`: for TowelSpread, the two-arm flattening spreads' choice of grasps: the pair of
  adjacent perceived corners the estimator is surest of, each taken just inside its corner.
- `RecipePolicy`: for TowelFold, the recipe's one-arm carries planned stage by stage on the
  corners the camera sees (planning.recipes.plan_stage), each grasp found again on the frame
  before it, a missed grasp tried once more: the closed loop's plan without its verification,
  relays and finishing carries.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from foldbot.carry import arms_apart
from foldbot.envs.towel_flatten import TowelFlattenEnv, TowelSpreadEnv
from foldbot.envs.towel_fold import TowelFoldEnv, TowelFoldPairEnv
from foldbot.envs.towel_task import TowelTaskEnv
from foldbot.errors import ConfigError, FoldbotError
from foldbot.grasp_points import regrasp_point
from foldbot.loop import LoopConfig
from foldbot.perception.fallback import vision_estimator
from foldbot.planning.actions import FoldAction, edge_middle
from foldbot.planning.flatten import cloth_surface, plan_pulls
from foldbot.planning.recipes import carries_stack, folded_as, plan_stage, recipe_stages
from foldbot.planning.spread import corner_pairs, plan_spread


class RandomPolicy:
    """Pick and place anywhere in the workspace, uniformly, from its own seeded generator."""

    def __init__(self, env: TowelTaskEnv, seed: int = 0) -> None:
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
        self.estimator = vision_estimator("towel", self.env.layout.obstacles)
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


class SpreadPolicy:
    """The two-arm flattening spreads (flatten.run_spreads) as a policy for TowelSpread: of the
    four pairs of adjacent perceived corners, the one the estimator is surest of (the edge the
    last spread laid down ranked late), palm-clear pairs first, each grasped where the spreads
    grasp it (planning.spread.plan_spread). Where the environment could not make the last
    spread (nothing moved), the next pair on the same frame. The closed loop also tries lower
    hang margins and tilted tools before giving a pair up; the environment's spread tries the
    margins itself."""

    def __init__(self, env: TowelSpreadEnv) -> None:
        self.env = env.unwrapped
        if not isinstance(self.env, TowelSpreadEnv):
            raise FoldbotError(f"SpreadPolicy drives TowelSpread, not {type(self.env).__name__}")
        self.estimator = vision_estimator("towel", self.env.layout.obstacles)
        self.reset()

    def reset(self) -> None:
        """A new towel: nothing laid, nothing tried."""
        self.laid: np.ndarray | None = None
        self.tried: set[tuple[str, str]] = set()

    def __call__(self, info: dict[str, Any]) -> np.ndarray | None:
        """The next spread's two grasp points as an action, or None when no corners are seen."""
        if info.get("infeasible") is None:
            self.tried = set()  # the cloth moved (or this is the first frame): every pair again
            if info.get("grasp_success") and info.get("place") is not None:
                self.laid = np.asarray(info["place"], dtype=float).reshape(2, 3)
        obs = self.env.observation
        state = self.estimator.estimate(obs)
        if not state.detected:
            return None
        surface = cloth_surface(obs, state, self.env.flatten)
        size = info["towel_size_m"]
        plans = []
        try:
            pairs = corner_pairs(state, self.laid)
        except (FoldbotError, KeyError):  # fewer than four corners seen
            return None
        for pair in pairs:
            if pair in self.tried:
                continue
            plan = plan_spread(state, size, self.env.spread, self.env.flatten, surface, pair=pair)
            plans.append((not plan.palm_clear, len(plans), pair, plan))
        if not plans:
            return None
        _, _, pair, plan = min(plans)
        self.tried.add(pair)
        a, b = (act.grasp[:2] for act in plan.actions)
        return self.env.world_to_action(a, b)


class RecipePolicy:
    """The recipe's carries for TowelFold, planned from what the camera sees: at each stage's
    start, plan_stage on the perceived corners (in the order the cells fold the recipe,
    folded_as), a folded stack carried by its edge's middle as the one-arm loop carries it;
    before each carry its corner is found again on the frame just seen (regrasp_point, the
    loop's radii), and a carry whose grasp closed on nothing is tried once more, found again.
    For TowelFoldPair a stage's two corners go as one pair of carries (a stack's too, as the
    two-arm loop carries them), a single corner alone, and one at a time where the corners or
    their places lie too close for two grippers (carry.arms_apart) or the arms could not make
    the pair. No verification, relays or finishing
    carries: what the closed loop adds is measured against this."""

    def __init__(self, env: TowelFoldEnv) -> None:
        self.env = env.unwrapped
        if not isinstance(self.env, TowelFoldEnv):
            raise FoldbotError(f"RecipePolicy drives TowelFold, not {type(self.env).__name__}")
        self.pairs = isinstance(self.env, TowelFoldPairEnv)
        self.recipe = folded_as(self.env.config.recipe)
        self.loop = LoopConfig()
        self.estimator = vision_estimator("towel", self.env.layout.obstacles)
        self.reset()

    def reset(self) -> None:
        """A new towel: the recipe from its first stage."""
        self.stage = 0
        self.queue: list[list[FoldAction]] = []
        self.last: list[FoldAction] | None = None
        self.retried = False

    def _plan_stage(self, corners: dict) -> list[list[FoldAction]]:
        actions = list(plan_stage(self.recipe, self.stage, corners).actions)
        stack = carries_stack(self.recipe, self.stage)
        self.stage += 1
        if self.pairs and (len(actions) < 2 or arms_apart(tuple(actions))):
            return [actions]  # both corners at once (a triangle fold's one alone)
        if stack and len(actions) == 2:
            return [[edge_middle(actions)]]
        return [[a] for a in actions]

    def _found_again(self, state, action: FoldAction) -> FoldAction:
        """`action` with its grasp on the corner seen now (the planned grasp where none is)."""
        grasp = None
        if not action.label.startswith("middle_"):
            grasp = regrasp_point(
                state,
                action.label,
                action.grasp,
                self.loop.regrasp_radius,
                self.loop.regrasp_label_radius,
                line=action.fold_line,
            )
        grasp = action.grasp if grasp is None else grasp
        return dataclasses.replace(action, grasp=np.asarray(grasp, dtype=float))

    def __call__(self, info: dict[str, Any]) -> np.ndarray | None:
        """The next carry (or pair), or None when the recipe is done or no corners are seen."""
        state = self.estimator.estimate(self.env.observation)
        if not state.detected:
            return None
        if info.get("infeasible") and self.last is not None and len(self.last) == 2:
            self.queue[:0] = [[self.last[0]], [self.last[1]]]  # the arms cannot: one at a time
            self.last = None
        missed = info.get("grasp_success") is False and self.last is not None
        if missed and not self.retried:
            carries, self.retried = self.last, True
        else:
            self.retried = False
            if not self.queue:
                if self.stage >= recipe_stages(self.recipe):
                    return None
                corners = {name: xyz for name, (xyz, _conf) in state.keypoints.items()}
                try:
                    self.queue = self._plan_stage(corners)
                except ConfigError:  # fewer than four corners, or a degenerate quad
                    return None
            carries = self.queue.pop(0)
        self.last = [self._found_again(state, a) for a in carries]
        if not self.pairs:
            (action,) = self.last
            return self.env.world_to_action(action.grasp[:2], action.place[:2])
        picks = [a.grasp[:2] for a in self.last] + [None] * (2 - len(self.last))
        places = [a.place[:2] for a in self.last] + [None] * (2 - len(self.last))
        return self.env.world_to_action(picks, places)
