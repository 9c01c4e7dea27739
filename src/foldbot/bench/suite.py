"""Benchmark suites: a TOML file that states exactly what runs and what the seed randomises.

A suite is the grid garment × recipe × perception × loop × seed; every cell is one episode with a
stable id such as `towel-half-vision-closed-s0007`. Suites live in the repository's `suites/`
folder (`--suite NAME`) or anywhere (`--suite path/to/file.toml`). The format:

```toml
name = "smoke"                          # must match the file name for suites/NAME.toml
description = "what the suite is for"

[axes]                                  # every combination runs for every seed
garment = ["towel"]                     # towel, tshirt, pants (a T-shirt's / pants' size is
                                        # drawn by the seed from foldbot.garments' ranges)
recipe = ["half", "diagonal"]           # towel: planning.recipes.RECIPES; tshirt: retail;
                                        # pants: leg_over_leg (every garment × recipe must match)
perception = ["vision", "oracle"]       # comparison axis: keypoints from RGB-D or ground truth
loop = ["closed", "open"]               # comparison axis: re-observe after every action or not
seeds = "0-1"                           # "0-49", "0,3,5" or a list of integers ≥ 0
                                        # (at most 10 000 seeds, each ≤ 2^31 − 1)
replicates = 1                          # runs of each seed's cloth (1–20): replicate k > 0 lays
                                        # it 0.1 mm from the seed's pose (EpisodeConfig.replicate)

[towel]                                 # the towel's fixed settings
resolution = 16                         # vertices along the longer side (4–40)
odd_grid = false                        # odd vertex counts: vertex rows on both midlines
max_vertices = 143                      # at most this many vertices (optional): a near-square
                                        # towel gets fewer along its longer side
width = 0.30                            # m; used when [randomise] towel_side is absent
height = 0.30

[randomise]                             # what the seed draws, uniformly, per episode
towel_side = [0.25, 0.45]               # m, each side independently (optional)
position_jitter = 0.03                  # m, centre offset in ±this along x and along y
yaw_deg = 15                            # degrees, yaw in ±this
garment_yaw_deg = 90                    # degrees, a T-shirt's / pants' base yaw (90: top toward
                                        # the robot; 0: sideways), the draw above added

[episode]
retries = 1                             # closed loop: redo a failed grasp / off placement
video_fps = 0                           # video.mp4 frames per simulated second (0 = none)
start = "flat"                          # "crumpled": crumple the cloth, flatten it, then fold
park = "home"                           # "out_of_view": the arm waits outside the camera's image
time_step = 0.0027778                   # s, physics step (optional; default SimConfig's 1/360)
arms = 1                                # 2: two arms side by side carry a stage's corners together
jaw_catch = "vertices"                  # "surface": closed jaws also hold cloth between mesh points
speed_scale = 1.0                       # fraction of full arm speed (0.05–1; the same paths, slower)
robot = "ur5"                           # the arm: ur5, ur5e or panda

[loop_options]                          # the closed loop's switches (foldbot.loop_options), e.g.
top_layer_first = false                 # true/false, integers, metres; "none" where allowed

[cloth]                                 # the cloth's physical parameters (foldbot.cloth_options),
margin_divisor = 6.5                    # e.g. a thinner collision margin: edge / 6.5 (default 5)

[flatten_options]                       # how a crumpled towel is flattened (foldbot.flatten_options;
finish_coverage = "none"                # crumpled starts only), e.g. stop at the 0.9 target

[layout]                                # the cell's layout (foldbot.sim.layout.CellLayout; world m),
table_height = 0.72                     # as `foldbot fold --layout FILE.toml`; the rest the default
robot_base_xyz = [0.0, 0.0, 0.72]       # cell's

[[layout.obstacles]]                    # a fixture every motion keeps 2 cm from (a named box,
name = "camera_post"                    # world m; foldbot.sim.layout.Obstacle), as a layout
center_xyz = [1.20, 0.0, 0.90]          # file's [[obstacles]]
size_xyz = [0.08, 0.08, 1.80]

[reference]
ravens_speed = true                     # plain-PyBullet speed reference (ravens_reference.py)
```

Every key is checked: an unknown section or key, a wrong type or an out-of-range value is one
ConfigError naming the file, the key, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from foldbot.cloth_options import CLOTH_OPTIONS, apply_cloth_options, check_cloth_options
from foldbot.errors import ConfigError
from foldbot.flatten_options import FLATTEN_OPTIONS, FlattenOptionValue, check_flatten_options
from foldbot.garments.towel import MAX_RESOLUTION, MIN_RESOLUTION, MIN_VERTICES, TowelSpec
from foldbot.layout_check import CameraPlacement
from foldbot.loop_options import LOOP_OPTIONS, LoopOptionValue, check_loop_options
from foldbot.pipeline import (
    ARM_COUNTS,
    GARMENTS,
    MAX_VIDEO_FPS,
    PARK_POSES,
    PERCEPTION_MODES,
    START_STATES,
    EpisodeConfig,
    garment_recipes,
)
from foldbot.planning.garment_recipes import GARMENT_RECIPES
from foldbot.planning.motion import MIN_SPEED_SCALE, MotionConfig
from foldbot.planning.recipes import RECIPES
from foldbot.sim.camera import CameraConfig
from foldbot.sim.cloth import ClothConfig
from foldbot.sim.grasp import JAW_CATCHES
from foldbot.sim.layout import (
    DEFAULT_LAYOUT,
    LAYOUT_FIELDS,
    CellLayout,
    layout_from_table,
    obstacle_from_table,
)
from foldbot.sim.robots import ROBOT_NAMES
from foldbot.sim.world import MAX_TIME_STEP, MIN_TIME_STEP, SimConfig

ALL_RECIPES = RECIPES + tuple(r for rs in GARMENT_RECIPES.values() for r in rs)

SUITES_DIR = Path(__file__).resolve().parents[3] / "suites"
"""The repository's suite folder (src/foldbot/bench/suite.py → <repo>/suites)."""
LOOP_MODES = ("closed", "open")
"""closed: re-observe after every action (retries, regrasp, stage checks); open: plan once."""

