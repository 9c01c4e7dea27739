"""Towel fold recipes computed from the perceived corner keypoints — never from fixed coordinates.

Corners are named in the world frame relative to the robot (see perception.keypoints):
near_left, near_right, far_right, far_left (near = closer to the robot, left = +y).
"""

from __future__ import annotations

import numpy as np

from foldbot.errors import ConfigError
from foldbot.planning.actions import FoldAction, FoldPlan

CORNER_NAMES = ("near_left", "near_right", "far_right", "far_left")
RECIPES = ("half",)


def _mirror(point: np.ndarray, line: tuple[float, float, float, float]) -> np.ndarray:
    """Reflect a point's x, y across the line [x, y, dx, dy]; z is kept."""
    x, y, dx, dy = line
    d = np.array([dx, dy]) / np.hypot(dx, dy)
    rel = point[:2] - np.array([x, y])
    along = rel @ d
    out = np.array(point, dtype=float)
    out[:2] = np.array([x, y]) + 2 * along * d - rel
    return out


def _require_corners(corners: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    missing = [n for n in CORNER_NAMES if n not in corners]
    if missing:
        raise ConfigError(f"fold planning needs the corners {CORNER_NAMES}, missing {missing}")
    return {n: np.asarray(corners[n], dtype=float) for n in CORNER_NAMES}


def half_fold(
    corners: dict[str, np.ndarray], axis: str = "x", place_lift: float = 0.004
) -> FoldPlan:
    """Half fold: the far edge's corners are carried onto the near edge's (axis "x"), or the left
    edge's onto the right edge's (axis "y"), one corner grasp after the other (one gripper).

    The fold line runs through the midpoints of the two edges that the fold bends, directed so
    that the moving side lies to its left, as the metric's convention requires.
    """
    c = _require_corners(corners)
    if axis == "x":  # fold across x: far half moves toward the robot
        moving = ("far_left", "far_right")
        staying = ("near_left", "near_right")
    elif axis == "y":  # left half moves onto the right half
        moving = ("far_left", "near_left")
        staying = ("far_right", "near_right")
    else:
        raise ConfigError(f"half fold axis must be 'x' or 'y', got {axis!r}")
    mid_a = (c[moving[0]] + c[staying[0]]) / 2
    mid_b = (c[moving[1]] + c[staying[1]]) / 2
    direction = mid_b[:2] - mid_a[:2]
    line = (float(mid_a[0]), float(mid_a[1]), float(direction[0]), float(direction[1]))
    # Orient the line so the moving side is on its left: (−dy, dx)·(p − p0) > 0.
    probe = (c[moving[0]] + c[moving[1]])[:2] / 2 - mid_a[:2]
    if -direction[1] * probe[0] + direction[0] * probe[1] < 0:
        line = (float(mid_b[0]), float(mid_b[1]), float(-direction[0]), float(-direction[1]))
    actions = []
    for name in moving:
        place = _mirror(c[name], line)
        place[2] = c[name][2] + place_lift
        actions.append(FoldAction(grasp=c[name], place=place, fold_line=line, label=name))
    return FoldPlan(recipe="half", fold_lines=(line,), actions=tuple(actions))


def plan_recipe(recipe: str, corners: dict[str, np.ndarray]) -> FoldPlan:
    """Instantiate a named recipe on the perceived corners."""
    if recipe == "half":
        return half_fold(corners)
    raise ConfigError(f"unknown recipe {recipe!r}; allowed: {', '.join(RECIPES)}")
