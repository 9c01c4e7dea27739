"""Randomised perception scenes and their rendering with ground truth: a towel (flat or
folded in half) or a flat T-shirt or pants, placed, coloured, lit and seen as `foldbot
eval-perception` draws them (colours, the arm, camera jitter, sensor noise, lighting), settled in
the simulator and rendered; the ground truth (corners or named keypoints, the cloth's and the
robot's pixels) is read beside the observation, for scoring perception and for its tests."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from foldbot.errors import ConfigError, FoldbotError
from foldbot.garments import make_garment, sample_garment
from foldbot.garments.mesh import ClothMesh
from foldbot.garments.pants import PantsSpec
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.garments.tshirt import TShirtSpec
from foldbot.perception.register import register_depth
from foldbot.sim.camera import (
    DEFAULT_EYE,
    DEFAULT_TARGET,
    DEFAULT_UP,
    CameraConfig,
    Lighting,
    RGBDCamera,
)
from foldbot.sim.cloth import ClothConfig, SoftCloth, settle
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout
from foldbot.sim.oracle import GroundTruthOracle
from foldbot.sim.robots import make_robot
from foldbot.sim.robots.base import HOME_HEIGHT_ABOVE_TABLE
from foldbot.sim.world import SimConfig, SimWorld
from foldbot.types import Observation

if TYPE_CHECKING:
    from foldbot.layout_check import CameraPlacement

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
