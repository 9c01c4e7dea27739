"""Simulated robots: one abstract ``Robot`` base, one module per arm.

``make_robot(name, client, layout)`` builds one by its registry name.
"""

from __future__ import annotations

import numpy as np

from foldbot.errors import ConfigError, UnreachableTargetError
from foldbot.sim.layout import CellLayout
from foldbot.sim.robots.base import HOME_HEIGHT_ABOVE_TABLE, Robot, gripper_down_quaternion
from foldbot.sim.robots.panda import Panda
from foldbot.sim.robots.ur5 import UR5
from foldbot.sim.robots.ur5e import UR5e

ROBOT_NAMES: tuple[str, ...] = ("ur5", "ur5e", "panda")
"""Names accepted by make_robot."""

_REGISTRY: dict[str, type[Robot]] = {"ur5": UR5, "ur5e": UR5e, "panda": Panda}


def robot_class(name: str) -> type[Robot]:
    """The class of robot `name` (its joint names, limits, …) without loading it."""
    cls = _REGISTRY.get(name) if isinstance(name, str) else None
    if cls is None:
        raise ConfigError(f"unknown robot {name!r}; allowed: {', '.join(ROBOT_NAMES)}")
    return cls


REACH_CHECK_HEIGHT = 0.01
"""Height (m) over the table at which the workspace centre must be reachable gripper-down."""


def _unreachable(name: str, layout: CellLayout, exc: Exception) -> ConfigError:
    bx, by, bz = layout.robot_base_xyz
    cx, cy = layout.workspace_center_xy
    where, fields = f"the workspace centre ({cx:g}, {cy:g}) m", "workspace_center_xy"
    if layout.home_xy is not None:  # home is set apart from the centre: it may be what fails
        hx, hy = layout.home_xy
        where = f"its home ({hx:g}, {hy:g}) m (home_xy) or {where}"
        fields = f"home_xy, {fields}"
    return ConfigError(
        f"the {name} mounted at ({bx:g}, {by:g}, {bz:g}) m cannot reach {where} on the table "
        f"at {layout.table_height:g} m gripper down ({exc}); move the layout's {fields}, "
        "robot_base_xyz or table_height (`foldbot check-layout FILE.toml` maps what the arm "
        "reaches over the whole workspace)"
    )


def make_robot(name: str, client: int, layout: CellLayout) -> Robot:
    """Load robot `name` into PyBullet client `client`, mounted as `layout` says; ConfigError
    naming the layout where the arm cannot reach its home over the workspace."""
    try:
        return robot_class(name)(client, layout)
    except UnreachableTargetError as exc:
        raise _unreachable(name, layout, exc) from None


def check_workspace_reach(robot: Robot, name: str) -> None:
    """ConfigError naming the layout where `robot` cannot reach its workspace centre at the
    table gripper down (a layout file that puts the cloth out of reach is refused before
    anything moves). Run on a planning twin: IK on the simulated arm itself, even one that
    leaves its joints as they were, changes the order Bullet meets contacts in, and with it
    every episode's cloth."""
    layout = robot.layout
    cx, cy = layout.workspace_center_xy
    try:
        robot.solve_ik([cx, cy, layout.table_height + REACH_CHECK_HEIGHT], q_seed=robot.home_q)
    except UnreachableTargetError as exc:
        raise _unreachable(name, layout, exc) from None


def rest_postures(robot: Robot, park: str) -> dict[str, np.ndarray]:
    """Where the arm rests between motions: its home, and its park pose where that is not the
    home (`park` "out_of_view"), which a layout's obstacles must leave clear
    (ArmExecutor.check_postures)."""
    out = {"home": np.asarray(robot.home_q, dtype=float)}
    if park == "out_of_view":
        out["out-of-view park"] = np.asarray(robot.out_of_view_q, dtype=float)
    return out


__all__ = [
    "HOME_HEIGHT_ABOVE_TABLE",
    "ROBOT_NAMES",
    "UR5",
    "Panda",
    "Robot",
    "UR5e",
    "check_workspace_reach",
    "gripper_down_quaternion",
    "make_robot",
    "rest_postures",
    "robot_class",
]
