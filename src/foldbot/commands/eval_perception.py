"""`foldbot eval-perception`: score the vision estimator against simulator ground truth.

Renders N randomised scenes and compares `VisionEstimator` with the `GroundTruthOracle`:
- Randomised per scene: towel size (0.2–0.45 m per side, independent, so the aspect varies;
  `--towel-sides LO HI` draws from another range),
  position within the workspace, rotation over the full circle, cloth and table colour (a quarter
  of the scenes with a cloth colour close to the table's, where depth alone must find it),
  lighting (direction, colour, ambient/diffuse/specular, shadows), camera pose jitter (±3 cm
  eye and target, ±3° roll), depth noise (σ = a·z², a ≤ 0.0015 /m), depth dropouts, RGB noise,
  flat or folded in half (a mesh whose one half is already reflected onto the other, settled), and
  an arm over the workspace in some scenes (otherwise parked out of view, pan turned by π).
- Corner error (mm): 3-D distance between each vision corner and the oracle's corner of the same
  label. Flat scenes are compared with the mesh's corner vertices; folded scenes with the corners
  of the cloth's top-view outline (`GroundTruthOracle.outline_corners`), since two of a folded
  towel's four outline corners are fold-line ends, not mesh corners. The headline
  `corner_error_mm` is over flat scenes (the targets are for flat towels); `by_state` has both.
- `mask_iou`: vision mask vs the cloth pixels of the simulator's segmentation buffer, over the
  pixels the robot does not cover (the vision mask includes cloth hidden under the arm;
  undetected scenes count 0).
- `ms_per_frame`: wall time of `VisionEstimator.estimate` only (no rendering, no physics), mean
  over scenes after one warm-up call; `ms_per_frame_best`: the mean of each frame's fastest of
  3 runs, less sensitive to other work on the machine.
- `label_agreement`: share of detected scenes whose label matching is also the best cyclic
  matching (a flip near the rule's 45° ties shows up here and as a large corner error).
- Scenes whose physics diverges are reported in `sim_failures` and left out of every figure.

`--garment tshirt` / `--garment pants` scores `GarmentEstimator` instead, on flat garments:
- Randomised per scene: a garment drawn from its children's-size ranges (`TShirtSpec.sample`,
  `PantsSpec.sample`), yaw 90° ± 15° (top towards the robot, as the fold pipeline places it),
  centre within 3 cm of the workspace centre, settled; colours, lighting, camera jitter and
  noise as for towels; no arm unless `--arm-fraction` asks for it (`--arm-pose home`: the
  gripper where the one-arm cell parks while it looks, 25 cm over the workspace centre, so over
  the garment's top, as in the garment suites' frames); never folded.
- Per keypoint (`by_keypoint`): `detection_rate` (share of scenes where it was found) and
  `error_mm` (3-D distance to the mesh keypoint of the same name, `GroundTruthOracle
  .keypoint_positions`: median, mean, p95, max); overall `keypoint_error_mm` and
  `keypoint_detection_rate`; `mask_iou` and `ms_per_frame` as above.
  Measured (seed 0, 20 scenes each, 640×480): T-shirt median 0.31 mm, p95 1.11 mm, max 1.64 mm;
  pants median 0.29 mm, p95 1.01 mm, max 2.74 mm (the crotch); every keypoint found. With the
  arm at home in every scene (`--arm-fraction 1 --arm-pose home --scenes 40`): every garment
  recognised, pants max 4.8 mm; T-shirts max 1.9 mm, the neck left out on the 2 whose neckline
  the gripper hides (a keypoint the arm hides that no other outline gives is not guessed).

`--layout FILE.toml` (either kind): the scenes in that cell, as `foldbot fold --layout` builds
it (the towel on its table in its workspace, its arm, the camera moved with the workspace).
`--camera-pose CALIBRATION.json`: every scene seen from the camera a calibration found
(`foldbot ros-calibrate`: its pose, and its image size and intrinsics where the file keeps
them), without the ±3 cm jitter: perception's accuracy from where a real camera stands. A
calibration solved on the simulated cell (`foldbot calibrate`) also knows where the camera truly
stood (its `truth`): the scenes are rendered from there and perceived from the pose the
calibration found, so the calibration's own error counts in the figures; any other calibration's
pose is taken as exact.

`--depth-sensor M` (either kind): the depth comes from a sensor M m beside the colour camera, as
on a real RGB-D camera (`depth_sensor_config`), registered onto the colour image
(`perception.register`) before the estimator sees it. Measured at 25 mm: flat towels median
0.35 mm, p95 1.74 mm (seed 1, 100 scenes); T-shirts 0.40 / 2.48 mm, pants 0.40 / 1.57 mm.
"""

from __future__ import annotations

import argparse
import dataclasses
import heapq
import json
import math
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import imageio.v3 as iio
import numpy as np

from foldbot.calibration.hand_eye import pose_error_record
from foldbot.errors import ConfigError, FoldbotError, SimulationDivergedError
from foldbot.garments import GARMENT_KEYPOINTS, make_garment, sample_garment
from foldbot.garments.mesh import ClothMesh
from foldbot.garments.pants import PantsSpec
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.garments.tshirt import TShirtSpec
from foldbot.io.staging import commit_output, prepare_output
from foldbot.metrics import keypoint_errors_mm
from foldbot.perception.estimator import VisionEstimator
from foldbot.perception.garment_keypoints import GarmentEstimator
from foldbot.perception.keypoints import CORNER_LABELS
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.register import register_depth
from foldbot.perception.state import ClothState, mask_iou
from foldbot.sim.camera import (
    DEFAULT_EYE,
    DEFAULT_TARGET,
    DEFAULT_UP,
    CameraConfig,
    Lighting,
    RGBDCamera,
)
from foldbot.sim.cloth import ClothConfig, SoftCloth, settle
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout, load_layout
from foldbot.sim.oracle import GroundTruthOracle
from foldbot.sim.robots import make_robot
from foldbot.sim.robots.base import HOME_HEIGHT_ABOVE_TABLE
from foldbot.sim.world import SimConfig, SimWorld
from foldbot.types import Observation

if TYPE_CHECKING:
    from foldbot.layout_check import CameraPlacement

