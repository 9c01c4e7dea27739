"""Garments: parametric outlines turned into cloth meshes with named keypoints.

`sample_garment(kind, rng)` draws a spec of a garment kind from its realistic ranges and builds
its flat mesh; `GARMENT_KEYPOINTS[kind]` names the keypoints the mesh (and perception) carry.

Physics: T-shirts and pants use `ClothConfig`'s defaults unchanged, mass included (0.1 kg, not
scaled with area). The sampled garments cover 0.08–0.12 m² with 169–250 vertices at the default
25 mm edge, against the reference towel's 0.09 m² and 256 vertices, so the mass per vertex (what a
mass-spring cloth's stability depends on) is 0.40–0.59 g against the towel's 0.39 g; scaling the
mass with area would give 0.51–0.57 g, no closer. Measured: every sampled garment tried settled
flat in place (within 1 mm of its spawn, heights 3.6–4.2 mm) without divergence.
"""

from __future__ import annotations

import numpy as np

from foldbot.errors import ConfigError
from foldbot.garments.mesh import ClothMesh
from foldbot.garments.pants import PANTS_KEYPOINTS, PantsSpec, make_pants
from foldbot.garments.towel import TOWEL_CORNERS, TowelSpec, make_towel
from foldbot.garments.tshirt import TSHIRT_KEYPOINTS, TShirtSpec, make_tshirt

GARMENTS = ("towel", "tshirt", "pants")
"""The garment kinds foldbot can generate."""
GARMENT_KEYPOINTS: dict[str, tuple[str, ...]] = {
    "towel": TOWEL_CORNERS,
    "tshirt": TSHIRT_KEYPOINTS,
    "pants": PANTS_KEYPOINTS,
}
"""The mesh keypoint names of each garment kind."""
TOWEL_SIZE = (0.2, 0.45)
"""Side range (m) of randomly drawn towels (each side independently)."""

GarmentSpec = TowelSpec | TShirtSpec | PantsSpec
"""Any garment spec."""


def make_garment(spec: GarmentSpec) -> ClothMesh:
    """The flat mesh of any garment spec."""
    if isinstance(spec, TShirtSpec):
        return make_tshirt(spec)
    if isinstance(spec, PantsSpec):
        return make_pants(spec)
    if isinstance(spec, TowelSpec):
        return make_towel(spec)
    raise ConfigError(f"not a garment spec: {type(spec).__name__}")


def garment_kind(spec: GarmentSpec) -> str:
    """The kind name ("towel", "tshirt", "pants") of a spec."""
    kinds = {TowelSpec: "towel", TShirtSpec: "tshirt", PantsSpec: "pants"}
    if type(spec) not in kinds:
        raise ConfigError(f"not a garment spec: {type(spec).__name__}")
    return kinds[type(spec)]


def sample_garment(
    kind: str, rng: np.random.Generator, edge_length: float | None = None
) -> tuple[GarmentSpec, ClothMesh]:
    """A random garment of `kind` drawn from its realistic ranges, and its flat mesh.

    `edge_length` (m) overrides the default mesh resolution (for towels: the grid spacing, turned
    into vertices per long side). The same generator state gives the same garment.
    """
    if kind not in GARMENTS:
        raise ConfigError(f"garment kind must be one of {GARMENTS}, got {kind!r}")
    spec: GarmentSpec
    if kind == "tshirt":
        spec = TShirtSpec.sample(rng, edge_length)
    elif kind == "pants":
        spec = PantsSpec.sample(rng, edge_length)
    else:
        w, h = (float(v) for v in rng.uniform(*TOWEL_SIZE, size=2))
        if edge_length is None:
            spec = TowelSpec(w, h)
        else:
            if not (np.isfinite(edge_length) and edge_length > 0):
                raise ConfigError(f"edge_length must be > 0 m, got {edge_length!r}")
            spec = TowelSpec(w, h, round(max(w, h) / edge_length) + 1)
    return spec, make_garment(spec)
