"""A cloth mesh: flat vertices, triangles and named keypoints — what a garment generator returns."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class ClothMesh:
    """A flat cloth mesh in its own frame (centred at the origin, z = 0), metres."""

    vertices: np.ndarray  # V×3
    faces: np.ndarray  # F×3 int
    keypoints: dict[str, int] = field(default_factory=dict)
    """Named semantic keypoints as vertex indices (e.g. towel corners)."""
    grid_shape: tuple[int, int] | None = None
    """(rows, cols) when the vertices form a regular grid, row-major, else None."""

    @property
    def edge_length(self) -> float:
        """Mean edge length (m)."""
        f = self.faces
        e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        return float(np.linalg.norm(self.vertices[e[:, 0]] - self.vertices[e[:, 1]], axis=1).mean())

    @property
    def area(self) -> float:
        """Total triangle area (m²)."""
        a, b, c = (self.vertices[self.faces[:, k]] for k in range(3))
        return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())

    def write_obj(self, path: Path) -> Path:
        """Write the mesh as a Wavefront OBJ with UVs (PyBullet's soft-body loader needs a file)."""
        v = self.vertices
        lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)
        uv = (v[:, :2] - lo) / np.maximum(hi - lo, 1e-9)
        lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
        lines += [f"vt {s:.6f} {t:.6f}" for s, t in uv]
        lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in self.faces + 1]
        path.write_text("\n".join(lines) + "\n")
        return path
