"""The machinery the towel environments share: a benchmark suite's towel per seed, simulated in
a fresh child process per episode (episode_process), RGB-D observations downscaled, an action of
two table points in [-1, 1]⁴ over the flattening workspace, one primitive per step, and the
ends of an episode (success, divergence or failure reported and never scored, truncation).

Each task (towel_flatten: TowelFlatten, TowelSpread; towel_fold: TowelFold) says which episode
a seed is, what its step does, what it rewards and when it has succeeded.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import cv2
import gymnasium as gym
import numpy as np
from gymnasium import spaces

from foldbot.envs.episode_process import (
    EpisodeDiverged,
    EpisodeFailed,
    EpisodeProcess,
    StepOutcome,
)
from foldbot.errors import ConfigError, FoldbotError, require
from foldbot.flatten_options import flatten_configs
from foldbot.pipeline import EpisodeConfig, seeded_towel
from foldbot.types import Observation

MAX_SEED = 2**31 - 1
"""Largest episode seed a reset draws when none is given."""
RESET_TRIES = 5
"""Seeds a reset tries before giving up: a crumple can blow up or throw the towel out of the
workspace (as the suites' error records count); the next seed is drawn from the generator the
reset's seed set, so the substitute is the same every time."""


@dataclass(frozen=True)
class TowelTaskConfig:
    """What a towel environment's episodes are: a suite's towels, and the task's limits."""

    suite: str = "towel_crumpled"
    """Benchmark suite (suites/NAME.toml, or a path) whose episode for the reset's seed is the
    towel, its start and its cloth (each task says which suites it takes)."""
    resolution: int | None = None
    """Vertices along the towel's longer side; None: the suite's. Fewer simulate faster (tests
    use 5) but lie coarser."""
    image_size: tuple[int, int] = (120, 160)
    """(height, width) of the observed images (px), downscaled from the 480 × 640 camera."""
    max_steps: int = 6
    """Actions before the episode is truncated."""
    fault_diverge_s: float | None = None
    """Fault injection: the simulation raises the divergence monitor's error this many
    simulated seconds into each episode's first step, to exercise the reporting path."""

    def __post_init__(self) -> None:
        require(
            self.resolution is None
            or (
                isinstance(self.resolution, int)
                and not isinstance(self.resolution, bool)
                and 4 <= self.resolution <= 40
            ),
            f"resolution must be None or an integer in [4, 40], got {self.resolution!r}",
        )
        h, w = self.image_size
        require(
            all(isinstance(v, int) and 16 <= v <= 480 for v in (h, w)) and w <= 640,
            f"image_size (height, width) must be in [16, 480] × [16, 640] px, got "
            f"{self.image_size!r}",
        )
        require(
            isinstance(self.max_steps, int)
            and not isinstance(self.max_steps, bool)
            and 1 <= self.max_steps <= 100,
            f"max_steps must be an integer in [1, 100], got {self.max_steps!r}",
        )
        require(
            self.fault_diverge_s is None
            or (math.isfinite(self.fault_diverge_s) and self.fault_diverge_s >= 0.0),
            f"fault_diverge_s must be None or ≥ 0 s, got {self.fault_diverge_s!r}",
        )


class TowelTaskEnv(gym.Env):
    """A towel task over the simulated cell from the RGB-D camera (module docstring); a task
    names its config, arms and primitive and says what a seed's episode is
    (`episode_config`), what it rewards (`reward`) and when it has succeeded (`succeeded`)."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 1}
    ARMS: ClassVar[int] = 1
    """Arms in the cell the suite must have."""
    PRIMITIVE: ClassVar[str] = "pick_and_place"
    """What a step does with the action's two points (episode_process.PRIMITIVES)."""
    ACTION_SIZE: ClassVar[int] = 4
    """Numbers in an action: two table points (x, y), or two per arm."""
    CONFIG: ClassVar[type[TowelTaskConfig]] = TowelTaskConfig

    def __init__(
        self, config: TowelTaskConfig | None = None, render_mode: str | None = None, **fields
    ) -> None:
        """`config`, or its fields by name (`gymnasium.make(..., resolution=5)`)."""
        name = self.CONFIG.__name__
        if config is not None and fields:
            raise ConfigError(f"give a {name} or its fields, not both: {fields}")
        try:
            self.config = config if config is not None else self.CONFIG(**fields)
        except TypeError as exc:
            allowed = ", ".join(f.name for f in dataclasses.fields(self.CONFIG))
            raise ConfigError(f"{exc}; allowed: {allowed}") from None
        require(
            render_mode is None or render_mode in self.metadata["render_modes"],
            f"render_mode must be None or one of {self.metadata['render_modes']}, "
            f"got {render_mode!r}",
        )
        self.render_mode = render_mode
        probe = self.episode_config(0)  # the suite, checked before a reset
        self.flatten, self.spread = flatten_configs(probe.flatten_options, probe.sim.layout)
        """The suite's pull and spread settings (workspace, grasp heights, hang margins)."""
        self.layout = probe.sim.layout
        """The suite's cell layout (sim.layout.CellLayout; the default cell's unless its
        `[layout]` says otherwise)."""
        h, w = self.config.image_size
        self.observation_space = spaces.Dict(
            {
                "rgb": spaces.Box(0, 255, (h, w, 3), np.uint8),
                "depth": spaces.Box(0.0, float(probe.camera.far), (h, w), np.float32),
            }
        )
        self.action_space = spaces.Box(-1.0, 1.0, (self.ACTION_SIZE,), np.float32)
        self._episode: EpisodeProcess | None = None
        self._last: StepOutcome | None = None
        self._steps = 0
        self._ended = True
        self.episode_seed: int | None = None
        """The suite seed of the current episode."""
        self.towel_size_m: tuple[float, float] | None = None
        """The current towel's flat width × height (m): the item the robot is told it handles,
        as the suites' flattening pulls are told (not its state)."""

    def episode_config(self, seed: int) -> EpisodeConfig:
        """The episode of `seed`: the task's suite's towel for it; ConfigError for a suite the
        task cannot run."""
        raise NotImplementedError

    def goal(self) -> str | None:
        """The towel recipe each step's outcome is scored against (StepOutcome.fold), or None."""
        return None

    def reward(self, before: StepOutcome, after: StepOutcome) -> float:
        """What a step from `before` to `after` earns."""
        raise NotImplementedError

    def succeeded(self, outcome: StepOutcome) -> bool:
        """Whether the task is done on `outcome` (the episode then terminates)."""
        raise NotImplementedError

    def progress(self, outcome: StepOutcome) -> dict[str, Any]:
        """The task's own measures of `outcome`, added to every info."""
        return {}

    @property
    def workspace(self) -> tuple[float, float, float, float]:
        """(x min, x max, y min, y max) of the table (world, m) the action's [-1, 1] spans: the
        suite's flattening workspace, unless the task says otherwise."""
        return self.flatten.workspace

    def action_to_world(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(pick xy, place xy) in the world (m) for an action in [-1, 1]⁴."""
        a = np.asarray(action, dtype=float).reshape(-1)
        if a.shape != (4,) or not np.all(np.isfinite(a)) or np.any(np.abs(a) > 1.0 + 1e-6):
            raise ConfigError(
                "an action is (pick x, pick y, place x, place y), each finite and in [-1, 1]; "
                f"got {np.asarray(action).tolist()!r}"
            )
        x0, x1, y0, y1 = self.workspace
        lo, span = np.array([x0, y0]), np.array([x1 - x0, y1 - y0])
        to_world = lambda u: lo + (np.clip(u, -1.0, 1.0) + 1.0) / 2.0 * span  # noqa: E731
        return to_world(a[:2]), to_world(a[2:])

    def world_to_action(self, pick_xy: np.ndarray, place_xy: np.ndarray) -> np.ndarray:
        """The action (float32, clipped to [-1, 1]) that picks at `pick_xy` and places at
        `place_xy` (world, m): for scripted policies that plan in the world."""
        x0, x1, y0, y1 = self.workspace
        lo, span = np.array([x0, y0]), np.array([x1 - x0, y1 - y0])
        to_unit = lambda xy: (np.asarray(xy, float)[:2] - lo) / span * 2.0 - 1.0  # noqa: E731
        return np.clip(np.r_[to_unit(pick_xy), to_unit(place_xy)], -1.0, 1.0).astype(np.float32)

    def _obs(self, outcome: StepOutcome) -> dict[str, np.ndarray]:
        h, w = self.config.image_size
        rgb = cv2.resize(outcome.observation.rgb, (w, h), interpolation=cv2.INTER_AREA)
        depth = np.nan_to_num(np.asarray(outcome.observation.depth, np.float32), nan=0.0)
        depth = cv2.resize(depth, (w, h), interpolation=cv2.INTER_NEAREST)
        far = self.observation_space["depth"].high.flat[0]
        return {"rgb": rgb.astype(np.uint8), "depth": np.clip(depth, 0.0, far).astype(np.float32)}

    def _info(self, outcome: StepOutcome, **more: Any) -> dict[str, Any]:
        return {
            "coverage": outcome.coverage,
            **self.progress(outcome),
            "is_success": self.succeeded(outcome),
            "steps": self._steps,
            "seed": self.episode_seed,
            "towel_size_m": self.towel_size_m,
            "sim_seconds": outcome.sim_seconds,
            **more,
        }

    @property
    def observation(self) -> Observation | None:
        """The latest full camera frame (480 × 640, intrinsics, camera pose, joint states) as
        foldbot's perception takes it; None before the first reset."""
        return None if self._last is None else self._last.observation

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """A new towel: the suite's episode for `seed`, or for a seed drawn from the
        environment's generator when none is given."""
        if options:
            raise ConfigError(f"{type(self).__name__}.reset takes no options, got {options!r}")
        require(
            seed is None or (isinstance(seed, int | np.integer) and 0 <= int(seed) <= MAX_SEED),
            f"seed must be an integer in [0, {MAX_SEED}], got {seed!r}",
        )
        super().reset(seed=seed)
        drawn = seed is None  # then the generator, seeded by an earlier reset or by entropy
        episode_seed = int(self.np_random.integers(0, MAX_SEED)) if drawn else int(seed)
        self._close_episode()
        self._ended = True
        skipped: dict[int, str] = {}
        for _ in range(RESET_TRIES):
            episode = self.episode_config(episode_seed)
            try:
                self._episode = EpisodeProcess(episode, self.config.fault_diverge_s, self.goal())
                break
            except EpisodeFailed as exc:  # the crumple failed: the next seed, drawn
                skipped[episode_seed] = str(exc)
                episode_seed = int(self.np_random.integers(0, MAX_SEED))
        else:
            tried = "; ".join(f"seed {s}: {why}" for s, why in skipped.items())
            raise FoldbotError(f"no towel could be set up in {RESET_TRIES} seeds: {tried}")
        self.episode_seed = episode_seed
        self.towel_size_m = seeded_towel(episode).width, seeded_towel(episode).height
        self._last = self._episode.first
        self._steps = 0
        self._ended = False
        return self._obs(self._last), self._info(self._last, skipped_seeds=skipped)

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self._ended and self._last is not None:
            raise ConfigError(
                f"the episode (seed {self.episode_seed}) has ended; call reset() for another"
            )
        if self._episode is None or self._last is None:
            raise ConfigError("call reset() before step()")
        p, q = self.action_to_world(action)
        before = self._last
        self._steps += 1
        try:
            outcome = self._episode.step(self.PRIMITIVE, p, q)
        except EpisodeFailed as exc:  # reported in info, never scored
            self._ended = True
            self._close_episode()
            why = "diverged" if isinstance(exc, EpisodeDiverged) else "failed"
            info = self._info(before, **{why: str(exc)}, is_success=False)
            return self._obs(before), 0.0, True, False, info
        self._last = outcome
        reward = float(self.reward(before, outcome))
        terminated = self.succeeded(outcome)
        truncated = not terminated and self._steps >= self.config.max_steps
        self._ended = terminated or truncated
        info = self._info(
            outcome,
            grasp_success=outcome.grasp_success,
            grasp_reason=outcome.grasp_reason,
            infeasible=outcome.infeasible,
            grasp=outcome.grasp,
            place=outcome.place,
        )
        if self._ended:
            self._close_episode()
        return self._obs(outcome), reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """The camera's full colour frame (rgb_array), as the episode stands."""
        if self.render_mode != "rgb_array" or self._last is None:
            return None
        return np.array(self._last.observation.rgb, copy=True)

    def _close_episode(self) -> None:
        if self._episode is not None:
            self._episode.close()
            self._episode = None

    def close(self) -> None:
        self._close_episode()
        super().close()
