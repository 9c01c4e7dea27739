"""Typed fold actions and plans, computed from perceived keypoints (world frame, metres)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from foldbot.errors import ConfigError


@dataclass(frozen=True)
class FoldAction:
    """One pick-and-place: grasp at `grasp`, carry over the fold line, release at `place`."""

    grasp: np.ndarray  # (3,) world xyz of the cloth point to pick
    place: np.ndarray  # (3,) world xyz where that point is released
    fold_line: tuple[float, float, float, float]  # [x, y, dx, dy] the fold this action serves
    label: str = ""
    """What is picked (e.g. the keypoint name)."""
    layers: int = 1
    """Cloth layers stacked at the grasp point that the grasp must hold together (a corner of a
    folded stack): with more than one, the jaws close down at the table, under the whole stack,
    instead of just under the perceived top surface."""
    descent: float | None = None
    """Height (m) over the place at which the carry arc ends, the carried point then coming
    straight down, slowly; None: the motion's `MotionConfig.place_height`. The towel loop sets it
    on a stage's two corners carried at once (LoopConfig.pair_descent)."""
    carry: str = "arc"
    """The carry's path (planning.motion.CARRY_PATHS): "arc", the half-sine arc; "stadium",
    straight up, a half circle over, straight down (a carry of a few mm: the loop's relays with
    LoopConfig.relay_stadium)."""
    lift: float | None = None
    """Lowest peak (m) of the carry above its start; None: the motion's
    `MotionConfig.min_arc_height`. A corner that slipped is laid back lifted this high, so its
    bunched edge hangs out straight (LoopConfig.slip_lay_back_lift)."""

    def __post_init__(self) -> None:
        if self.carry not in ("arc", "stadium"):
            raise ConfigError(
                f"action '{self.label}': carry must be 'arc' or 'stadium', got {self.carry!r}"
            )
        if self.lift is not None and not (math.isfinite(self.lift) and 0.0 < self.lift <= 0.5):
            raise ConfigError(
                f"action '{self.label}': lift must be a height in (0, 0.5] m or None, "
                f"got {self.lift!r}"
            )

    def as_dict(self) -> dict:
        d = {
            "label": self.label,
            "layers": self.layers,
            "grasp": [float(v) for v in self.grasp],
            "place": [float(v) for v in self.place],
            "fold_line": [float(v) for v in self.fold_line],
        }
        if self.descent is not None:
            d["descent"] = float(self.descent)
        if self.carry != "arc":
            d["carry"] = self.carry
        if self.lift is not None:
            d["lift"] = float(self.lift)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> FoldAction:
        """The action from its `as_dict()` form."""
        return cls(
            grasp=np.array(d["grasp"], dtype=float),
            place=np.array(d["place"], dtype=float),
            fold_line=tuple(float(v) for v in d["fold_line"]),
            label=d.get("label", ""),
            layers=int(d.get("layers", 1)),
            descent=None if d.get("descent") is None else float(d["descent"]),
            carry=str(d.get("carry", "arc")),
            lift=None if d.get("lift") is None else float(d["lift"]),
        )


def edge_middle(
    actions: tuple[FoldAction, ...] | list[FoldAction], layers: int | None = None
) -> FoldAction:
    """One action for two corners of one edge carried over the same line: grasped midway between
    their grasps and placed midway between their places (the mirror of that middle, as the
    mirror is affine), holding `layers` (default: as many as its corners are grasped with). One
    arm carries a folded stack so, by the middle of its edge, rather than corner after corner,
    which drags the stack beneath along (docs/experiments.md)."""
    if len(actions) != 2:
        raise ValueError(f"edge_middle joins 2 actions, got {len(actions)}")
    a, b = actions
    if a.fold_line != b.fold_line:
        raise ValueError(
            f"edge_middle joins actions over one fold line, got {a.fold_line} and {b.fold_line}"
        )
    return FoldAction(
        grasp=(np.asarray(a.grasp, dtype=float) + np.asarray(b.grasp, dtype=float)) / 2,
        place=(np.asarray(a.place, dtype=float) + np.asarray(b.place, dtype=float)) / 2,
        fold_line=a.fold_line,
        label=f"middle_{a.label}_{b.label}",
        layers=max(a.layers, b.layers) if layers is None else layers,
        descent=a.descent,
    )


@dataclass(frozen=True)
class FoldPlan:
    """A recipe instantiated on one cloth: its fold lines (in order) and the actions that do them."""

    recipe: str
    fold_lines: tuple[tuple[float, float, float, float], ...]
    actions: tuple[FoldAction, ...]
