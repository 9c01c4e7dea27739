"""Short-sleeved T-shirts lying flat: a parametric outline, its mesh and nine named keypoints.

Mesh frame: the neck is at +y, the hem at −y, "left" is the −x side. The body is a rectangle
(`body_width` × `body_length`, hem to the top of the shoulders at the neck); the shoulders slope
down by `shoulder_drop` from the neck to the shoulder points above the body's sides, where the
sleeves start; each sleeve's top edge continues outwards `sleeve_length` at `sleeve_angle` below
the horizontal and ends in a cuff of `sleeve_opening` square to it; the sleeve's under edge runs
back to the armpit, `armhole_depth` below the shoulder point on the body's side. The neckline is
a half ellipse `neck_width` wide and `neck_depth` deep.

Sizes: `TShirtSpec.sample` draws children's T-shirts (about ages 1–4) whose whole outline fits a
0.5 m square, so that the cell's 0.6 m workspace and camera hold it with margin at any yaw within
±15° of the fold pipeline's placement (top towards the robot).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from foldbot.errors import require
from foldbot.garments.mesh import ClothMesh
from foldbot.garments.outline import Outline, outline_mesh
from foldbot.garments.params import check_ranges, sample_ranges

TSHIRT_KEYPOINTS = (
    "neck",
    "left_shoulder",
    "right_shoulder",
    "left_sleeve",
    "right_sleeve",
    "left_armpit",
    "right_armpit",
    "left_hem",
    "right_hem",
)
"""Keypoint names: neckline centre, shoulder points, cuff middles, armpits, hem corners."""

TSHIRT_LIMITS: dict[str, tuple[float, float, str]] = {
    "body_width": (0.15, 0.6, "m"),
    "body_length": (0.2, 0.8, "m"),
    "sleeve_length": (0.04, 0.3, "m"),
    "sleeve_angle": (0.0, 1.0, "rad"),
    "sleeve_opening": (0.04, 0.2, "m"),
    "armhole_depth": (0.05, 0.3, "m"),
    "neck_width": (0.06, 0.3, "m"),
    "neck_depth": (0.01, 0.15, "m"),
    "shoulder_drop": (0.0, 0.08, "m"),
    "edge_length": (0.01, 0.06, "m"),
}
"""Allowed range (low, high, unit) of each field; cross-field rules are in `TShirtSpec`."""

TSHIRT_SAMPLING: dict[str, tuple[float, float]] = {
    "body_width": (0.24, 0.29),
    "body_length": (0.30, 0.40),
    "sleeve_length": (0.08, 0.11),
    "sleeve_angle": (0.30, 0.50),
    "sleeve_opening": (0.065, 0.085),
    "neck_width": (0.10, 0.13),
    "neck_depth": (0.03, 0.055),
    "shoulder_drop": (0.015, 0.035),
}
"""Uniform ranges `TShirtSpec.sample` draws from (children's sizes, m and rad). The armhole depth
is drawn as 1.15–1.4 × the depth that keeps the sleeve as wide at the body as at the cuff."""
ARMHOLE_FACTOR = (1.15, 1.4)
MIN_UNDERSLEEVE = 0.02
"""Smallest sideways reach (m) of a sleeve's under edge beyond the body's side."""
NECK_SAMPLES = 15
"""Points on the neckline's half ellipse between its two ends (the outline is resampled anyway)."""


@dataclass(frozen=True)
class TShirtSpec:
    """A short-sleeved T-shirt's flat outline (m, rad) and mesh resolution; see the module doc."""

    body_width: float = 0.27
    """Width of the body (m), side seam to side seam."""
    body_length: float = 0.35
    """Hem to the top of the shoulders at the neck (m)."""
    sleeve_length: float = 0.095
    """Length of a sleeve's top edge, shoulder point to cuff (m)."""
    sleeve_angle: float = 0.4
    """Angle of the sleeves below the horizontal (rad)."""
    sleeve_opening: float = 0.075
    """Width of a cuff (m), square to the sleeve."""
    armhole_depth: float = 0.11
    """Shoulder point to armpit, down the body's side (m)."""
    neck_width: float = 0.115
    """Width of the neckline (m)."""
    neck_depth: float = 0.045
    """Depth of the neckline below the neck's sides (m)."""
    shoulder_drop: float = 0.025
    """How far the shoulder points lie below the neck's sides (m)."""
    edge_length: float = 0.025
    """Target mesh edge length (m); 0.025 gives about 210 vertices for the default shirt."""

    def __post_init__(self) -> None:
        check_ranges("tshirt", self, TSHIRT_LIMITS)
        half = self.body_width / 2
        require(
            self.neck_width / 2 <= half - 0.03,
            f"tshirt neck_width must leave ≥ 3 cm of shoulder on each side, i.e. be ≤ "
            f"{self.body_width - 0.06:.3f} m for body_width {self.body_width}, got {self.neck_width!r}",
        )
        c, s = math.cos(self.sleeve_angle), math.sin(self.sleeve_angle)
        reach = self.sleeve_length * c - self.sleeve_opening * s
        require(
            reach >= MIN_UNDERSLEEVE,
            f"tshirt sleeve_length must be ≥ {(MIN_UNDERSLEEVE + self.sleeve_opening * s) / c:.3f} m "
            f"for this sleeve_opening and sleeve_angle (the cuff must end beyond the body's "
            f"side), got {self.sleeve_length!r}",
        )
        require(
            self.armhole_depth * c >= self.sleeve_opening,
            f"tshirt armhole_depth must be ≥ {self.sleeve_opening / c:.3f} m so the sleeve is at "
            f"least as wide at the body as at the cuff, got {self.armhole_depth!r}",
        )
        armpit = self.body_length - self.shoulder_drop - self.armhole_depth
        require(
            armpit >= 0.3 * self.body_length,
            f"tshirt armhole_depth must leave ≥ 30 % of the body below the armpits, i.e. be ≤ "
            f"{0.7 * self.body_length - self.shoulder_drop:.3f} m, got {self.armhole_depth!r}",
        )
        deepest = self.shoulder_drop + self.armhole_depth - 0.02
        require(
            self.neck_depth <= deepest,
            f"tshirt neck_depth must end ≥ 2 cm above the armpits, i.e. be ≤ {deepest:.3f} m, "
            f"got {self.neck_depth!r}",
        )

    @classmethod
    def sample(cls, rng: np.random.Generator, edge_length: float | None = None) -> TShirtSpec:
        """A random children's T-shirt (`TSHIRT_SAMPLING`); the same generator state, the same shirt."""
        fields = sample_ranges(rng, TSHIRT_SAMPLING)
        cos = math.cos(fields["sleeve_angle"])
        fields["armhole_depth"] = (
            fields["sleeve_opening"] / cos * float(rng.uniform(*ARMHOLE_FACTOR))
        )
        if edge_length is not None:
            fields["edge_length"] = edge_length
        return cls(**fields)

    @property
    def span(self) -> float:
        """Cuff to cuff (m): the outline's width."""
        return self.body_width + 2.0 * self.sleeve_length * math.cos(self.sleeve_angle)


def tshirt_outline(spec: TShirtSpec) -> Outline:
    """The T-shirt's counter-clockwise outline (hem at y = 0, symmetric about x = 0)."""
    a = spec.body_width / 2
    top = spec.body_length
    shoulder_y = top - spec.shoulder_drop
    c, s = math.cos(spec.sleeve_angle), math.sin(spec.sleeve_angle)
    cuff_top = np.array([a + spec.sleeve_length * c, shoulder_y - spec.sleeve_length * s])
    cuff_bottom = cuff_top + spec.sleeve_opening * np.array([-s, -c])
    cuff_mid = 0.5 * (cuff_top + cuff_bottom)
    armpit_y = shoulder_y - spec.armhole_depth
    t = np.linspace(0.0, math.pi, NECK_SAMPLES + 2)
    neck = np.stack([spec.neck_width / 2 * np.cos(t), top - spec.neck_depth * np.sin(t)], axis=1)

    def mirror(p: np.ndarray) -> np.ndarray:
        return np.array([-p[0], p[1]])

    named: list[tuple[str | None, np.ndarray]] = [
        ("left_hem", np.array([-a, 0.0])),
        ("right_hem", np.array([a, 0.0])),
        ("right_armpit", np.array([a, armpit_y])),
        ("", cuff_bottom),
        ("right_sleeve", cuff_mid),
        ("", cuff_top),
        ("right_shoulder", np.array([a, shoulder_y])),
        ("", neck[0]),
        *[(None, q) for q in neck[1 : NECK_SAMPLES // 2 + 1]],
        ("neck", neck[NECK_SAMPLES // 2 + 1]),
        *[(None, q) for q in neck[NECK_SAMPLES // 2 + 2 : -1]],
        ("", neck[-1]),
        ("left_shoulder", mirror(np.array([a, shoulder_y]))),
        ("", mirror(cuff_top)),
        ("left_sleeve", mirror(cuff_mid)),
        ("", mirror(cuff_bottom)),
        ("left_armpit", np.array([-a, armpit_y])),
    ]
    points = np.array([p for _, p in named])
    keypoints = {name: i for i, (name, _) in enumerate(named) if name}
    corners = tuple(i for i, (name, _) in enumerate(named) if name is not None)
    return Outline(points, keypoints, corners)


def make_tshirt(spec: TShirtSpec) -> ClothMesh:
    """The T-shirt's flat mesh (bounding box centred at the origin, z = 0), keypoints named."""
    return outline_mesh(tshirt_outline(spec), spec.edge_length)