_SCHEMA: dict[str, set[str]] = {
    "": {
        "name",
        "description",
        "axes",
        "towel",
        "randomise",
        "episode",
        "loop_options",
        "cloth",
        "flatten_options",
        "layout",
        "reference",
    },
    "axes": {"garment", "recipe", "perception", "loop", "seeds", "replicates"},
    "towel": {"resolution", "odd_grid", "max_vertices", "width", "height"},
    "randomise": {"towel_side", "position_jitter", "yaw_deg", "garment_yaw_deg"},
    "episode": {
        "retries",
        "video_fps",
        "start",
        "park",
        "time_step",
        "arms",
        "jaw_catch",
        "speed_scale",
        "robot",
    },
    "loop_options": set(LOOP_OPTIONS),
    "cloth": set(CLOTH_OPTIONS),
    "flatten_options": set(FLATTEN_OPTIONS),
    "layout": set(LAYOUT_FIELDS),
    "reference": {"ravens_speed"},
}


MAX_REPLICATES = 20
"""Most runs of one seed's cloth a suite may ask for (`[axes] replicates`)."""
MAX_SEEDS = 10_000
"""Most seeds one seed text or list (a suite's `[axes] seeds`, `bench --seeds`) may name: a
generous bound (the full suites run 50), checked before a range is expanded."""
MAX_SEED = 2**31 - 1
"""Largest seed (as the gym environment's, foldbot.envs.towel_task.MAX_SEED)."""


def parse_seeds(text: str | list[int]) -> list[int]:
    """'0-9', '0,3,5', '4' or a list of integers → sorted unique seeds, each in [0, MAX_SEED],
    at most MAX_SEEDS of them (a range is checked before it is expanded)."""
    shown = repr(text) if len(repr(text)) <= 60 else repr(text)[:57] + "…"
    ranges: list[tuple[int, int]] = []
    if isinstance(text, list):
        if not all(isinstance(s, int) and not isinstance(s, bool) for s in text):
            raise ConfigError(f"seeds must be integers ≥ 0, got {shown}")
        ranges = [(s, s) for s in text]
    else:
        try:
            for part in str(text).split(","):
                if "-" in part.strip()[1:]:
                    lo, hi = (int(v) for v in part.split("-", 1))
                    if hi < lo:
                        raise ValueError
                    ranges.append((lo, hi))
                else:
                    ranges.append((int(part), int(part)))
        except ValueError:
            raise ConfigError(f"seeds must look like '0-9' or '0,3,5', got {shown}") from None
    seeds: set[int] = set()
    for lo, hi in ranges:
        if hi > MAX_SEED or hi - lo >= MAX_SEEDS:
            raise ConfigError(
                f"seeds must name at most {MAX_SEEDS} seeds, each in [0, {MAX_SEED}], got {shown}"
            )
        seeds.update(range(lo, hi + 1))
        if len(seeds) > MAX_SEEDS:
            raise ConfigError(
                f"seeds must name at most {MAX_SEEDS} seeds, got {shown} ({len(seeds)} or more)"
            )
    if not seeds or min(seeds) < 0:
        raise ConfigError(f"seeds must name at least one seed, all ≥ 0, got {shown}")
    return sorted(seeds)