GARMENTS = ("towel", "tshirt", "pants")
"""Garments eval-perception can render."""
FOLDED_FRACTION = 0.3
"""Default share of folded towels (garments are always flat)."""
ARM_FRACTION = {"towel": 0.4, "tshirt": 0.0, "pants": 0.0}
"""Default share of scenes with the arm over the workspace, by garment."""
ARM_POSES = ("anywhere", "home")
"""Where a scene's arm is (`--arm-pose`): its TCP anywhere over the workspace, 12–35 cm above
the table, or at home, gripper down 25 cm over the workspace centre, where the one-arm cell
parks while its camera looks at a garment."""
GARMENT_YAW = (math.pi / 2, math.radians(15.0))
"""T-shirts and pants lie at yaw 90° ± 15° (top towards the robot), as the fold pipeline places them
by default (`--garment-yaw-range` widens the spread, up to 180°: any direction)."""
GARMENT_JITTER = 0.03
"""Largest shift (m) of a garment's centre from the workspace centre, as the pipeline's."""
TOWEL_SIDES = (0.2, 0.45)
"""Default range (m) each towel side is drawn from: the suites' 25–45 cm and smaller."""
MAX_TOWEL_SIDE = 0.7
"""Largest towel side (m) `--towel-sides` accepts: a 70 cm towel fills the camera's view."""
TIMING_REPEATS = 3
"""Each frame is estimated this many times: `ms` is the first run, `ms_best` the fastest."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare eval-perception's command-line options on `parser`."""
    parser.add_argument("--scenes", type=int, default=100, help="number of scenes (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument(
        "--save-overlays",
        type=int,
        default=0,
        metavar="K",
        help="write overlays of the K worst scenes to OUT/overlays (default 0)",
    )
    parser.add_argument("--garment", choices=GARMENTS, default="towel", help="garment kind")
    parser.add_argument("--width", type=int, default=None, help="image width (px; default 640)")
    parser.add_argument("--height", type=int, default=None, help="image height (px; default 480)")
    parser.add_argument(
        "--layout",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="the cell's layout (as for foldbot fold): the scenes lie in its workspace on its "
        "table, its arm stands where it says, the camera moves with the workspace",
    )
    parser.add_argument(
        "--camera-pose",
        type=Path,
        default=None,
        metavar="CALIBRATION.json",
        help="render every scene from the camera a calibration found (its pose, and its image "
        "size and intrinsics where the file keeps them) instead of the default camera jittered "
        "±3 cm: perception's accuracy from where your camera is; a calibration solved on the "
        "simulated cell (foldbot calibrate) renders from its true pose and perceives from the "
        "one it found, so its error counts",
    )
    parser.add_argument(
        "--folded-fraction",
        type=float,
        default=None,
        help=f"share of scenes with the towel folded in half (default {FOLDED_FRACTION}; "
        "T-shirts and pants: 0, always flat)",
    )
    parser.add_argument(
        "--arm-fraction",
        type=float,
        default=None,
        help="share of scenes with the arm over the workspace (default 0.4 for towels, 0 for "
        "T-shirts and pants)",
    )
    parser.add_argument(
        "--arm-pose",
        choices=ARM_POSES,
        default="anywhere",
        help="where those scenes' arm is: its gripper anywhere over the workspace, 12–35 cm up "
        "(default), or at home, 25 cm over the workspace centre, where the one-arm cell parks "
        "while it looks (`--arm-fraction 1 --arm-pose home`: the garment suites' first frames)",
    )
    parser.add_argument(
        "--towel-sides",
        type=float,
        nargs=2,
        default=list(TOWEL_SIDES),
        metavar=("LO", "HI"),
        help="each towel side drawn uniformly from LO to HI m (default %(default)s: the suites' "
        f"25–45 cm and smaller; at most {MAX_TOWEL_SIDE} m, where a towel fills the view)",
    )
    parser.add_argument(
        "--resolution", type=int, default=16, help="towel mesh vertices per long side (default 16)"
    )
    parser.add_argument(
        "--edge-length",
        type=float,
        default=None,
        help="T-shirt / pants mesh edge length in m (default: the spec's, 0.025)",
    )
    parser.add_argument(
        "--depth-sensor",
        type=float,
        default=None,
        metavar="M",
        help="render depth with a sensor M metres to the colour camera's left, as on a real "
        "RGB-D camera (turned 1°, 424 × 240 at 640 × 480 with a wider view), and register it "
        f"onto the colour image as the perception node does (0 < M ≤ {MAX_DEPTH_BASELINE}; "
        "default: depth rendered at the colour camera, as the cell's)",
    )
    parser.add_argument(
        "--garment-yaw-range",
        type=float,
        default=math.degrees(GARMENT_YAW[1]),
        metavar="DEG",
        help="T-shirts and pants lie at yaw 90° ± DEG (default 15; 180: any direction)",
    )


@dataclass(frozen=True)
class SceneLook:
    """How a scene looks besides the cloth's shape and pose, drawn alike for towel and garment
    scenes (_sample_look): colours, the arm, the camera, sensor noise, lighting (SI units,
    colours RGB 0..1)."""

    cloth_rgb: tuple[float, float, float]
    table_rgb: tuple[float, float, float]
    similar_colour: bool
    arm_target: tuple[float, float, float] | None
    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    roll: float
    depth_noise: float
    depth_dropout: float
    rgb_noise: float
    lighting: Lighting


@dataclass(frozen=True)
class Scene(SceneLook):
    """The randomised parameters of one evaluation scene (SI units, colours RGB 0..1)."""

    index: int
    state: str
    towel_width: float
    towel_height: float
    fold_axis: str
    yaw: float
    x: float
    y: float


@dataclass(frozen=True)
class GarmentScene(SceneLook):
    """The randomised parameters of one flat T-shirt or pants scene (SI units, colours RGB 0..1)."""

    index: int
    garment: str
    spec: TShirtSpec | PantsSpec
    yaw: float
    x: float
    y: float

    @property
    def state(self) -> str:
        """Always "flat"."""
        return "flat"


def sample_garment_scene(
    rng: np.random.Generator,
    index: int,
    garment: str,
    arm_fraction: float = 0.0,
    edge_length: float | None = None,
    yaw_range: float = GARMENT_YAW[1],
    arm_pose: str = "anywhere",
    layout: CellLayout = DEFAULT_LAYOUT,
) -> GarmentScene:
    """Draw one T-shirt or pants scene: a garment from its realistic ranges, yaw 90° ± `yaw_range`
    (rad; default 15°), its centre within 3 cm of the `layout`'s workspace centre (less if it
    would leave the workspace), and the towel scenes' colours, arm, camera jitter, noise and
    lighting."""
    if garment not in ("tshirt", "pants"):
        raise ConfigError(f"garment scenes are 'tshirt' or 'pants', got {garment!r}")
    lay = layout
    spec, mesh = sample_garment(garment, rng, edge_length)
    yaw = float(GARMENT_YAW[0] + rng.uniform(-yaw_range, yaw_range))
    c, s = math.cos(yaw), math.sin(yaw)
    xy = mesh.vertices[:, :2] @ np.array([[c, s], [-s, c]])
    ex, ey = np.abs(xy).max(axis=0)
    half = lay.workspace_size / 2
    cx, cy = lay.workspace_center_xy
    x = cx + rng.uniform(-1, 1) * min(GARMENT_JITTER, max(0.0, half - ex))
    y = cy + rng.uniform(-1, 1) * min(GARMENT_JITTER, max(0.0, half - ey))
    look = _sample_look(rng, arm_fraction, arm_pose, layout)
    return GarmentScene(
        index=index, garment=garment, spec=spec, yaw=yaw, x=float(x), y=float(y), **look
    )


