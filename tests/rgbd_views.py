"""A towel seen as a real RGB-D camera sees it: colour from the cell's camera, depth from a
sensor beside it with its own pose, intrinsics and image size (perception.register's tests and
the perception node's)."""

from __future__ import annotations

import math

import numpy as np

from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.sim.camera import CameraConfig, RGBDCamera
from foldbot.sim.cloth import ClothConfig, SoftCloth, settle
from foldbot.sim.layout import DEFAULT_LAYOUT
from foldbot.sim.oracle import GroundTruthOracle
from foldbot.sim.world import SimConfig, SimWorld
from foldbot.types import Observation


def _rotation_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# The depth sensor 25 mm to the colour camera's left and turned 1° about the optical axis, as on
# an RGB-D camera whose depth and colour sensors sit side by side.
T_COLOR_DEPTH = np.eye(4)
T_COLOR_DEPTH[:3, :3] = _rotation_z(math.radians(1.0))
T_COLOR_DEPTH[:3, 3] = [-0.025, 0.001, 0.0]


def render_views() -> tuple[Observation, Observation, dict[str, np.ndarray]]:
    """A settled 30 cm towel seen by the cell's colour camera (640 × 480) and by a depth camera
    beside it (424 × 240, its own K), with the towel's true corners."""
    lay = DEFAULT_LAYOUT
    with SimWorld(SimConfig()) as world:
        cloth = SoftCloth(
            world.client,
            make_towel(TowelSpec(0.3, 0.3, 12)),
            ClothConfig(),
            lay.table_height,
            (0.55, 0.1),
            0.3,
        )
        settle(world, cloth, max_time=0.6)
        color_cam = RGBDCamera(world.client, CameraConfig())
        T_world_color = color_cam.T_world_camera
        depth_cfg = CameraConfig(
            width=424,
            height=240,
            fx=430.0,
            fy=432.0,
            cx=210.5,
            cy=121.0,
            pose=tuple(map(tuple, T_world_color @ T_COLOR_DEPTH)),
        )
        depth_cam = RGBDCamera(world.client, depth_cfg)
        color = color_cam.observe(stamp=world.sim_time)
        depth = depth_cam.observe(stamp=world.sim_time)
        corners = GroundTruthOracle(cloth, color_cam).labelled_corners()
    return color, depth, corners