@dataclass(frozen=True)
class EpisodeSpec:
    """One benchmark episode: its grid cell, seed and randomisation ranges (JSON-able)."""

    garment: str
    recipe: str
    perception: str
    loop: str
    seed: int
    towel_width: float = 0.30
    """m; ignored when towel_side_range is set."""
    towel_height: float = 0.30
    towel_resolution: int = 16
    towel_odd_grid: bool = False
    """Odd vertex counts along both sides (TowelSpec.odd_grid)."""
    towel_max_vertices: int | None = None
    """At most this many vertices per towel (TowelSpec.max_vertices); None: no bound."""
    towel_side_range: tuple[float, float] | None = None
    """m; each side drawn uniformly from it by the seed."""
    position_jitter: float = 0.03
    """m; the cloth centre is offset by a uniform draw in ±this along x and y."""
    yaw_deg: float = 15.0
    """degrees; the cloth yaw is a uniform draw in ±this."""
    garment_yaw_deg: float = 90.0
    """degrees; a T-shirt's or pants' base yaw (EpisodeConfig.garment_yaw), the draw added."""
    retries: int = 1
    video_fps: float = 0.0
    start: str = "flat"
    """flat, or crumpled: crumple the cloth, flatten it, then fold."""
    park: str = "home"
    """Where the arm waits while the camera looks: home or out_of_view."""
    time_step: float | None = None
    """Physics step (s); None = SimConfig's default (1/360 s)."""
    arms: int = 1
    """Arms in the cell (EpisodeConfig.arms): 1, or 2 side by side."""
    jaw_catch: str = "vertices"
    """What the closed jaws hold (EpisodeConfig.jaw_catch): vertices, or surface."""
    speed_scale: float = 1.0
    """Fraction of full speed the arms move at (MotionConfig.speed_scale)."""
    robot: str = "ur5"
    """The arm (EpisodeConfig.robot): ur5, ur5e or panda."""
    loop_options: tuple[tuple[str, LoopOptionValue], ...] = ()
    """The closed loop's switches set by name (EpisodeConfig.loop_options), as (name, value)."""
    cloth_options: tuple[tuple[str, float], ...] = ()
    """The cloth's physical parameters set by name (cloth_options.CLOTH_OPTIONS), as (name,
    value); the others at ClothConfig's defaults."""
    flatten_options: tuple[tuple[str, FlattenOptionValue], ...] = ()
    """How a crumpled towel is flattened, set by name (EpisodeConfig.flatten_options), as
    (name, value)."""
    replicate: int = 0
    """EpisodeConfig.replicate: 0, the seed's pose; k > 0, the same cloth laid 0.1 mm from it."""
    layout: tuple[tuple[str, Any], ...] = ()
    """The cell's layout set by field (sim.layout.CellLayout), as (name, value), lists as
    tuples; the others at the default cell's."""
    camera: tuple[tuple[str, Any], ...] = ()
    """The camera a calibration placed (`bench --camera-pose`; camera_items): its pose found,
    where it truly stood, K, image size and file, as (name, value); empty: the suite's
    camera, its pose given to perception exactly."""

    @property
    def id(self) -> str:
        """Stable id and folder name, e.g. towel-half-vision-closed-s0007 (a crumpled start adds
        -crumpled before the seed, a replicate k > 0 -rk after it)."""
        start = "" if self.start == "flat" else f"-{self.start}"
        rep = f"-r{self.replicate}" if self.replicate else ""
        return (
            f"{self.garment}-{self.recipe}-{self.perception}-{self.loop}{start}"
            f"-s{self.seed:04d}{rep}"
        )

    @property
    def group(self) -> tuple[str, str, str, str]:
        """(garment, recipe, perception, loop): the summary's grouping key."""
        return (self.garment, self.recipe, self.perception, self.loop)

    def to_config(self) -> EpisodeConfig:
        """The pipeline's EpisodeConfig for this spec (validated by EpisodeConfig itself)."""
        return EpisodeConfig(
            garment=self.garment,
            recipe=self.recipe,
            perception=self.perception,
            closed_loop=self.loop == "closed",
            seed=self.seed,
            towel=TowelSpec(
                width=self.towel_width,
                height=self.towel_height,
                resolution=self.towel_resolution,
                odd_grid=self.towel_odd_grid,
                max_vertices=self.towel_max_vertices,
            ),
            towel_size_range=self.towel_side_range,
            position_jitter=self.position_jitter,
            yaw_range=math.radians(self.yaw_deg),
            garment_yaw=math.radians(self.garment_yaw_deg),
            retries=self.retries,
            video_fps=self.video_fps,
            start=self.start,
            park=self.park,
            arms=self.arms,
            jaw_catch=self.jaw_catch,
            motion=MotionConfig(speed_scale=self.speed_scale),
            robot=self.robot,
            loop_options=dict(self.loop_options),
            cloth=apply_cloth_options(ClothConfig(), dict(self.cloth_options)),
            flatten_options=dict(self.flatten_options),
            replicate=self.replicate,
            sim=SimConfig(
                time_step=SimConfig.time_step if self.time_step is None else self.time_step,
                layout=CellLayout(**dict(self.layout)) if self.layout else DEFAULT_LAYOUT,
            ),
            camera=camera_from_items(self.camera),
        )

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-able fields (tuples as lists)."""
        d = dataclasses.asdict(self)
        if d["time_step"] is None:
            del d["time_step"]  # runs from before the key existed resume unchanged
        if not d["towel_odd_grid"]:
            del d["towel_odd_grid"]  # likewise
        if d["towel_max_vertices"] is None:
            del d["towel_max_vertices"]  # likewise
        if d["arms"] == 1:
            del d["arms"]  # likewise
        if d["jaw_catch"] == "vertices":
            del d["jaw_catch"]  # likewise
        if d["speed_scale"] == 1.0:
            del d["speed_scale"]  # likewise
        if d["robot"] == "ur5":
            del d["robot"]  # likewise
        if d["garment_yaw_deg"] == 90.0:
            del d["garment_yaw_deg"]  # likewise
        if d["loop_options"]:
            d["loop_options"] = dict(self.loop_options)
        else:
            del d["loop_options"]  # likewise
        if d["cloth_options"]:
            d["cloth_options"] = dict(self.cloth_options)
        else:
            del d["cloth_options"]  # likewise
        if d["flatten_options"]:
            d["flatten_options"] = dict(self.flatten_options)
        else:
            del d["flatten_options"]  # likewise
        if d["replicate"] == 0:
            del d["replicate"]  # likewise
        if d["layout"]:
            d["layout"] = {
                k: [o.as_dict() for o in v]
                if k == "obstacles"
                else (list(v) if isinstance(v, tuple) else v)
                for k, v in self.layout
            }
        else:
            del d["layout"]  # likewise
        if d["camera"]:
            d["camera"] = {k: _plain(v) for k, v in self.camera}
        else:
            del d["camera"]  # likewise
        if d["towel_side_range"] is not None:
            d["towel_side_range"] = list(d["towel_side_range"])
        return d

    def with_options(
        self,
        loop: dict[str, LoopOptionValue],
        cloth: dict[str, float],
        flatten: dict[str, FlattenOptionValue],
    ) -> EpisodeSpec:
        """This episode with the `loop`, `cloth` and `flatten` options set over (and beside) its
        own, each checked (ConfigError: e.g. a loop option a garment's loop does not read)."""
        return dataclasses.replace(
            self,
            loop_options=tuple(
                check_loop_options({**dict(self.loop_options), **loop}, self.garment).items()
            ),
            cloth_options=tuple(check_cloth_options({**dict(self.cloth_options), **cloth}).items()),
            flatten_options=tuple(
                check_flatten_options({**dict(self.flatten_options), **flatten}).items()
            ),
        )

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> EpisodeSpec:
        """Inverse of as_dict."""
        d = dict(d)
        if d.get("towel_side_range") is not None:
            d["towel_side_range"] = tuple(d["towel_side_range"])
        for key in ("loop_options", "cloth_options", "flatten_options"):
            if key in d:
                d[key] = tuple(d[key].items())
        if "layout" in d:
            d["layout"] = layout_items(d["layout"])
        if "camera" in d:
            d["camera"] = tuple(
                (k, _frozen(v) if isinstance(v, list) else v) for k, v in d["camera"].items()
            )
        return cls(**d)


def camera_items(placement: CameraPlacement) -> tuple[tuple[str, Any], ...]:
    """A calibration's camera as an EpisodeSpec keeps it (hashable, JSON-able)."""
    true = placement.true_T_world_camera
    return (
        ("T_world_camera", _frozen(placement.T_world_camera)),
        ("true_T_world_camera", None if true is None else _frozen(true)),
        ("K", _frozen(placement.K)),
        ("width", int(placement.width)),
        ("height", int(placement.height)),
        ("source", placement.source),
    )


def camera_from_items(camera: tuple[tuple[str, Any], ...]) -> CameraConfig:
    """The EpisodeConfig camera for an EpisodeSpec's `camera`: the default camera, or the one
    the calibration placed (CameraPlacement.sim_camera)."""
    if not camera:
        return CameraConfig()
    c = dict(camera)
    true = c["true_T_world_camera"]
    placement = CameraPlacement(
        np.array(c["T_world_camera"], dtype=float),
        np.array(c["K"], dtype=float),
        int(c["width"]),
        int(c["height"]),
        str(c["source"]),
        None if true is None else np.array(true, dtype=float),
    )
    return placement.sim_camera(CameraConfig())


def _frozen(value: Any) -> Any:
    """Nested lists or arrays as nested tuples of floats (None kept)."""
    if value is None:
        return None
    return tuple(tuple(float(v) for v in row) for row in np.asarray(value, dtype=float))


def _plain(value: Any) -> Any:
    """Nested tuples as nested lists, for JSON."""
    return [list(row) for row in value] if isinstance(value, tuple) else value


@dataclass(frozen=True)
class Suite:
    """A loaded, validated suite: its episodes (grid order) and what it randomises."""

    name: str
    description: str
    episodes: tuple[EpisodeSpec, ...]
    axes: dict[str, list]
    randomised: dict[str, Any]
    """What the seed draws, in words and numbers (for the summary)."""
    ravens_speed: bool = True
    source: str = ""
    """The file it came from ('' for a suite built from command-line options)."""

    @property
    def loop_options(self) -> dict[str, LoopOptionValue]:
        """The loop options its episodes set (one [loop_options] table for the whole suite)."""
        return dict(self.episodes[0].loop_options) if self.episodes else {}

    @property
    def robot(self) -> str:
        """The arm its episodes fold with (one [episode] robot for the whole suite)."""
        return self.episodes[0].robot if self.episodes else "ur5"

    @property
    def cloth_options(self) -> dict[str, float]:
        """The cloth options its episodes set (one [cloth] table for the whole suite)."""
        return dict(self.episodes[0].cloth_options) if self.episodes else {}

    @property
    def flatten_options(self) -> dict[str, FlattenOptionValue]:
        """The flatten options its episodes set (one [flatten_options] table for the suite)."""
        return dict(self.episodes[0].flatten_options) if self.episodes else {}

    def as_dict(self) -> dict[str, Any]:
        """JSON-able description (written to DIR/suite.json; resuming checks it)."""
        return {
            "name": self.name,
            "description": self.description,
            "source": self.source,
            "axes": self.axes,
            "randomised": self.randomised,
            "ravens_speed": self.ravens_speed,
            "episodes": {e.id: e.as_dict() for e in self.episodes},
        }


def available_suites() -> list[str]:
    """Names of the suite files in the repository's suites/ folder."""
    return sorted(p.stem for p in SUITES_DIR.glob("*.toml")) if SUITES_DIR.is_dir() else []


def resolve_suite_path(name: str) -> Path:
    """suites/NAME.toml, or NAME itself when it is a path to a .toml file."""
    p = Path(name)
    if p.suffix == ".toml" or "/" in name:
        if not p.is_file():
            raise ConfigError(f"suite file {name!r} does not exist")
        return p
    path = SUITES_DIR / f"{name}.toml"
    if not path.is_file():
        allowed = ", ".join(available_suites()) or "(none found)"
        raise ConfigError(
            f"unknown suite {name!r}; available in {SUITES_DIR}: {allowed} "
            "(or give a path to a .toml file)"
        )
    return path


def load_suite(name: str, seeds: list[int] | None = None) -> Suite:
    """Load and validate a suite by name (suites/NAME.toml) or path; with `seeds`, its episodes
    for those seeds instead of its own axes.seeds (each seed draws its towel alone, so seed N's
    episode is the same whichever seeds run beside it)."""
    path = resolve_suite_path(name)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"suite file {path}: not valid TOML: {exc}") from None
    if seeds is not None:
        axes = data.get("axes")
        data["axes"] = {**(axes if isinstance(axes, dict) else {}), "seeds": list(seeds)}
    suite = suite_from_dict(data, source=str(path))
    if path.parent.resolve() == SUITES_DIR and suite.name != path.stem:
        raise ConfigError(f"suite file {path}: name = {suite.name!r} must match the file name")
    return suite


