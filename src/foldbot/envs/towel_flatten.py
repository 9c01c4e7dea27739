"""TowelFlatten: a crumpled towel to flatten by pick-and-place, as a Gymnasium environment
(and TowelSpread, at the end: the same with two arms, whose step is a spread).

The task of issue 6's crumpled suites, opened to any policy (a learned one, a scripted one): each
episode is a benchmark suite's towel for the reset's seed, crumpled by the same draws as in
`foldbot bench`, and a policy flattens it one pick-and-place at a time with the cell's UR5.

- **Observation**: the cell's RGB-D camera, downscaled to `image_size`: {"rgb": H×W×3 uint8,
  "depth": H×W float32 metres along the optical axis, 0 where unknown}. The full frame with its
  intrinsics and camera pose (a foldbot Observation) is `env.unwrapped.observation`, for
  policies that back-project.
- **Action**: (pick x, pick y, place x, place y) in [-1, 1], mapped onto the flattening
  workspace (FlattenConfig.workspace, world metres; −1 its near / right edge, +1 its far / left
  edge). The arm grasps at the pick point, at the height the depth image gives there (raised so
  its palm clears heaped cloth, as the flattening pulls grasp), carries, and lets go over the
  place point. An action outside [-1, 1] is refused.
- **Reward**: the change in coverage (cloth area seen from above over its flat area; ground
  truth, shared/notes/metrics.md) that the step made.
- **Success and the end**: terminated once the coverage reaches `goal_coverage` (0.9, the
  issue's flattening target; `info["is_success"]`), when the cloth blows up
  (`info["diverged"]`) or when the episode cannot go on (`info["failed"]`: the camera lost the
  cloth …), those two with reward 0: reported, never scored; truncated after `max_steps` (6,
  the issue's budget) actions.
- **Randomisation** (the suite's, per seed): towel sides 25–45 cm, position ±3 cm, yaw ±15°,
  and the crumple (pinch point, lift, drag). `reset(seed=N)` is `foldbot bench --suite
  towel_crumpled --seeds N`'s towel, crumpled alike. Where that crumple fails (the heap blows
  up, or the towel lands outside the workspace: the suites record it as an error), the reset
  takes the next seed its generator draws and names the one it skipped in
  `info["skipped_seeds"]`; `info["seed"]` is the suite seed the episode runs.

Each episode simulates in a fresh child process (episode_process), so the same seed gives the
same episode however many ran before it in this process; the machinery is towel_task's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from foldbot.bench.suite import load_suite
from foldbot.envs.episode_process import StepOutcome
from foldbot.envs.towel_task import TowelTaskConfig, TowelTaskEnv
from foldbot.errors import require
from foldbot.pipeline import EpisodeConfig


@dataclass(frozen=True)
class TowelFlattenConfig(TowelTaskConfig):
    """What the environment's episodes are: a suite's crumpled towels, and the task's limits."""

    suite: str = "towel_crumpled"
    """Benchmark suite (suites/NAME.toml, or a path) whose episode for the reset's seed is the
    towel, its crumple and its cloth: a one-arm suite with crumpled starts."""
    max_steps: int = 6
    """Actions before the episode is truncated (issue 6: flattened within 6 actions)."""
    goal_coverage: float = 0.9
    """Coverage at which the towel counts as flattened and the episode terminates."""

    def __post_init__(self) -> None:
        super().__post_init__()
        require(
            isinstance(self.goal_coverage, int | float)
            and math.isfinite(self.goal_coverage)
            and 0.0 < self.goal_coverage <= 1.0,
            f"goal_coverage must be in (0, 1], got {self.goal_coverage!r}",
        )


@dataclass(frozen=True)
class TowelSpreadConfig(TowelFlattenConfig):
    """TowelSpread's episodes: a two-arm suite's crumpled towels."""

    suite: str = "towel_crumpled_two_arms"
    """Benchmark suite whose episode for the reset's seed is the towel: a two-arm suite with
    crumpled starts."""


def episode_config(cfg: TowelFlattenConfig, seed: int, arms: int = 1) -> EpisodeConfig:
    """The suite's episode for `seed` (its towel, crumple and cloth), at `cfg.resolution`;
    ConfigError for a suite this task cannot run (no crumpled start, or not `arms` arms)."""
    suite = load_suite(cfg.suite, seeds=[seed])
    spec = suite.episodes[0]
    require(
        spec.start == "crumpled" and spec.garment == "towel",
        f"suite {suite.name!r} starts its {spec.garment}s {spec.start}; TowelFlatten needs a "
        'towel suite with start = "crumpled" (e.g. towel_crumpled)',
    )
    task, example = ("TowelFlatten", "towel_crumpled") if arms == 1 else ("TowelSpread", "")
    require(
        spec.arms == arms,
        f"suite {suite.name!r} has {spec.arms} arm{'s' if spec.arms > 1 else ''}; "
        + (
            f"{task}'s pick-and-place is one arm's (e.g. {example})"
            if arms == 1
            else "TowelSpread's spread is two arms' (e.g. towel_crumpled_two_arms)"
        ),
    )
    if cfg.resolution is not None:
        spec = dataclasses.replace(spec, towel_resolution=cfg.resolution)
    return dataclasses.replace(spec.to_config(), video_fps=0.0)


class TowelFlattenEnv(TowelTaskEnv):
    """Flatten a crumpled towel by pick-and-place from the RGB-D camera (module docstring)."""

    CONFIG = TowelFlattenConfig
    config: TowelFlattenConfig

    def episode_config(self, seed: int) -> EpisodeConfig:
        return episode_config(self.config, seed, self.ARMS)

    def reward(self, before: StepOutcome, after: StepOutcome) -> float:
        """The coverage's change."""
        return after.coverage - before.coverage

    def succeeded(self, outcome: StepOutcome) -> bool:
        """Flattened: the coverage reached `goal_coverage`."""
        return outcome.coverage >= self.config.goal_coverage


class TowelSpreadEnv(TowelFlattenEnv):
    """TowelSpread: the same task in the two-arm cell, where a step is a spread (FlingBot's
    action, two grasp points). The action is (a x, a y, b x, b y) in [-1, 1] over the same
    workspace: both arms grasp, each at its point (the +y arm at the point further along +y;
    gripper down, at the height the depth image gives there, the palm clear of the heap), lift
    the towel, spread the points one nominal side apart, hang it and lay it down across the
    workspace, as the two-arm flattening spreads do (planning.spread.plan_spread_at). A spread
    the arms cannot make, or whose palm would press into the heap, moves nothing
    (`info["infeasible"]` says why). Episodes are `towel_crumpled_two_arms`' towels by default;
    reward, ends and randomisation as TowelFlatten's."""

    ARMS = 2
    PRIMITIVE = "spread"
    CONFIG = TowelSpreadConfig
