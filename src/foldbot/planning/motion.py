"""Fold actions → end-effector waypoint segments: approach, descend, close, arc over the fold line,
lower, open, retreat. Pure geometry (world frame, metres); IK and timing happen in control."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from foldbot.errors import require
from foldbot.planning.actions import FoldAction


@dataclass(frozen=True)
class MotionConfig:
    """Shape and speed of the pick-and-place motion."""

    approach_height: float = 0.08
    """Height above the grasp point the gripper descends from (m)."""
    grasp_depth: float = 0.004
    """TCP height above the perceived grasp point at closing (m); the pads straddle the cloth."""
    arc_height_ratio: float = 0.5
    """Peak height of the carry arc above the straight line, per metre of carried distance."""
    min_arc_height: float = 0.05
    """Lowest carry-arc peak (m)."""
    stack_grasp_height: float = 0.004
    """For a grasp that must hold a folded stack (`FoldAction.layers` > 1): the grasp point's height
    above the perceived table (m), i.e. where a single layer's corner is, so the closing jaws reach
    under every layer."""
    place_lift: float = 0.004
    """A carried point is released this high above the height it was grasped at (m)."""
    place_height: float = 0.01
    """Height above the place point at which the arc ends before the final lowering (m), unless
    the action sets its own (`FoldAction.descent`)."""
    place_slide: float = 0.0
    """Lower-then-slide placement: the carried point comes down this far short of its place point
    (back along the carry direction) and is then slid out onto it, pulling the laid layer taut
    from the crease (m; 0 = lower straight onto the place point)."""
    retreat_height: float = 0.08
    """Rise after releasing (m)."""
    cartesian_speed: float = 0.25
    """Nominal TCP speed along carry paths (m/s)."""
    free_speed: float = 0.5
    """Nominal TCP speed for moves without cloth (m/s)."""
    arc_points: int = 40
    """Waypoints along the carry arc."""
    speed_scale: float = 1.0
    """Fraction of full speed every arm motion runs at, in (MIN_SPEED_SCALE, 1]: the same paths,
    1/speed_scale times as long (joint velocity, acceleration and jerk limits and TCP speeds
    scaled as time is: ×s, ×s², ×s³, ×s), as a real arm's speed slider for its first runs."""

    def __post_init__(self) -> None:
        require(
            isinstance(self.speed_scale, (int, float))
            and not isinstance(self.speed_scale, bool)
            and MIN_SPEED_SCALE <= self.speed_scale <= 1.0,
            f"speed_scale must be in [{MIN_SPEED_SCALE:g}, 1] (a fraction of full speed), got "
            f"{self.speed_scale!r}",
        )


MIN_SPEED_SCALE = 0.05
"""Slowest speed_scale accepted: a twentieth of full speed keeps a motion's wait for its driver
(the task node's 300 s) beyond the longest motion of a fold."""


@dataclass(frozen=True)
class Segment:
    """A Cartesian TCP path with its speed; `gripper` is applied when the segment has finished."""

    name: str
    points: np.ndarray  # N×3
    speed: float
    gripper: str | None = None  # "close" | "open" | None
    dwell: float = 0.0
    """Held still this long (s) at the segment's end, before its gripper event."""
    orientations: np.ndarray | None = None
    """N×4 TCP orientation (x, y, z, w) at each waypoint; None: gripper down at the executor's
    yaw all along."""

    def __post_init__(self) -> None:
        if self.orientations is not None:
            o = np.asarray(self.orientations, dtype=float)
            require(
                o.shape == (len(self.points), 4) and bool(np.isfinite(o).all()),
                f"segment '{self.name}': orientations must be {len(self.points)}×4 finite "
                f"quaternions (one per waypoint), got shape {o.shape}",
            )


def line_path(a: np.ndarray, b: np.ndarray, step: float = 0.01) -> np.ndarray:
    """Straight TCP path from a to b with waypoints every `step` metres."""
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
    return a + (b - a) * np.linspace(0.0, 1.0, n)[:, None]


def carry_height(dist: float, cfg: MotionConfig, lift: float | None = None) -> float:
    """Peak height (m) of a carry over `dist` metres: in proportion to the distance, and at least
    `lift` (the action's own, else `cfg.min_arc_height`)."""
    return max(cfg.min_arc_height if lift is None else lift, cfg.arc_height_ratio * dist)


def carry_arc(
    start: np.ndarray, end: np.ndarray, cfg: MotionConfig, lift: float | None = None
) -> np.ndarray:
    """A half-sine arc from start to end, high enough that the carried cloth hangs clear."""
    dist = float(np.linalg.norm(end[:2] - start[:2]))
    height = carry_height(dist, cfg, lift)
    t = np.linspace(0.0, 1.0, cfg.arc_points)
    pts = start + (end - start) * t[:, None]
    pts[:, 2] += height * np.sin(np.pi * t)
    return pts