def _get(
    data: dict, section: str, key: str, kind: type | tuple[type, ...], default: Any, where: str
):
    table = data.get(section, {}) if section else data
    if key not in table:
        return default
    value = table[key]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    ok = isinstance(value, kinds) and not (isinstance(value, bool) and bool not in kinds)
    if not ok:
        names = " or ".join(k.__name__ for k in kinds)
        raise ConfigError(
            f"{where}: {section + '.' if section else ''}{key} = {value!r} must be a {names}"
        )
    return value


def _choices(data: dict, key: str, allowed: tuple[str, ...], default: list[str], where: str):
    values = _get(data, "axes", key, list, default, where)
    if not values:
        raise ConfigError(f"{where}: axes.{key} is empty; allowed values: {', '.join(allowed)}")
    for v in values:
        if v not in allowed:
            raise ConfigError(
                f"{where}: axes.{key} has unknown value {v!r}; allowed: {', '.join(allowed)}"
            )
    if len(set(values)) != len(values):
        raise ConfigError(f"{where}: axes.{key} = {values!r} repeats a value")
    return list(values)


def _range(value: Any, key: str, lo: float, hi: float, where: str) -> float:
    if not (isinstance(value, int | float) and not isinstance(value, bool)) or not (
        lo <= value <= hi
    ):
        raise ConfigError(f"{where}: {key} = {value!r} must be a number in [{lo:g}, {hi:g}]")
    return float(value)


