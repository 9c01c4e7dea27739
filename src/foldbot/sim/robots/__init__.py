"""Simulated robots: one abstract ``Robot`` base, one module per arm.

``make_robot(name, client, layout)`` builds one by its registry name.
"""

from __future__ import annotations

from foldbot.errors import ConfigError
from foldbot.sim.layout import CellLayout
from foldbot.sim.robots.base import HOME_HEIGHT_ABOVE_TABLE, Robot, gripper_down_quaternion
from foldbot.sim.robots.panda import Panda
from foldbot.sim.robots.ur5 import UR5

ROBOT_NAMES: tuple[str, ...] = ("ur5", "panda")
"""Names accepted by make_robot."""

_REGISTRY: dict[str, type[Robot]] = {"ur5": UR5, "panda": Panda}


def robot_class(name: str) -> type[Robot]:
    """The class of robot `name` (its joint names, limits, …) without loading it."""
    cls = _REGISTRY.get(name) if isinstance(name, str) else None
    if cls is None:
        raise ConfigError(f"unknown robot {name!r}; allowed: {', '.join(ROBOT_NAMES)}")
    return cls


def make_robot(name: str, client: int, layout: CellLayout) -> Robot:
    """Load robot `name` into PyBullet client `client`, mounted as `layout` says."""
    return robot_class(name)(client, layout)


__all__ = [
    "HOME_HEIGHT_ABOVE_TABLE",
    "ROBOT_NAMES",
    "UR5",
    "Panda",
    "Robot",
    "gripper_down_quaternion",
    "make_robot",
    "robot_class",
]
