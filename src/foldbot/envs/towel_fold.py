"""TowelFold: a flat towel to fold to a recipe's goal by one-arm carries, as a Gymnasium
environment.

The task of issue 4's closed loop, opened to any policy: each episode is a benchmark suite's flat
towel for the reset's seed (`towel_loop`'s by default: sides 25–45 cm, position ±3 cm, yaw ±15°),
and a policy folds it one carry at a time with the cell's UR5 toward the goal of a named recipe
(half, quarter, diagonal, thirds …), as SoftGym's ClothFold and FabricFlowNet's goal-conditioned
folds pose it.

- **Observation**: the cell's RGB-D camera, downscaled, as TowelFlatten's ({"rgb", "depth"}); the
  full frame is `env.unwrapped.observation`.
- **Action**: (pick x, pick y, place x, place y) in [-1, 1] over `workspace` (world m; −1 its
  near / right edge, +1 its far / left edge): wider than the flattening workspace toward the
  robot, where the suites' largest towels reach (x 0.12–0.82 m, y ±0.35 m). The arm grasps the cloth at the pick point at the table, under every layer
  there (raised so its palm clears the cloth around), carries it over the half-sine arc a fold's
  carry takes, and lets go a few mm over the place point, above the layer it is laid on
  (episode_process.fold_carry). An action outside [-1, 1] is refused.
- **Goal and reward**: the recipe's fold lines on the settled towel's true corners (GROUND TRUTH,
  planning.recipes.recipe_fold_lines: each later fold on the outline the earlier ones leave),
  composed into every vertex's goal (metrics.fold_goal, ../shared/notes/metrics.md). The reward
  is the decrease of the mean vertex distance to that goal (m; FabricFlowNet's fold error) that
  the step made; `info` carries the fold error (mm), the first fold's normalized performance
  (SoftGym) and the coverage.
- **Success and the end**: terminated once the fold meets the benchmark's success rule
  (metrics.success: normalized performance ≥ 0.8 and fold error within the towel's bound;
  `info["is_success"]`), when the cloth blows up (`info["diverged"]`) or when the episode cannot
  go on (`info["failed"]`), those two with reward 0: reported, never scored; truncated after
  `max_steps` (6) carries.
- **Randomisation**: the suite's, per seed; `reset(seed=N)` is `foldbot bench --suite towel_loop
  --seeds N`'s towel. The recipe is the config's, the same for every episode.

The goal is the recipe's geometry on the true corners: a cell's closed loop plans each stage on
the corners it perceives then and scores against those lines, so the same fold scores a few mm
differently here than in the benchmark.

TowelFoldPair (at the end) is the same task in the two-arm cell, two carries a step.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from foldbot.bench.suite import load_suite
from foldbot.envs.episode_process import StepOutcome
from foldbot.envs.towel_task import TowelTaskConfig, TowelTaskEnv
from foldbot.errors import ConfigError, require
from foldbot.pipeline import EpisodeConfig
from foldbot.planning.recipes import RECIPES


@dataclass(frozen=True)
class TowelFoldConfig(TowelTaskConfig):
    """TowelFold's episodes: a suite's flat towels, folded to one recipe's goal."""

    suite: str = "towel_loop"
    """Benchmark suite (suites/NAME.toml, or a path) whose episode for the reset's seed is the
    towel and its cloth: a one-arm towel suite with flat starts (its recipes are not used)."""
    recipe: str = "half"
    """The towel recipe whose goal the fold is scored against (planning.recipes.RECIPES)."""
    workspace: tuple[float, float, float, float] = (0.12, 0.82, -0.35, 0.35)
    """(x min, x max, y min, y max) of the table (world, m) an action spans: every corner of the
    suites' towels (sides to 45 cm, ±3 cm, ±15° about (0.45, 0)) lies inside."""

    def __post_init__(self) -> None:
        super().__post_init__()
        require(
            self.recipe in RECIPES,
            f"recipe must be one of {', '.join(RECIPES)}, got {self.recipe!r}",
        )
        try:
            x0, x1, y0, y1 = (float(v) for v in self.workspace)
            ok = all(math.isfinite(v) for v in (x0, x1, y0, y1)) and x0 < x1 and y0 < y1
        except (TypeError, ValueError):  # not four numbers
            ok = False
        require(
            ok,
            "workspace must be (x min, x max, y min, y max) with min < max (m), got "
            f"{self.workspace!r}",
        )


@dataclass(frozen=True)
class TowelFoldPairConfig(TowelFoldConfig):
    """TowelFoldPair's episodes: a two-arm suite's flat towels, folded to one recipe's goal."""

    suite: str = "towel_two_arms"
    """Benchmark suite whose episode for the reset's seed is the towel and its cloth: a two-arm
    towel suite with flat starts (its recipes are not used)."""