def layout_items(table: dict[str, Any]) -> tuple[tuple[str, Any], ...]:
    """A `[layout]` table as EpisodeSpec.layout's (name, value) pairs, lists as tuples (its
    `[[layout.obstacles]]` as sim.layout.Obstacle)."""
    if not isinstance(table, dict):
        raise ConfigError(f"[layout] must be a table of name = value, got {table!r}")

    def value(k: str, v: Any) -> Any:
        if k == "obstacles" and isinstance(v, list | tuple):
            return tuple(
                obstacle_from_table(o, f"[layout] obstacles[{i}]") for i, o in enumerate(v)
            )
        return tuple(v) if isinstance(v, list) else v

    return tuple((k, value(k, v)) for k, v in table.items())


def _option_table(
    data: dict[str, Any],
    section: str,
    check: Callable[[dict[str, Any]], dict[str, Any]],
    where: str,
) -> tuple[tuple[str, Any], ...]:
    """A `[section]` table of options by name ("none" read as None), checked by `check`, as
    (name, value) pairs; ConfigError naming the file and the table otherwise."""
    table = data.get(section, {})
    try:
        return tuple(check({k: None if v == "none" else v for k, v in table.items()}).items())
    except ConfigError as exc:
        raise ConfigError(f"{where}: [{section}] {exc}") from None


