"""Pants lying flat: a parametric outline, its mesh and seven named keypoints.

Mesh frame: the waist is at +y, the leg ends at −y, "left" is the −x side. The waistband is a
straight edge `waist_width` wide; the outer side of each leg runs from the waist corner out to the
hip (`hip_width` across, at crotch level) and down to the leg's outer hem corner; each leg ends in
a hem `leg_opening` wide; the inseams run from the leg's inner hem corner up to the crotch,
`rise` below the waist; the inner hem corners are `hem_gap` apart. `length` is waist to hem.

Sizes: `PantsSpec.sample` draws children's trousers (about ages 1–4) whose whole outline fits a
0.5 m square, so that the cell's 0.6 m workspace and camera hold it with margin at any yaw within
±15° of the fold pipeline's placement (waist towards the robot).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldbot.errors import require
from foldbot.garments.mesh import ClothMesh
from foldbot.garments.outline import Outline, outline_mesh
from foldbot.garments.params import check_ranges, sample_ranges

PANTS_KEYPOINTS = (
    "left_waist",
    "right_waist",
    "left_leg_outer",
    "left_leg_inner",
    "right_leg_outer",
    "right_leg_inner",
    "crotch",
)
"""Keypoint names: waistband corners, each leg's hem corners (outer, inner), crotch."""

PANTS_LIMITS: dict[str, tuple[float, float, str]] = {
    "waist_width": (0.12, 0.6, "m"),
    "hip_width": (0.12, 0.7, "m"),
    "length": (0.2, 1.2, "m"),
    "rise": (0.08, 0.4, "m"),
    "leg_opening": (0.05, 0.3, "m"),
    "hem_gap": (0.02, 0.3, "m"),
    "edge_length": (0.01, 0.06, "m"),
}
"""Allowed range (low, high, unit) of each field; cross-field rules are in `PantsSpec`."""

PANTS_SAMPLING: dict[str, tuple[float, float]] = {
    "waist_width": (0.22, 0.27),
    "length": (0.36, 0.45),
    "rise": (0.15, 0.19),
    "leg_opening": (0.085, 0.105),
    "hem_gap": (0.04, 0.08),
}
"""Uniform ranges `PantsSpec.sample` draws from (children's sizes, m); the hip is 2–6 cm wider than
the waist."""
HIP_EXTRA = (0.02, 0.06)


@dataclass(frozen=True)
class PantsSpec:
    """A pair of trousers' flat outline (m) and mesh resolution; see the module docstring."""

    waist_width: float = 0.245
    """Width of the waistband (m), flat."""
    hip_width: float = 0.26
    """Width across the hips at crotch level (m)."""
    length: float = 0.40
    """Waist to hem (m), along the outer side."""
    rise: float = 0.17
    """Waist to crotch (m)."""
    leg_opening: float = 0.095
    """Width of each leg's hem (m)."""
    hem_gap: float = 0.075
    """Distance between the two inner hem corners (m)."""
    edge_length: float = 0.025
    """Target mesh edge length (m); 0.025 gives about 200 vertices for the default pants."""

    def __post_init__(self) -> None:
        check_ranges("pants", self, PANTS_LIMITS)
        require(
            self.hip_width >= self.waist_width,
            f"pants hip_width must be ≥ waist_width ({self.waist_width} m), got {self.hip_width!r}",
        )
        require(
            self.rise <= 0.7 * self.length,
            f"pants rise must be ≤ 70 % of the length ({0.7 * self.length:.3f} m), "
            f"got {self.rise!r}",
        )
        require(
            self.hem_gap / 2 + self.leg_opening <= 1.25 * self.hip_width / 2,
            f"pants leg_opening must be ≤ {1.25 * self.hip_width / 2 - self.hem_gap / 2:.3f} m "
            f"for this hip_width and hem_gap (the legs would flare far beyond the hips), "
            f"got {self.leg_opening!r}",
        )
        require(
            self.hem_gap / 2 + 0.03 <= self.hip_width / 2,
            f"pants hem_gap must be ≤ {self.hip_width - 0.06:.3f} m for this hip_width, "
            f"got {self.hem_gap!r}",
        )

    @classmethod
    def sample(cls, rng: np.random.Generator, edge_length: float | None = None) -> PantsSpec:
        """Random children's pants (`PANTS_SAMPLING`); the same generator state, the same pants."""
        fields = sample_ranges(rng, PANTS_SAMPLING)
        fields["hip_width"] = fields["waist_width"] + float(rng.uniform(*HIP_EXTRA))
        if edge_length is not None:
            fields["edge_length"] = edge_length
        return cls(**fields)


def pants_outline(spec: PantsSpec) -> Outline:
    """The pants' counter-clockwise outline (hems at y = 0, symmetric about x = 0)."""
    inner = spec.hem_gap / 2
    outer = inner + spec.leg_opening
    crotch_y = spec.length - spec.rise
    named: list[tuple[str, tuple[float, float]]] = [
        ("left_leg_outer", (-outer, 0.0)),
        ("left_leg_inner", (-inner, 0.0)),
        ("crotch", (0.0, crotch_y)),
        ("right_leg_inner", (inner, 0.0)),
        ("right_leg_outer", (outer, 0.0)),
        ("", (spec.hip_width / 2, crotch_y)),
        ("right_waist", (spec.waist_width / 2, spec.length)),
        ("left_waist", (-spec.waist_width / 2, spec.length)),
        ("", (-spec.hip_width / 2, crotch_y)),
    ]
    points = np.array([p for _, p in named], dtype=float)
    keypoints = {name: i for i, (name, _) in enumerate(named) if name}
    return Outline(points, keypoints, corners=tuple(range(len(named))))


def make_pants(spec: PantsSpec) -> ClothMesh:
    """The pants' flat mesh (bounding box centred at the origin, z = 0), keypoints named."""
    return outline_mesh(pants_outline(spec), spec.edge_length)
