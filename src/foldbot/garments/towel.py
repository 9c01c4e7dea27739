"""Rectangular towels: a regular triangulated grid with its four corners as keypoints."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldbot.errors import require
from foldbot.garments.mesh import ClothMesh

MIN_RESOLUTION = 4
MAX_RESOLUTION = 40
MIN_VERTICES = (MIN_RESOLUTION + 1) ** 2
"""The smallest vertex bound a towel may be given: the coarsest grid any towel can get (5 × 5,
odd counts)."""
TOWEL_CORNERS = ("corner_00", "corner_10", "corner_11", "corner_01")
"""Mesh-frame corner names: corner_ij at (i ? +w/2 : −w/2, j ? +h/2 : −h/2)."""


@dataclass(frozen=True)
class TowelSpec:
    """A rectangular towel of `width` (x) × `height` (y) metres."""

    width: float = 0.30
    """Side along the mesh x axis (m)."""
    height: float = 0.30
    """Side along the mesh y axis (m)."""
    resolution: int = 16
    """Vertices along the longer side (the shorter side gets proportionally fewer, at least 4)."""
    odd_grid: bool = False
    """Odd vertex counts along both sides (each the odd count nearest the proportional one, at
    least 5), so both midlines, the half folds' lines, are vertex rows. A mass-spring mesh
    creases only at its vertices: a fold line that falls between two rows leaves a whole edge
    standing in the crease, and the folded layer lies up to an edge's length off its goal."""
    max_vertices: int | None = None
    """At most this many vertices: where `resolution` along the longer side gives more (a
    near-square towel), the longer side gets the largest count that stays within it. A physics
    step's cost grows with the vertices, so this bounds an episode's; None: no bound."""

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            require(
                np.isfinite(value) and 0.05 <= value <= 1.0,
                f"towel {name} must be in [0.05, 1.0] m, got {value!r}",
            )
        require(
            isinstance(self.resolution, int | np.integer)
            and MIN_RESOLUTION <= self.resolution <= MAX_RESOLUTION,
            f"towel resolution must be an integer in [{MIN_RESOLUTION}, {MAX_RESOLUTION}] "
            f"vertices per long side, got {self.resolution!r}",
        )
        require(
            isinstance(self.odd_grid, bool | np.bool_),
            f"towel odd_grid must be true or false, got {self.odd_grid!r}",
        )
        if self.max_vertices is not None:
            require(
                isinstance(self.max_vertices, int | np.integer)
                and not isinstance(self.max_vertices, bool)
                and MIN_VERTICES <= self.max_vertices <= MAX_RESOLUTION**2,
                f"towel max_vertices must be an integer in [{MIN_VERTICES}, "
                f"{MAX_RESOLUTION**2}], got {self.max_vertices!r}",
            )

    @property
    def grid_shape(self) -> tuple[int, int]:
        """(rows along y, cols along x) of the vertex grid, spacing as square as possible (with
        `odd_grid`, both counts odd), `resolution` along the longer side or, where that gives more
        than `max_vertices`, the largest count that does not."""
        for resolution in range(self.resolution, MIN_RESOLUTION - 1, -1):
            ny, nx = self._grid_at(resolution)
            if self.max_vertices is None or ny * nx <= self.max_vertices:
                return ny, nx
        return ny, nx  # the coarsest grid: MIN_VERTICES keeps it within any allowed bound

    def _grid_at(self, resolution: int) -> tuple[int, int]:
        long_side = max(self.width, self.height)
        edges_x = (resolution - 1) * self.width / long_side
        edges_y = (resolution - 1) * self.height / long_side
        if self.odd_grid:  # an even number of edges puts a vertex row on each midline
            return _odd_count(edges_y), _odd_count(edges_x)
        nx = max(MIN_RESOLUTION, round(edges_x) + 1)
        ny = max(MIN_RESOLUTION, round(edges_y) + 1)
        return ny, nx


def _odd_count(edges: float) -> int:
    """The odd vertex count (at least 5) whose edge count is the even number nearest `edges`
    (ties round up)."""
    return max(MIN_RESOLUTION + 1, 2 * int(np.floor(edges / 2 + 0.5)) + 1)


def make_towel(spec: TowelSpec) -> ClothMesh:
    """Generate the towel's flat grid mesh, centred at the origin, corners named."""
    ny, nx = spec.grid_shape
    xs = np.linspace(-spec.width / 2, spec.width / 2, nx)
    ys = np.linspace(-spec.height / 2, spec.height / 2, ny)
    gx, gy = np.meshgrid(xs, ys)  # row-major: index = j * nx + i
    vertices = np.stack([gx.ravel(), gy.ravel(), np.zeros(nx * ny)], axis=1)
    faces = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            b, c, d = a + 1, a + nx, a + nx + 1
            # Alternate the diagonal so the mesh has no preferred shear direction.
            if (i + j) % 2 == 0:
                faces += [(a, b, d), (a, d, c)]
            else:
                faces += [(a, b, c), (b, d, c)]
    keypoints = {
        "corner_00": 0,
        "corner_10": nx - 1,
        "corner_11": nx * ny - 1,
        "corner_01": nx * (ny - 1),
    }
    return ClothMesh(
        vertices=vertices,
        faces=np.asarray(faces, dtype=np.int64),
        keypoints=keypoints,
        grid_shape=(ny, nx),
    )