def fold_episode_config(cfg: TowelFoldConfig, seed: int, arms: int = 1) -> EpisodeConfig:
    """The suite's towel for `seed` at `cfg.resolution`, with the config's recipe; ConfigError
    for a suite this task cannot run (not a towel, a crumpled start, or not `arms` arms)."""
    suite = load_suite(cfg.suite, seeds=[seed])
    spec = suite.episodes[0]
    task, example, whose = (
        ("TowelFold", "towel_loop", "one arm's")
        if arms == 1
        else ("TowelFoldPair", "towel_two_arms", "two arms'")
    )
    require(
        spec.garment == "towel" and spec.start == "flat",
        f"suite {suite.name!r} starts its {spec.garment}s {spec.start}; {task} needs a towel "
        f'suite with start = "flat" (e.g. {example})',
    )
    require(
        spec.arms == arms,
        f"suite {suite.name!r} has {spec.arms} arm{'s' if spec.arms > 1 else ''}; {task}'s "
        f"carries are {whose} (e.g. {example})",
    )
    spec = dataclasses.replace(spec, recipe=cfg.recipe)
    if cfg.resolution is not None:
        spec = dataclasses.replace(spec, towel_resolution=cfg.resolution)
    return dataclasses.replace(spec.to_config(), video_fps=0.0)


class TowelFoldEnv(TowelTaskEnv):
    """Fold a flat towel to a recipe's goal by one-arm carries from the RGB-D camera (module
    docstring)."""

    PRIMITIVE = "fold"
    CONFIG = TowelFoldConfig
    config: TowelFoldConfig

    def episode_config(self, seed: int) -> EpisodeConfig:
        return fold_episode_config(self.config, seed, self.ARMS)

    @property
    def workspace(self) -> tuple[float, float, float, float]:
        """The config's workspace; its default moved with a suite layout's workspace."""
        ws = self.config.workspace
        if tuple(ws) != TowelFoldConfig.workspace:
            return ws
        dx, dy, _ = self.layout.workspace_shift()
        return (ws[0] + dx, ws[1] + dx, ws[2] + dy, ws[3] + dy)

    def goal(self) -> str | None:
        return self.config.recipe

    def reward(self, before: StepOutcome, after: StepOutcome) -> float:
        """The fold error's decrease (m)."""
        assert before.fold is not None and after.fold is not None
        return (before.fold.fold_error_mm - after.fold.fold_error_mm) / 1000.0

    def succeeded(self, outcome: StepOutcome) -> bool:
        """Folded: the benchmark's success rule (metrics.success) on the recipe's goal."""
        return outcome.fold is not None and outcome.fold.success

    def progress(self, outcome: StepOutcome) -> dict[str, Any]:
        fold = outcome.fold
        return {
            "recipe": self.config.recipe,
            "fold_error_mm": None if fold is None else fold.fold_error_mm,
            "normalized_performance": None if fold is None else fold.normalized_performance,
        }


class TowelFoldPairEnv(TowelFoldEnv):
    """TowelFoldPair: the same task in the two-arm cell, where a step is two fold carries at
    once (a stage's two corners, as the two-arm loop carries them). The action is (a pick x,
    a pick y, a place x, a place y, b pick x, b pick y, b place x, b place y) in [-1, 1] over
    the same workspace: each carry as TowelFold's, both arms on one clock, each arm on its
    grasp's side of the cell (the other way round where their motions would meet). A carry
    shorter than 1 cm is none: that arm stays parked and the other carries alone (a triangle
    fold's single corner); a missed grasp lets both go; a pair the arms cannot make moves
    nothing (`info["infeasible"]` says why). Episodes are `towel_two_arms`' towels by default;
    goal, reward and ends as TowelFold's."""

    ARMS = 2
    PRIMITIVE = "fold_pair"
    CONFIG = TowelFoldPairConfig
    ACTION_SIZE = 8

    def action_to_world(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(picks, places), each 2×2 (world, m; carry a's, then b's) for an action in [-1, 1]⁸."""
        a = np.asarray(action, dtype=float).reshape(-1)
        if a.shape != (8,) or not np.all(np.isfinite(a)) or np.any(np.abs(a) > 1.0 + 1e-6):
            raise ConfigError(
                "an action is (a pick x, a pick y, a place x, a place y, b pick x, b pick y, "
                "b place x, b place y), each finite and in [-1, 1]; "
                f"got {np.asarray(action).tolist()!r}"
            )
        (pa, qa), (pb, qb) = (
            super(TowelFoldPairEnv, self).action_to_world(h) for h in (a[:4], a[4:])
        )
        return np.array([pa, pb]), np.array([qa, qb])

    def world_to_action(self, pick_xy: np.ndarray, place_xy: np.ndarray) -> np.ndarray:
        """The action for two carries, `pick_xy[i]` to `place_xy[i]` (world, m; 2×2 each); a
        carry given as None (both its points) is none: its pick is laid on its place, at the
        other carry's pick."""
        picks = [None if p is None else np.asarray(p, float)[:2] for p in pick_xy]
        places = [None if q is None else np.asarray(q, float)[:2] for q in place_xy]
        halves = []
        for i in range(2):
            p, q = picks[i], places[i]
            if p is None or q is None:
                p = q = picks[1 - i]
            halves.append(super().world_to_action(p, q))
        return np.concatenate(halves).astype(np.float32)