STADIUM_MIN_WIDTH = 0.005
"""A stadium carry narrower than this (m) goes straight up to its height and straight down: a
half circle that narrow turns too tightly (a lay-back of a corner 0.3 mm from where it was to
be laid took 90 s), while a path that turns back comes to rest there and is timed in two parts
(control.trajectory)."""


def stadium_arc(
    start: np.ndarray, end: np.ndarray, cfg: MotionConfig, lift: float | None = None
) -> np.ndarray:
    """As high as `carry_arc`, but straight up, a half circle as wide as the carry, straight
    down: over a carry of a few mm the half-sine's tip turns on a radius of a fraction of a mm
    (d²/(π²h)), which caps the whole motion's speed (a relay's 8 mm carry took 77 s); the half
    circle's radius is half the carry. Under STADIUM_MIN_WIDTH, up and down."""
    dist = float(np.linalg.norm(end[:2] - start[:2]))
    if dist < 1e-6 and lift is None:
        return line_path(start, end)
    height = carry_height(dist, cfg, lift)
    top = max(float(start[2]), float(end[2])) + height
    if dist < STADIUM_MIN_WIDTH:
        apex = np.array([*(start[:2] + end[:2]) / 2, top])
        return np.vstack([line_path(start, apex, 0.005), line_path(apex, end, 0.005)[1:]])
    radius = dist / 2
    along = (end[:2] - start[:2]) / dist
    middle = (start[:2] + end[:2]) / 2
    rise = np.array([*start[:2], max(top - radius, float(start[2]))])
    fall = np.array([*end[:2], max(top - radius, float(end[2]))])
    theta = np.linspace(np.pi, 0.0, max(cfg.arc_points // 2, 8))
    over = np.column_stack(
        [
            middle[0] + radius * np.cos(theta) * along[0],
            middle[1] + radius * np.cos(theta) * along[1],
            rise[2] + (fall[2] - rise[2]) * (1 - np.cos(theta)) / 2 + radius * np.sin(theta),
        ]
    )
    return np.vstack([line_path(start, rise, 0.005), over[1:], line_path(fall, end, 0.005)[1:]])


CARRY_PATHS = {"arc": carry_arc, "stadium": stadium_arc}
"""A FoldAction's `carry` → the function that draws its carry path."""


def action_segments(action: FoldAction, current: np.ndarray, cfg: MotionConfig) -> list[Segment]:
    """The segments that execute one fold action, starting from TCP position `current`."""
    up = np.array([0.0, 0.0, 1.0])
    descent = cfg.place_height if action.descent is None else action.descent
    require(
        math.isfinite(descent) and cfg.grasp_depth <= descent <= cfg.approach_height,
        f"action '{action.label}': descent {descent!r} m must lie between the grasp depth "
        f"{cfg.grasp_depth} m and the approach height {cfg.approach_height} m",
    )
    grasp_tcp = action.grasp + up * cfg.grasp_depth
    pre_grasp = action.grasp + up * cfg.approach_height
    place_tcp = action.place + up * cfg.grasp_depth
    carry = np.array([*(action.place[:2] - action.grasp[:2]), 0.0])
    dist = float(np.linalg.norm(carry))
    slide = min(cfg.place_slide, 0.5 * dist)
    touch_tcp = place_tcp - (carry / dist * slide if slide > 0 else 0.0)
    pre_place = touch_tcp + up * (descent - cfg.grasp_depth)
    segments = [
        Segment("approach", line_path(current, pre_grasp), cfg.free_speed),
        Segment("descend", line_path(pre_grasp, grasp_tcp, 0.005), cfg.free_speed / 3, "close"),
        Segment(
            "carry",
            CARRY_PATHS[action.carry](grasp_tcp, pre_place, cfg, action.lift),
            cfg.cartesian_speed,
        ),
    ]
    if slide > 0:
        segments += [
            Segment("lower", line_path(pre_place, touch_tcp, 0.003), cfg.cartesian_speed / 3),
            Segment(
                "slide", line_path(touch_tcp, place_tcp, 0.003), cfg.cartesian_speed / 3, "open"
            ),
        ]
    else:
        segments.append(
            Segment(
                "lower", line_path(pre_place, place_tcp, 0.003), cfg.cartesian_speed / 3, "open"
            )
        )
    segments.append(
        Segment(
            "retreat", line_path(place_tcp, place_tcp + up * cfg.retreat_height), cfg.free_speed
        )
    )
    return segments