def folded_towel(spec: TowelSpec, axis: str = "x", lift: float | None = None) -> ClothMesh:
    """A towel mesh already folded in half across its mesh `axis` ("x": the +x half onto −x).

    The moving half is mirrored onto the other and raised by `lift` (m; default 0.6 edge
    lengths, at least 1 cm, which clears both layers' collision margins of edge/5 — a smaller
    gap starts the layers interpenetrating and can blow the cloth up), then the mesh is
    re-centred; settling it in the simulator gives a folded towel without a robot.
    """
    if axis not in ("x", "y"):
        raise ConfigError(f"fold axis must be 'x' or 'y', got {axis!r}")
    mesh = make_towel(spec)
    if lift is None:
        lift = max(0.01, 0.6 * mesh.edge_length)
    v = mesh.vertices.copy()
    k = 0 if axis == "x" else 1
    moving = v[:, k] > 1e-9
    v[moving, k] = -v[moving, k]
    v[moving, 2] += lift
    v[:, k] -= 0.5 * (v[:, k].max() + v[:, k].min())
    return ClothMesh(v, mesh.faces, dict(mesh.keypoints), mesh.grid_shape)


def _rot_z(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


def sample_scene(
    rng: np.random.Generator,
    index: int,
    folded_fraction: float,
    arm_fraction: float,
    arm_pose: str = "anywhere",
    towel_sides: tuple[float, float] = TOWEL_SIDES,
    layout: CellLayout = DEFAULT_LAYOUT,
) -> Scene:
    """Draw one scene's randomisation (see the module docstring) in `layout`'s workspace; each
    towel side uniform in `towel_sides` (m)."""
    lay = layout
    state = "folded" if rng.random() < folded_fraction else "flat"
    w, h = rng.uniform(*towel_sides, size=2)
    fold_axis = "x" if rng.random() < 0.5 else "y"
    yaw = float(rng.uniform(-math.pi, math.pi))
    # Footprint of the (possibly folded) towel once rotated, to keep it inside the workspace.
    fw = w / 2 if state == "folded" and fold_axis == "x" else w
    fh = h / 2 if state == "folded" and fold_axis == "y" else h
    ex = 0.5 * (abs(fw * math.cos(yaw)) + abs(fh * math.sin(yaw)))
    ey = 0.5 * (abs(fw * math.sin(yaw)) + abs(fh * math.cos(yaw)))
    x0, x1, y0, y1 = lay.workspace_bounds
    cx, cy = lay.workspace_center_xy
    x = cx + rng.uniform(-1, 1) * max(0.0, (x1 - x0) / 2 - ex)
    y = cy + rng.uniform(-1, 1) * max(0.0, (y1 - y0) / 2 - ey)
    look = _sample_look(rng, arm_fraction, arm_pose, layout)
    return Scene(
        index=index,
        state=state,
        towel_width=float(w),
        towel_height=float(h),
        fold_axis=fold_axis,
        yaw=yaw,
        x=float(x),
        y=float(y),
        **look,
    )


def _sample_look(
    rng: np.random.Generator,
    arm_fraction: float,
    arm_pose: str = "anywhere",
    layout: CellLayout = DEFAULT_LAYOUT,
) -> dict[str, Any]:
    """Colours, arm, camera jitter, sensor noise and lighting of one scene (Scene field → value)
    in `layout` (the camera moved with its workspace, as the cell's); the arm (`arm_pose`,
    ARM_POSES) moves nothing else: the same draws are made either way."""
    if arm_pose not in ARM_POSES:
        raise ConfigError(f"arm pose must be one of {ARM_POSES}, got {arm_pose!r}")
    lay = layout
    x0, x1, y0, y1 = lay.workspace_bounds
    table = rng.uniform(0.15, 0.85, size=3)
    similar = bool(rng.random() < 0.25)
    cloth = np.clip(table + rng.normal(0.0, 0.03, 3), 0, 1) if similar else rng.uniform(0, 1, 3)
    arm_target = None
    if rng.random() < arm_fraction:
        arm_target = (
            float(rng.uniform(x0, x1)),
            float(rng.uniform(y0, y1)),
            float(lay.table_height + rng.uniform(0.12, 0.35)),
        )
        if arm_pose == "home":
            cx, cy = lay.workspace_center_xy
            arm_target = (cx, cy, lay.table_height + HOME_HEIGHT_ABOVE_TABLE)
    shift = np.array(layout.workspace_shift())
    eye = np.array(DEFAULT_EYE) + shift + rng.uniform(-0.03, 0.03, 3)
    target = np.array(DEFAULT_TARGET) + shift + rng.uniform(-0.03, 0.03, 3)
    direction = rng.normal(size=3)
    direction[2] = abs(direction[2]) + 0.5
    lighting = Lighting(
        direction=tuple(float(v) for v in direction),
        color=tuple(float(v) for v in rng.uniform(0.8, 1.0, 3)),
        distance=2.0,
        ambient=float(rng.uniform(0.4, 0.8)),
        diffuse=float(rng.uniform(0.2, 0.6)),
        specular=float(rng.uniform(0.0, 0.1)),
        shadow=bool(rng.random() < 0.3),
    )
    return {
        "cloth_rgb": tuple(float(v) for v in cloth),
        "table_rgb": tuple(float(v) for v in table),
        "similar_colour": similar,
        "arm_target": arm_target,
        "eye": tuple(float(v) for v in eye),
        "target": tuple(float(v) for v in target),
        "roll": float(rng.uniform(-math.radians(3), math.radians(3))),
        "depth_noise": float(rng.uniform(0.0, 0.0015)),
        "depth_dropout": float(rng.uniform(0.0, 0.01)),
        "rgb_noise": float(rng.uniform(0.0, 4.0)),
        "lighting": lighting,
    }


def _camera_config(
    scene: Scene | GarmentScene,
    width: int,
    height: int,
    seed: int,
    camera: CameraPlacement | None = None,
) -> CameraConfig:
    """The scene's camera: at its jittered eye and target, turned by its roll; or, given
    `camera`, that camera's image size and intrinsics, rendered from where it truly stands and
    perceived from the pose it was given (CameraPlacement.sim_camera; the scene's noise and
    light)."""
    if camera is not None:
        return camera.sim_camera(
            CameraConfig(
                depth_noise=scene.depth_noise,
                depth_dropout=scene.depth_dropout,
                rgb_noise=scene.rgb_noise,
                seed=seed,
                lighting=scene.lighting,
            )
        )
    view = np.array(scene.target) - np.array(scene.eye)
    view /= np.linalg.norm(view)
    up = np.array(DEFAULT_UP, dtype=float)
    # roll: turn the up vector about the optical axis (Rodrigues)
    c, s = math.cos(scene.roll), math.sin(scene.roll)
    up = up * c + np.cross(view, up) * s + view * (view @ up) * (1 - c)
    return CameraConfig(
        width=width,
        height=height,
        eye=scene.eye,
        target=scene.target,
        up=tuple(float(v) for v in up),
        depth_noise=scene.depth_noise,
        depth_dropout=scene.depth_dropout,
        rgb_noise=scene.rgb_noise,
        seed=seed,
        lighting=scene.lighting,
    )


def default_scene(**overrides: Any) -> Scene:
    """A plain scene (flat 0.3 m towel at the workspace centre, default camera and lighting, no
    noise, arm parked); keyword arguments replace fields. Handy for tests and examples."""
    fields: dict[str, Any] = {
        "index": 0,
        "state": "flat",
        "towel_width": 0.3,
        "towel_height": 0.3,
        "fold_axis": "x",
        "yaw": 0.0,
        "x": DEFAULT_LAYOUT.workspace_center_xy[0],
        "y": DEFAULT_LAYOUT.workspace_center_xy[1],
        "cloth_rgb": (0.2, 0.4, 0.85),
        "table_rgb": (0.55, 0.45, 0.35),
        "similar_colour": False,
        "arm_target": None,
        "eye": DEFAULT_EYE,
        "target": DEFAULT_TARGET,
        "roll": 0.0,
        "depth_noise": 0.0,
        "depth_dropout": 0.0,
        "rgb_noise": 0.0,
        "lighting": Lighting(),
    }
    fields.update(overrides)
    return Scene(**fields)


def default_garment_scene(spec: TShirtSpec | PantsSpec, **overrides: Any) -> GarmentScene:
    """A plain flat garment scene (`spec` at the workspace centre, yaw 90°: top towards the robot;
    default camera and lighting, no noise, arm parked); keyword arguments replace fields."""
    base = asdict(default_scene())
    look = {k: base[k] for k in base if k in GarmentScene.__dataclass_fields__}
    look["lighting"] = Lighting()
    fields: dict[str, Any] = {
        **look,
        "garment": "tshirt" if isinstance(spec, TShirtSpec) else "pants",
        "spec": spec,
        "yaw": math.pi / 2,
    }
    fields.update(overrides)
    return GarmentScene(**fields)


@dataclass(frozen=True)
class RenderedScene:
    """One rendered scene: what the camera saw and the simulator's ground truth."""

    obs: Observation
    corners: dict[str, np.ndarray]
    """GROUND TRUTH corners by label: mesh corners (flat) or top-view outline corners (folded);
    for a T-shirt or pants, the mesh's named keypoints."""
    cloth_mask: np.ndarray
    """GROUND TRUTH visible cloth pixels (segmentation buffer)."""
    robot_mask: np.ndarray
    """GROUND TRUTH robot pixels (segmentation buffer)."""


MAX_DEPTH_BASELINE = 0.1
"""The farthest (m) eval-perception's depth sensor may sit from the colour camera."""
DEPTH_SENSOR_SIZE = (0.6625, 0.5)
"""The depth sensor's image as shares of the colour image's width and height (424 × 240 at
640 × 480), as a real RGB-D camera's depth stream is often smaller than its colour one."""
DEPTH_SENSOR_FOCAL = 0.49
"""Its focal length as a share of the colour camera's: a wider view (52° across at 640 × 480,
against 40°), as a depth sensor's usually is."""
DEPTH_SENSOR_ROLL_DEG = 1.0
"""How far it is turned about its optical axis against the colour camera (mounting error)."""


def depth_sensor_config(color: CameraConfig, baseline: float) -> tuple[CameraConfig, np.ndarray]:
    """A depth sensor beside the colour camera `color`, as on a real RGB-D camera: `baseline` m
    to its left, turned DEPTH_SENSOR_ROLL_DEG about the optical axis, with its own, smaller image
    and wider view; its noise as the colour camera's depth. Returns its configuration and
    T_color_depth (its coordinates into the colour camera's)."""
    roll = math.radians(DEPTH_SENSOR_ROLL_DEG)
    T_color_depth = np.eye(4)
    T_color_depth[:3, :3] = [
        [math.cos(roll), -math.sin(roll), 0.0],
        [math.sin(roll), math.cos(roll), 0.0],
        [0.0, 0.0, 1.0],
    ]
    T_color_depth[0, 3] = -baseline
    width = max(16, round(color.width * DEPTH_SENSOR_SIZE[0]))
    height = max(16, round(color.height * DEPTH_SENSOR_SIZE[1]))
    T_world_depth = color.T_world_camera @ T_color_depth
    cfg = dataclasses.replace(
        color,
        width=width,
        height=height,
        fx=color.fx * DEPTH_SENSOR_FOCAL,
        fy=color.fy * DEPTH_SENSOR_FOCAL,
        cx=(width - 1) / 2.0,
        cy=(height - 1) / 2.0,
        pose=tuple(tuple(float(v) for v in row) for row in T_world_depth),
        seed=color.seed + 1,
    )
    return cfg, T_color_depth


def render_scene(
    scene: Scene,
    width: int = 640,
    height: int = 480,
    resolution: int = 16,
    seed: int = 0,
    settle_time: float | None = None,
    depth_baseline: float | None = None,
    layout: CellLayout = DEFAULT_LAYOUT,
    camera: CameraPlacement | None = None,
) -> RenderedScene:
    """Build, settle and render `scene` in the cell `layout` lays out and read its ground truth.

    The corners are the mesh corners for a flat towel and the top-view outline corners for a
    folded one. `settle_time` (s) defaults to 1.0 flat / 1.5 folded; 0 renders the towel as
    spawned (after one physics step: flat, ~5 mm above the table), fast enough for unit tests.
    `depth_baseline` (m): the depth comes from a sensor that far beside the colour camera,
    registered onto it (depth_sensor_config). `camera`: render from that camera (its pose,
    size and intrinsics) instead of the scene's.
    """
    spec = TowelSpec(scene.towel_width, scene.towel_height, resolution)
    mesh = folded_towel(spec, scene.fold_axis) if scene.state == "folded" else make_towel(spec)
    if settle_time is None:
        settle_time = 1.5 if scene.state == "folded" else 1.0

    def truth(oracle: GroundTruthOracle) -> dict[str, np.ndarray]:
        return oracle.labelled_corners() if scene.state == "flat" else oracle.outline_corners()

    return _render(
        scene, mesh, truth, width, height, seed, settle_time, depth_baseline, layout, camera
    )


def render_garment_scene(
    scene: GarmentScene,
    width: int = 640,
    height: int = 480,
    seed: int = 0,
    settle_time: float = 1.0,
    depth_baseline: float | None = None,
    layout: CellLayout = DEFAULT_LAYOUT,
    camera: CameraPlacement | None = None,
) -> RenderedScene:
    """Build, settle and render a garment scene (in `layout`'s cell, from `camera` where given,
    as render_scene); the ground truth is the mesh's named keypoints.

    `settle_time` 0 renders the garment as spawned (after one physics step), for unit tests.
    """
    mesh = make_garment(scene.spec)
    return _render(
        scene,
        mesh,
        lambda oracle: oracle.keypoint_positions(),
        width,
        height,
        seed,
        settle_time,
        depth_baseline,
        layout,
        camera,
    )


def _render(
    scene: Scene | GarmentScene,
    mesh: ClothMesh,
    truth: Callable[[GroundTruthOracle], dict[str, np.ndarray]],
    width: int,
    height: int,
    seed: int,
    settle_time: float,
    depth_baseline: float | None = None,
    layout: CellLayout = DEFAULT_LAYOUT,
    camera: CameraPlacement | None = None,
) -> RenderedScene:
    """Place `mesh` as the scene says (pose, colours, arm, camera, lighting) in `layout`'s cell,
    settle, render (from `camera` where given); with `depth_baseline`, the depth from a sensor
    beside the camera, registered onto it."""
    lay = layout
    rgba = (*scene.table_rgb, 1.0)
    with SimWorld(SimConfig(table_rgba=rgba, layout=layout)) as world:
        robot = make_robot("ur5", world.client, world.layout)
        if scene.arm_target is not None:
            try:
                q = robot.solve_ik(list(scene.arm_target), q_seed=robot.home_q)
            except FoldbotError:
                q = robot.home_q
        else:
            q = np.array(robot.home_q)
            q[0] += math.pi  # parked: the arm turned away from the table, out of view
        robot.reset_joints(q)
        cloth = SoftCloth(
            world.client,
            mesh,
            ClothConfig(rgba=(*scene.cloth_rgb, 1.0)),
            lay.table_height,
            (scene.x, scene.y),
            scene.yaw,
        )
        if settle_time > 0:
            settle(world, cloth, max_time=settle_time)
        else:
            world.step(1)  # PyBullet draws a soft body only once the world has stepped
        cloth.check_finite_and_bounded(lay.workspace_center_xy, 1.0)
        rgbd = RGBDCamera(world.client, _camera_config(scene, width, height, seed, camera))
        obs = rgbd.observe(joint_positions=robot.joint_positions(), stamp=world.sim_time)
        if depth_baseline is not None:
            depth_cfg, T_color_depth = depth_sensor_config(rgbd.config, depth_baseline)
            seen = RGBDCamera(world.client, depth_cfg).observe(stamp=world.sim_time)
            registered = register_depth(
                seen.depth,
                depth_cfg.K,
                rgbd.config.K,
                T_color_depth,
                (rgbd.config.width, rgbd.config.height),
            )
            obs = dataclasses.replace(obs, depth=registered)
        oracle = GroundTruthOracle(cloth, rgbd)
        corners = truth(oracle)
        seg = rgbd.render_segmentation()  # ground truth, read here for the IoU only
        return RenderedScene(obs, corners, seg == cloth.body_id, seg == robot.body_id)


def _stats(values: list[float]) -> dict[str, float | int | None]:
    if not values:
        return {"median": None, "p95": None, "max": None, "n": 0}
    a = np.asarray(values, dtype=float)
    return {
        "median": float(np.median(a)),
        "p95": float(np.percentile(a, 95)),
        "max": float(a.max()),
        "n": len(values),
    }


def _label_ok(state: ClothState, truth: dict[str, np.ndarray]) -> bool:
    est = np.array([state.keypoints[n][0] for n in CORNER_LABELS])
    gt = np.array([truth[n] for n in CORNER_LABELS])
    costs = [np.linalg.norm(est - np.roll(gt, s, axis=0), axis=1).sum() for s in range(4)]
    return int(np.argmin(costs)) == 0


def _group(rows: list[dict[str, Any]]) -> dict[str, Any]:
    detected = [r for r in rows if r["detected"]]
    errors = [e for r in detected for e in r["corner_error_mm"].values()]
    ms = [r["ms"] for r in rows]
    best = [r["ms_best"] for r in rows]
    return {
        "scenes": len(rows),
        "corner_error_mm": _stats(errors),
        "detection_rate": len(detected) / len(rows) if rows else None,
        "mask_iou": float(np.mean([r["mask_iou"] for r in rows])) if rows else None,
        "ms_per_frame": float(np.mean(ms)) if ms else None,
        "ms_per_frame_p95": float(np.percentile(ms, 95)) if ms else None,
        "ms_per_frame_best": float(np.mean(best)) if best else None,
        "label_agreement": (
            float(np.mean([r["label_ok"] for r in detected])) if detected else None
        ),
    }


def _print_table(summary: dict[str, Any], worst: list[dict[str, Any]]) -> None:
    def fmt(v: Any, spec: str) -> str:
        if v is None:
            width = spec.lstrip("<>^").split(".")[0]
            return format("—", f">{width}") if width.isdigit() else "—"
        return format(v, spec)

    print(
        f"eval-perception: {summary['scenes']} scenes, seed {summary['seed']}, "
        f"{summary['width']}×{summary['height']}{_cell_words(summary)}"
    )
    header = (
        f"{'state':<8}{'scenes':>7}{'detect':>8}{'median mm':>11}{'p95 mm':>9}{'max mm':>9}"
        f"{'IoU':>7}{'labels':>8}{'ms/frame':>10}{'best ms':>9}"
    )
    print(header)
    print("-" * len(header))
    for name, g in summary["by_state"].items():
        ce = g["corner_error_mm"]
        print(
            f"{name:<8}{g['scenes']:>7}{fmt(g['detection_rate'], '>8.1%')}"
            f"{fmt(ce['median'], '>11.2f')}{fmt(ce['p95'], '>9.2f')}{fmt(ce['max'], '>9.2f')}"
            f"{fmt(g['mask_iou'], '>7.3f')}{fmt(g['label_agreement'], '>8.1%')}"
            f"{fmt(g['ms_per_frame'], '>10.1f')}{fmt(g['ms_per_frame_best'], '>9.1f')}"
        )
    ce = summary["corner_error_mm"]
    print(
        f"headline (flat towels): corner error median {fmt(ce['median'], '.2f')} mm, "
        f"p95 {fmt(ce['p95'], '.2f')} mm, max {fmt(ce['max'], '.2f')} mm; "
        f"detection {fmt(summary['detection_rate'], '.1%')}; "
        f"{fmt(summary['ms_per_frame'], '.1f')} ms/frame "
        f"(best of {TIMING_REPEATS}: {fmt(summary['ms_per_frame_best'], '.1f')})"
    )
    if worst:
        items = [
            f"#{r['index']} ("
            + ("not detected" if r["score"] is None else f"{r['score']:.1f} mm")
            + ")"
            for r in worst
        ]
        print("worst scenes: " + ", ".join(items))
    if summary["sim_failures"]:
        print(f"left out (physics diverged): {summary['sim_failures']}")


def _with_defaults(args: argparse.Namespace) -> argparse.Namespace:
    """A copy of `args` with the garment-dependent defaults (folded and arm fractions) filled in."""
    out = argparse.Namespace(**vars(args))
    garment = getattr(out, "garment", "towel")
    if getattr(out, "folded_fraction", None) is None:
        out.folded_fraction = FOLDED_FRACTION if garment == "towel" else 0.0
    if getattr(out, "arm_fraction", None) is None:
        out.arm_fraction = ARM_FRACTION.get(garment, 0.0)
    if not hasattr(out, "edge_length"):
        out.edge_length = None
    if not hasattr(out, "arm_pose"):
        out.arm_pose = "anywhere"
    if not hasattr(out, "garment_yaw_range"):
        out.garment_yaw_range = math.degrees(GARMENT_YAW[1])
    if not hasattr(out, "depth_sensor"):
        out.depth_sensor = None
    layout_file = getattr(out, "layout", None)
    out.cell_layout = DEFAULT_LAYOUT if layout_file is None else load_layout(layout_file)
    out.camera = None
    if getattr(out, "camera_pose", None) is not None:
        from foldbot.commands.check_layout import camera_placement

        if out.width is not None or out.height is not None:
            raise ConfigError(
                "--width and --height are the calibration's with --camera-pose (its camera_info, "
                "or 640 × 480 where it has none); give one or the other"
            )
        out.camera = camera_placement(out.camera_pose, out.cell_layout)
        out.width, out.height = out.camera.width, out.camera.height
    if out.width is None:
        out.width = 640
    if out.height is None:
        out.height = 480
    return out


def _validate(args: argparse.Namespace) -> None:
    checks = [
        (
            isinstance(args.scenes, int) and args.scenes > 0,
            f"--scenes must be > 0, got {args.scenes}",
        ),
        (
            isinstance(args.save_overlays, int) and args.save_overlays >= 0,
            f"--save-overlays must be ≥ 0, got {args.save_overlays}",
        ),
        (args.garment in GARMENTS, f"--garment must be one of {GARMENTS}, got {args.garment!r}"),
        (
            0.0 <= args.folded_fraction <= 1.0,
            f"--folded-fraction must be in [0, 1], got {args.folded_fraction}",
        ),
        (
            args.garment == "towel" or args.folded_fraction == 0.0,
            f"--folded-fraction must be 0 for --garment {args.garment} (only towels are "
            f"rendered folded), got {args.folded_fraction}",
        ),
        (
            0.0 <= args.arm_fraction <= 1.0,
            f"--arm-fraction must be in [0, 1], got {args.arm_fraction}",
        ),
        (
            args.arm_pose in ARM_POSES,
            f"--arm-pose must be one of {ARM_POSES}, got {args.arm_pose!r}",
        ),
        (
            0.0 <= args.garment_yaw_range <= 180.0,
            f"--garment-yaw-range must be in [0, 180] degrees, got {args.garment_yaw_range}",
        ),
        (
            0.05 <= args.towel_sides[0] <= args.towel_sides[1] <= MAX_TOWEL_SIDE,
            f"--towel-sides must be LO HI with 0.05 ≤ LO ≤ HI ≤ {MAX_TOWEL_SIDE} m, "
            f"got {args.towel_sides[0]} {args.towel_sides[1]}",
        ),
        (
            args.garment == "towel" or list(args.towel_sides) == list(TOWEL_SIDES),
            f"--towel-sides is for --garment towel, got {args.towel_sides[0]} "
            f"{args.towel_sides[1]} with --garment {args.garment}",
        ),
        (
            args.depth_sensor is None
            or (math.isfinite(args.depth_sensor) and 0.0 < args.depth_sensor <= MAX_DEPTH_BASELINE),
            f"--depth-sensor must be in (0, {MAX_DEPTH_BASELINE}] m, got {args.depth_sensor}",
        ),
        (
            args.garment != "towel" or args.garment_yaw_range == math.degrees(GARMENT_YAW[1]),
            "--garment-yaw-range is for --garment tshirt or pants; towel scenes draw their own "
            f"yaw, got {args.garment_yaw_range}",
        ),
    ]
    for ok, message in checks:
        if not ok:
            raise ConfigError(message)
    CameraConfig(width=args.width, height=args.height)  # ConfigError names a bad size
    TowelSpec(resolution=args.resolution)
    if args.edge_length is not None:
        # The specs' own checks name a bad edge length.
        TShirtSpec(edge_length=args.edge_length)


def run(args: argparse.Namespace) -> int:
    """Run the evaluation: 0 on success, 2 (message on stderr) for bad arguments or --out."""
    try:
        args = _with_defaults(args)
        _validate(args)
        out = Path(args.out)
        stage = prepare_output(out)
    except FoldbotError as exc:
        print(f"foldbot eval-perception: error: {exc}", file=sys.stderr)
        return 2
    try:
        _evaluate(args, stage)
        commit_output(stage, out)
    except OSError as exc:
        shutil.rmtree(stage, ignore_errors=True)
        print(f"foldbot eval-perception: error: cannot write {out}: {exc}", file=sys.stderr)
        return 2
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    return 0


def _evaluate(args: argparse.Namespace, stage: Path) -> dict[str, Any]:
    if args.garment != "towel":
        return _evaluate_garment(args, stage)
    from tqdm import tqdm

    estimator = VisionEstimator()
    rows: list[dict[str, Any]] = []
    failures: list[int] = []
    keep = int(args.save_overlays)
    worst_heap: list[tuple[float, int, Observation, ClothState, dict[str, np.ndarray]]] = []
    for i in tqdm(range(args.scenes), desc="eval-perception", unit="scene", file=sys.stderr):
        rng = np.random.default_rng([args.seed, i])
        scene = sample_scene(
            rng,
            i,
            args.folded_fraction,
            args.arm_fraction,
            args.arm_pose,
            tuple(args.towel_sides),
            args.cell_layout,
        )
        try:
            rendered = render_scene(
                scene,
                args.width,
                args.height,
                args.resolution,
                seed=args.seed * 100003 + i,
                depth_baseline=args.depth_sensor,
                layout=args.cell_layout,
                camera=args.camera,
            )
        except SimulationDivergedError:
            failures.append(i)
            continue
        obs, truth = rendered.obs, rendered.corners
        # The vision mask includes cloth hidden under the arm; score the pixels the arm leaves
        # visible, where the segmentation buffer knows the answer.
        seen = ~rendered.robot_mask
        if not rows:
            estimator.estimate(obs)  # warm-up (imports, caches): a running robot is warm
        times = []
        for _ in range(TIMING_REPEATS):
            t0 = time.perf_counter()
            state = estimator.estimate(obs)
            times.append(1000.0 * (time.perf_counter() - t0))
        row: dict[str, Any] = {
            "index": i,
            "state": scene.state,
            "detected": state.detected,
            "reason": state.reason,
            "ms": times[0],
            "ms_best": min(times),
            "mask_iou": mask_iou(state.mask & seen, rendered.cloth_mask) if state.detected else 0.0,
            "corner_error_mm": {},
            "confidence": {},
            "label_ok": False,
            "scene": _scene_record(scene, args.camera, ("index", "state")),
        }
        if state.detected:
            seen = {name: state.keypoints[name][0] for name in CORNER_LABELS}
            row["corner_error_mm"] = keypoint_errors_mm(seen, truth)
            row["confidence"] = {name: state.keypoints[name][1] for name in CORNER_LABELS}
            row["label_ok"] = _label_ok(state, truth)
        score = max(row["corner_error_mm"].values()) if state.detected else math.inf
        row["score"] = score if math.isfinite(score) else None  # None: not detected
        rows.append(row)
        if keep:
            item = (score, i, obs, state, truth)
            if len(worst_heap) < keep:
                heapq.heappush(worst_heap, item)
            elif score > worst_heap[0][0]:
                heapq.heapreplace(worst_heap, item)

    if not rows:
        raise ConfigError("every scene's physics diverged; nothing to score")
    flat = [r for r in rows if r["state"] == "flat"]
    folded = [r for r in rows if r["state"] == "folded"]
    everything = _group(rows)
    headline = _group(flat) if flat else everything
    summary: dict[str, Any] = {
        "scenes": len(rows),
        "seed": args.seed,
        "garment": args.garment,
        "width": args.width,
        "height": args.height,
        "folded_fraction": args.folded_fraction,
        "arm_fraction": args.arm_fraction,
        "arm_pose": args.arm_pose,
        "towel_sides_m": list(args.towel_sides),
        "depth_sensor_baseline_m": args.depth_sensor,
        **_cell_record(args),
        "corner_error_mm": headline["corner_error_mm"],
        "corner_error_scope": "flat scenes, vs mesh corners" if flat else "all scenes",
        "detection_rate": everything["detection_rate"],
        "mask_iou": everything["mask_iou"],
        "ms_per_frame": everything["ms_per_frame"],
        "ms_per_frame_p95": everything["ms_per_frame_p95"],
        "ms_per_frame_best": everything["ms_per_frame_best"],
        "label_agreement": everything["label_agreement"],
        "by_state": {"all": everything, "flat": _group(flat), "folded": _group(folded)},
        "sim_failures": failures,
        "rows": rows,
    }
    (stage / "summary.json").write_text(
        json.dumps(summary, indent=2, default=_json_default, allow_nan=False) + "\n"
    )
    worst = sorted(worst_heap, key=lambda t: (-t[0], t[1]))
    if worst:
        odir = stage / "overlays"
        odir.mkdir()
        for score, i, obs, state, truth in worst:
            del score
            img = draw_overlay(obs, state, reference=truth)
            iio.imwrite(odir / f"scene_{i:04d}.png", img)
    _print_table(summary, sorted(rows, key=_badness, reverse=True)[:5])
    return summary


def _scene_record(
    scene: Scene | GarmentScene, camera: CameraPlacement | None, leave: tuple[str, ...]
) -> dict[str, Any]:
    """A row's scene as summary.json keeps it: without `leave`, and without the jittered camera
    a fixed one (--camera-pose) replaced."""
    if camera is not None:
        leave = (*leave, "eye", "target", "roll")
    return {k: v for k, v in asdict(scene).items() if k not in leave}


def _cell_record(args: argparse.Namespace) -> dict[str, Any]:
    """The cell the scenes were rendered in: the layout's changes from the default cell's and the
    camera (`jittered`: the default camera, ±3 cm a scene; else the calibration's)."""
    camera: dict[str, Any] = {"source": "the default camera, jittered ±3 cm and ±3° a scene"}
    if args.camera is not None:
        camera = {
            "source": args.camera.source,
            "T_world_camera": args.camera.T_world_camera.tolist(),
            "K": args.camera.K.tolist(),
        }
        true = args.camera.true_T_world_camera
        if true is not None:
            camera |= {
                "true_T_world_camera": true.tolist(),
                **pose_error_record(args.camera.T_world_camera, true),
            }
    layout_file = getattr(args, "layout", None)
    return {
        "layout": args.cell_layout.changes(),
        "layout_file": None if layout_file is None else str(layout_file),
        "camera": camera,
    }


def _cell_words(summary: dict[str, Any]) -> str:
    """The header's note of a layout or a calibration's camera, where the run had one."""
    words = ""
    if summary.get("layout_file"):
        words += f", layout {summary['layout_file']}"
    camera = summary.get("camera", {})
    if "T_world_camera" in camera:
        words += f"; camera: {camera['source']}"
        if "calibration_error_mm" in camera:
            words += (
                f" (rendered from the true pose, perceived from the calibration's, "
                f"{camera['calibration_error_mm']:.2f} mm and "
                f"{camera['calibration_error_deg']:.3f}° off it)"
            )
    return words


def _stats_mean(values: list[float]) -> dict[str, float | int | None]:
    """_stats plus the mean (the garment summary's error statistics)."""
    out = _stats(values)
    out["mean"] = float(np.mean(values)) if values else None
    return out


def _garment_summary(
    rows: list[dict[str, Any]], names: tuple[str, ...]
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Per-keypoint (detection rate, error statistics) and overall figures of garment rows."""
    by_keypoint = {}
    for name in names:
        errors = [r["keypoint_error_mm"][name] for r in rows if name in r["keypoint_error_mm"]]
        by_keypoint[name] = {
            "detection_rate": len(errors) / len(rows) if rows else None,
            "error_mm": _stats_mean(errors),
        }
    errors = [e for r in rows for e in r["keypoint_error_mm"].values()]
    ms = [r["ms"] for r in rows]
    overall = {
        "scenes": len(rows),
        "keypoint_error_mm": _stats_mean(errors),
        "keypoint_detection_rate": len(errors) / (len(rows) * len(names)) if rows else None,
        "detection_rate": float(np.mean([r["detected"] for r in rows])) if rows else None,
        "mask_iou": float(np.mean([r["mask_iou"] for r in rows])) if rows else None,
        "ms_per_frame": float(np.mean(ms)) if ms else None,
        "ms_per_frame_p95": float(np.percentile(ms, 95)) if ms else None,
        "ms_per_frame_best": float(np.mean([r["ms_best"] for r in rows])) if rows else None,
    }
    return by_keypoint, overall


def _evaluate_garment(args: argparse.Namespace, stage: Path) -> dict[str, Any]:
    """eval-perception for flat T-shirts or pants: `GarmentEstimator` against the mesh keypoints."""
    from tqdm import tqdm

    names = GARMENT_KEYPOINTS[args.garment]
    estimator = GarmentEstimator(args.garment)
    rows: list[dict[str, Any]] = []
    failures: list[int] = []
    keep = int(args.save_overlays)
    worst_heap: list[tuple[float, int, Observation, ClothState, dict[str, np.ndarray]]] = []
    for i in tqdm(range(args.scenes), desc="eval-perception", unit="scene", file=sys.stderr):
        rng = np.random.default_rng([args.seed, i])
        scene = sample_garment_scene(
            rng,
            i,
            args.garment,
            args.arm_fraction,
            args.edge_length,
            math.radians(args.garment_yaw_range),
            args.arm_pose,
            args.cell_layout,
        )
        try:
            rendered = render_garment_scene(
                scene,
                args.width,
                args.height,
                seed=args.seed * 100003 + i,
                depth_baseline=args.depth_sensor,
                layout=args.cell_layout,
                camera=args.camera,
            )
        except SimulationDivergedError:
            failures.append(i)
            continue
        obs, truth = rendered.obs, rendered.corners
        if not rows:
            estimator.estimate(obs)  # warm-up
        times = []
        for _ in range(TIMING_REPEATS):
            t0 = time.perf_counter()
            state = estimator.estimate(obs)
            times.append(1000.0 * (time.perf_counter() - t0))
        seen = ~rendered.robot_mask
        row: dict[str, Any] = {
            "index": i,
            "state": "flat",
            "detected": state.detected,
            "reason": state.reason,
            "ms": times[0],
            "ms_best": min(times),
            "mask_iou": mask_iou(state.mask & seen, rendered.cloth_mask) if state.detected else 0.0,
            "keypoint_error_mm": {},
            "confidence": {},
            "missing": [n for n in names if n not in state.keypoints],
            "scene": _scene_record(scene, args.camera, ("index",)),
        }
        found = [name for name in names if name in state.keypoints]
        row["keypoint_error_mm"] = keypoint_errors_mm(
            {name: state.keypoints[name][0] for name in found}, truth
        )
        row["confidence"] = {name: state.keypoints[name][1] for name in found}
        score = max(row["keypoint_error_mm"].values()) if not row["missing"] else math.inf
        row["score"] = score if math.isfinite(score) else None  # None: a keypoint not found
        rows.append(row)
        if keep:
            item = (score, i, obs, state, truth)
            if len(worst_heap) < keep:
                heapq.heappush(worst_heap, item)
            elif score > worst_heap[0][0]:
                heapq.heapreplace(worst_heap, item)

    if not rows:
        raise ConfigError("every scene's physics diverged; nothing to score")
    by_keypoint, overall = _garment_summary(rows, names)
    summary: dict[str, Any] = {
        "scenes": len(rows),
        "seed": args.seed,
        "garment": args.garment,
        "width": args.width,
        "height": args.height,
        "arm_fraction": args.arm_fraction,
        "arm_pose": args.arm_pose,
        "garment_yaw_range_deg": args.garment_yaw_range,
        "depth_sensor_baseline_m": args.depth_sensor,
        **_cell_record(args),
        **{k: v for k, v in overall.items() if k != "scenes"},
        "by_keypoint": by_keypoint,
        "sim_failures": failures,
        "rows": rows,
    }
    (stage / "summary.json").write_text(
        json.dumps(summary, indent=2, default=_json_default, allow_nan=False) + "\n"
    )
    worst = sorted(worst_heap, key=lambda t: (-t[0], t[1]))
    if worst:
        odir = stage / "overlays"
        odir.mkdir()
        for _, i, obs, state, truth in worst:
            iio.imwrite(odir / f"scene_{i:04d}.png", draw_overlay(obs, state, reference=truth))
    _print_garment_table(summary, sorted(rows, key=_badness, reverse=True)[:5])
    return summary


def _print_garment_table(summary: dict[str, Any], worst: list[dict[str, Any]]) -> None:
    def fmt(v: Any, spec: str) -> str:
        if v is None:
            width = spec.lstrip("<>^").split(".")[0]
            return format("—", f">{width}") if width.isdigit() else "—"
        return format(v, spec)

    print(
        f"eval-perception: {summary['scenes']} flat {summary['garment']} scenes, "
        f"seed {summary['seed']}, {summary['width']}×{summary['height']}{_cell_words(summary)}"
    )
    header = (
        f"{'keypoint':<17}{'detect':>8}{'median mm':>11}{'mean mm':>9}{'p95 mm':>9}{'max mm':>9}"
    )
    print(header)
    print("-" * len(header))
    rows = [*summary["by_keypoint"].items(), ("overall", None)]
    for name, g in rows:
        if g is None:
            rate, e = summary["keypoint_detection_rate"], summary["keypoint_error_mm"]
        else:
            rate, e = g["detection_rate"], g["error_mm"]
        print(
            f"{name:<17}{fmt(rate, '>8.1%')}{fmt(e['median'], '>11.2f')}{fmt(e['mean'], '>9.2f')}"
            f"{fmt(e['p95'], '>9.2f')}{fmt(e['max'], '>9.2f')}"
        )
    print(
        f"garment detection {fmt(summary['detection_rate'], '.1%')}; mask IoU "
        f"{fmt(summary['mask_iou'], '.3f')}; {fmt(summary['ms_per_frame'], '.1f')} ms/frame "
        f"(best of {TIMING_REPEATS}: {fmt(summary['ms_per_frame_best'], '.1f')})"
    )
    if worst:
        print("worst scenes: " + ", ".join(f"#{r['index']} ({_garment_verdict(r)})" for r in worst))
    if summary["sim_failures"]:
        print(f"left out (physics diverged): {summary['sim_failures']}")


def _garment_verdict(row: dict[str, Any]) -> str:
    """One scene in a word or two: its largest error, or what was not found (recognised, but
    a keypoint the arm hides left out; or not recognised at all)."""
    if row["score"] is not None:
        return f"{row['score']:.1f} mm"
    if not row["detected"]:
        return "not recognised"
    return "missing: " + ", ".join(row["missing"])


def _badness(row: dict[str, Any]) -> float:
    return math.inf if row["score"] is None else row["score"]


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