def suite_from_dict(data: dict[str, Any], source: str = "") -> Suite:
    """Validate a parsed suite (the TOML's tables) and expand it into episode specs."""
    where = f"suite file {source}" if source else "suite"
    for section, allowed in _SCHEMA.items():
        table = data if not section else data.get(section, {})
        if section and not isinstance(table, dict):
            raise ConfigError(f"{where}: [{section}] must be a table")
        for key in table:
            if key not in allowed:
                name = f"{section}.{key}" if section else key
                raise ConfigError(
                    f"{where}: unknown key {name!r}; allowed"
                    f"{' in [' + section + ']' if section else ''}: {', '.join(sorted(allowed))}"
                )
    name = _get(data, "", "name", str, "", where)
    if not name or not name.replace("_", "").replace("-", "").isalnum():
        raise ConfigError(
            f"{where}: name = {name!r} must be a non-empty word (letters, digits, _-)"
        )
    description = _get(data, "", "description", str, "", where)

    garments = _choices(data, "garment", GARMENTS, ["towel"], where)
    recipes = _choices(data, "recipe", ALL_RECIPES, ["half"], where)
    for garment in garments:
        for recipe in recipes:
            if recipe not in garment_recipes(garment):
                raise ConfigError(
                    f"{where}: recipe {recipe!r} does not fold a {garment}; "
                    f"{garment} recipes: {', '.join(garment_recipes(garment))}"
                )
    perceptions = _choices(data, "perception", PERCEPTION_MODES, ["vision"], where)
    loops = _choices(data, "loop", LOOP_MODES, ["closed"], where)
    seeds_raw = _get(data, "axes", "seeds", (str, list, int), None, where)
    if seeds_raw is None:
        raise ConfigError(f'{where}: axes.seeds is required, e.g. seeds = "0-49"')
    try:
        seeds = parse_seeds([seeds_raw] if isinstance(seeds_raw, int) else seeds_raw)
    except ConfigError as exc:
        raise ConfigError(f"{where}: axes.{exc}") from None
    replicates = _get(data, "axes", "replicates", int, 1, where)
    if not 1 <= replicates <= MAX_REPLICATES:
        raise ConfigError(
            f"{where}: axes.replicates = {replicates!r} must be an integer in [1, {MAX_REPLICATES}]"
        )

    towel = data.get("towel", {})
    resolution = _get(data, "towel", "resolution", int, 16, where)
    if not MIN_RESOLUTION <= resolution <= MAX_RESOLUTION:
        raise ConfigError(
            f"{where}: towel.resolution = {resolution!r} must be an integer in "
            f"[{MIN_RESOLUTION}, {MAX_RESOLUTION}]"
        )
    odd_grid = _get(data, "towel", "odd_grid", bool, False, where)
    max_vertices = _get(data, "towel", "max_vertices", int, None, where)
    if max_vertices is not None and not MIN_VERTICES <= max_vertices <= MAX_RESOLUTION**2:
        raise ConfigError(
            f"{where}: towel.max_vertices = {max_vertices!r} must be an integer in "
            f"[{MIN_VERTICES}, {MAX_RESOLUTION**2}]"
        )
    width = _range(towel.get("width", 0.30), "towel.width", 0.05, 1.0, where)
    height = _range(towel.get("height", 0.30), "towel.height", 0.05, 1.0, where)

    rand = data.get("randomise", {})
    side = rand.get("towel_side")
    side_range = None
    if side is not None:
        if not (isinstance(side, list) and len(side) == 2):
            raise ConfigError(
                f"{where}: randomise.towel_side = {side!r} must be [lo, hi] in metres"
            )
        lo = _range(side[0], "randomise.towel_side[0]", 0.05, 1.0, where)
        hi = _range(side[1], "randomise.towel_side[1]", 0.05, 1.0, where)
        if hi < lo:
            raise ConfigError(f"{where}: randomise.towel_side = {side!r} needs lo ≤ hi")
        side_range = (lo, hi)
    jitter = _range(rand.get("position_jitter", 0.03), "randomise.position_jitter", 0, 0.15, where)
    yaw = _range(rand.get("yaw_deg", 15.0), "randomise.yaw_deg", 0, 180, where)
    garment_yaw = _range(
        rand.get("garment_yaw_deg", 90.0), "randomise.garment_yaw_deg", -180, 360, where
    )

    ep = data.get("episode", {})
    retries = _get(data, "episode", "retries", int, 1, where)
    if not 0 <= retries <= 10:
        raise ConfigError(f"{where}: episode.retries = {retries!r} must be an integer in [0, 10]")
    video_fps = _range(ep.get("video_fps", 0.0), "episode.video_fps", 0, MAX_VIDEO_FPS, where)
    start = _get(data, "episode", "start", str, "flat", where)
    if start not in START_STATES:
        raise ConfigError(
            f"{where}: episode.start = {start!r} is unknown; allowed: {', '.join(START_STATES)}"
        )
    park = _get(data, "episode", "park", str, "home", where)
    if park not in PARK_POSES:
        raise ConfigError(
            f"{where}: episode.park = {park!r} is unknown; allowed: {', '.join(PARK_POSES)}"
        )
    arms = _get(data, "episode", "arms", int, 1, where)
    if arms not in ARM_COUNTS:
        raise ConfigError(
            f"{where}: episode.arms = {arms!r} is not allowed; allowed: "
            f"{', '.join(map(str, ARM_COUNTS))}"
        )
    jaw_catch = _get(data, "episode", "jaw_catch", str, "vertices", where)
    if jaw_catch not in JAW_CATCHES:
        raise ConfigError(
            f"{where}: episode.jaw_catch = {jaw_catch!r} is unknown; allowed: "
            f"{', '.join(JAW_CATCHES)}"
        )
    speed_scale = _range(
        ep.get("speed_scale", 1.0), "episode.speed_scale", MIN_SPEED_SCALE, 1.0, where
    )
    robot = _get(data, "episode", "robot", str, "ur5", where)
    if robot not in ROBOT_NAMES:
        raise ConfigError(
            f"{where}: episode.robot = {robot!r} is unknown; allowed: {', '.join(ROBOT_NAMES)}"
        )
    time_step = ep.get("time_step")
    if time_step is not None:
        time_step = _range(time_step, "episode.time_step", MIN_TIME_STEP, MAX_TIME_STEP, where)

    def loop_checked(table: dict[str, Any]) -> dict[str, LoopOptionValue]:
        checked = check_loop_options(table)
        for garment in garments:  # each garment's loop reads only its own
            check_loop_options(checked, garment)
        return checked

    loop_options = _option_table(data, "loop_options", loop_checked, where)
    try:
        cloth_options = tuple(check_cloth_options(data.get("cloth", {})).items())
    except ConfigError as exc:
        raise ConfigError(f"{where}: [cloth] {exc}") from None
    flatten_options = _option_table(data, "flatten_options", check_flatten_options, where)
    layout = layout_items(data.get("layout", {}))
    layout_from_table(dict(layout), f"{where}: [layout]")  # checked here, named by the file
    ravens = _get(data, "reference", "ravens_speed", bool, True, where)

    specs = [
        EpisodeSpec(
            garment=garment,
            recipe=recipe,
            perception=perception,
            loop=loop,
            seed=seed,
            towel_width=width,
            towel_height=height,
            towel_resolution=resolution,
            towel_odd_grid=odd_grid,
            towel_max_vertices=max_vertices,
            towel_side_range=side_range,
            position_jitter=jitter,
            yaw_deg=yaw,
            garment_yaw_deg=garment_yaw,
            retries=retries,
            video_fps=video_fps,
            start=start,
            park=park,
            time_step=time_step,
            arms=arms,
            jaw_catch=jaw_catch,
            speed_scale=speed_scale,
            robot=robot,
            loop_options=loop_options,
            cloth_options=cloth_options,
            flatten_options=flatten_options,
            replicate=replicate,
            layout=layout,
        )
        for garment, recipe, perception, loop, seed, replicate in itertools.product(
            garments, recipes, perceptions, loops, seeds, range(replicates)
        )
    ]
    for spec in {(spec.garment, spec.perception): spec for spec in specs}.values():
        try:  # anything EpisodeConfig refuses is refused here, before any run
            spec.to_config()
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
    randomised = {
        "towel_side_m": list(side_range) if side_range else None,
        "towel_fixed_m": None if side_range else [width, height],
        "towel_resolution": resolution,
        "towel_odd_grid": odd_grid,
        "towel_max_vertices": max_vertices,
        "position_jitter_m": jitter,
        "yaw_deg": yaw,
        "garment_yaw_deg": garment_yaw if set(garments) - {"towel"} else None,
        "text": "; ".join(
            [
                *(
                    [
                        (
                            f"towel sides uniform in [{side_range[0]:g}, {side_range[1]:g}] m each"
                            if side_range
                            else f"towel {width:g} × {height:g} m (fixed)"
                        )
                        + f", {resolution} vertices along the longer side"
                        + (" (odd counts: vertex rows on both midlines)" if odd_grid else "")
                        + (
                            f", at most {max_vertices} vertices (fewer along the longer side "
                            "where that would give more)"
                            if max_vertices is not None
                            else ""
                        )
                    ]
                    if "towel" in garments
                    else []
                ),
                *(
                    f"{g} size drawn from foldbot.garments.{g}'s ranges (children's sizes)"
                    for g in garments
                    if g != "towel"
                ),
                f"centre ±{jitter * 100:g} cm in x and y; yaw ±{yaw:g}°"
                + (
                    f" (garments about a {garment_yaw:g}° base yaw)"
                    if set(garments) - {"towel"}
                    else ""
                ),
                *(
                    ["crumpled by the seed, flattened by the robot, then folded"]
                    if start != "flat"
                    else []
                ),
            ]
        ),
    }
    return Suite(
        name=name,
        description=description,
        episodes=tuple(specs),
        axes={
            "garment": garments,
            "recipe": recipes,
            "perception": perceptions,
            "loop": loops,
            "seeds": seeds,
            "replicates": replicates,
        },
        randomised=randomised,
        ravens_speed=ravens,
        source=source,
    )
