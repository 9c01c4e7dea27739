"""A closed 2-D outline (mesh frame, metres) turned into a flat triangle mesh with named keypoints.

Method: the outline is resampled at about one edge length between its corners (corners and named
keypoints stay exact vertices), the inside is filled with a triangular lattice of the same spacing
(mirror-symmetric about x = 0, so symmetric garments get symmetric meshes) minus the lattice points
closer than `clearance` edge lengths to the outline, the points are triangulated (Delaunay) and the
triangles whose centroid lies outside the outline (neckline, armpits, crotch) are dropped. A few
rounds of Laplacian smoothing of the inner vertices followed by a fresh triangulation even out the
triangles next to the outline. The mesh is checked: every outline edge is a mesh edge, one
connected piece, no triangle sharper than `MIN_ANGLE_DEG`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay

from foldbot.errors import ConfigError, require
from foldbot.garments.mesh import ClothMesh

MIN_ANGLE_DEG = 20.0
"""Smallest triangle angle a generated mesh may have (sliver triangles make stiff, unstable springs)."""
MIN_EDGE_LENGTH = 0.005
"""Smallest target edge length (m) `outline_mesh` accepts."""
MAX_EDGE_LENGTH = 0.1
"""Largest target edge length (m) `outline_mesh` accepts."""


@dataclass(frozen=True)
class Outline:
    """A simple closed polygon in the mesh frame (metres, counter-clockwise, last ≠ first).

    `corners` are vertex indices kept exactly when the outline is resampled (sharp corners); the
    vertices in between may be dense samples of a curve. Named `keypoints` (vertex indices) are
    always kept too.
    """

    points: np.ndarray
    """N×2 polygon vertices (m), counter-clockwise."""
    keypoints: dict[str, int] = field(default_factory=dict)
    """Named keypoints as indices into `points`."""
    corners: tuple[int, ...] = ()
    """Indices into `points` kept exactly by the resampling, in addition to the keypoints."""

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=float)
        require(
            pts.ndim == 2 and pts.shape[1] == 2 and len(pts) >= 3 and bool(np.isfinite(pts).all()),
            f"an outline needs N ≥ 3 finite 2-D points (N×2), got shape {pts.shape}",
        )
        n = len(pts)
        for name, i in self.keypoints.items():
            require(0 <= i < n, f"outline keypoint {name!r} index {i} is not in [0, {n})")
        for i in self.corners:
            require(0 <= i < n, f"outline corner index {i} is not in [0, {n})")
        seg = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)
        require(bool(seg.min() > 1e-9), "an outline must not repeat a point")
        require(is_simple(pts), "an outline must not cross itself")
        require(signed_area(pts) > 0.0, "an outline must run counter-clockwise (positive area)")
        object.__setattr__(self, "points", pts)

    @property
    def area(self) -> float:
        """Enclosed area (m²)."""
        return signed_area(self.points)

    def keypoint(self, name: str) -> np.ndarray:
        """(x, y) of a named keypoint."""
        return self.points[self.keypoints[name]]


def signed_area(points: np.ndarray) -> float:
    """Shoelace area of a polygon (N×2); positive when counter-clockwise."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def is_simple(points: np.ndarray) -> bool:
    """Whether a closed polygon (N×2) has no two non-adjacent edges that touch or cross."""
    a = points
    b = np.roll(points, -1, axis=0)
    n = len(a)
    d = b - a
    # Edge i against edge j: proper or touching intersection test, vectorised over all pairs.
    ai, di = a[:, None, :], d[:, None, :]
    aj, dj = a[None, :, :], d[None, :, :]
    denom = _cross(di, dj)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = _cross(aj - ai, dj) / denom
        u = _cross(aj - ai, di) / denom
    hit = (np.abs(denom) > 1e-15) & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)
    idx = np.arange(n)
    gap = np.abs(idx[:, None] - idx[None, :])
    adjacent = (gap <= 1) | (gap == n - 1)
    return not bool((hit & ~adjacent).any())


def points_inside(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Bool per point (M×2): strictly inside the polygon (N×2), by the even–odd rule."""
    x, y = points[:, 0][:, None], points[:, 1][:, None]
    x0, y0 = polygon[:, 0][None, :], polygon[:, 1][None, :]
    x1, y1 = np.roll(polygon[:, 0], -1)[None, :], np.roll(polygon[:, 1], -1)[None, :]
    straddle = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (np.count_nonzero(straddle & (x < x_cross), axis=1) % 2) == 1


def distance_to_outline(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance (m) from each point (M×2) to the nearest edge of a closed polygon (N×2)."""
    a = polygon[None, :, :]
    d = np.roll(polygon, -1, axis=0)[None, :, :] - a
    rel = points[:, None, :] - a
    t = np.clip(np.sum(rel * d, axis=2) / np.maximum(np.sum(d * d, axis=2), 1e-18), 0.0, 1.0)
    return np.linalg.norm(rel - t[..., None] * d, axis=2).min(axis=1)


def resample(outline: Outline, spacing: float) -> tuple[np.ndarray, dict[str, int]]:
    """The outline resampled at ≈ `spacing` along its length between kept vertices.

    Returns the new counter-clockwise points (M×2) and the keypoints' indices among them.
    """
    pts = outline.points
    n = len(pts)
    kept = sorted(set(outline.corners) | set(outline.keypoints.values()))
    if not kept:
        kept = [0]
    out: list[np.ndarray] = []
    new_index: dict[int, int] = {}
    for k, start in enumerate(kept):
        end = kept[(k + 1) % len(kept)]
        stop = end if end > start else end + n
        chain = pts[np.arange(start, stop + 1) % n]
        seg = np.linalg.norm(np.diff(chain, axis=0), axis=1)
        s = np.r_[0.0, np.cumsum(seg)]
        m = max(1, round(s[-1] / spacing))
        new_index[start] = sum(len(c) for c in out)
        targets = np.linspace(0.0, s[-1], m + 1)[:-1]  # the end is the next chain's start
        out.append(
            np.stack([np.interp(targets, s, chain[:, 0]), np.interp(targets, s, chain[:, 1])], 1)
        )
    keypoints = {name: new_index[i] for name, i in outline.keypoints.items()}
    return np.concatenate(out), keypoints


def lattice(lo: np.ndarray, hi: np.ndarray, spacing: float) -> np.ndarray:
    """Triangular-lattice points of side `spacing` covering the box [lo, hi], symmetric about x = 0."""
    dy = spacing * math.sqrt(3.0) / 2.0
    rows = np.arange(math.floor(lo[1] / dy), math.ceil(hi[1] / dy) + 1)
    out = []
    for r in rows:
        shift = 0.5 * spacing * (r % 2)
        i0 = math.floor((lo[0] - shift) / spacing)
        i1 = math.ceil((hi[0] - shift) / spacing)
        xs = np.arange(i0, i1 + 1) * spacing + shift
        out.append(np.stack([xs, np.full_like(xs, r * dy)], axis=1))
    return np.concatenate(out)


def triangle_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """F×3 interior angles (rad) of the triangles."""
    p = vertices[faces][..., :2]
    out = np.empty(faces.shape)
    for k in range(3):
        a = p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        cos = np.sum(a * b, axis=1) / np.maximum(
            np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-18
        )
        out[:, k] = np.arccos(np.clip(cos, -1.0, 1.0))
    return out


def _triangulate(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Delaunay triangles of `points` whose centroid lies inside `polygon`, counter-clockwise
    (flat ones left out)."""
    faces = Delaunay(points).simplices
    p = points[faces]
    doubled_area = _cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    scale = float(np.ptp(points, axis=0).max()) ** 2
    # Qhull keeps flat triangles between collinear points of the convex hull (a straight hem).
    keep = (np.abs(doubled_area) > 1e-9 * scale) & points_inside(p.mean(axis=1), polygon)
    faces, doubled_area = faces[keep], doubled_area[keep]
    flip = doubled_area < 0
    faces[flip] = faces[flip][:, [0, 2, 1]]
    return faces


def _smooth(points: np.ndarray, faces: np.ndarray, movable: np.ndarray, rounds: int) -> np.ndarray:
    """Move each movable vertex towards the mean of its mesh neighbours (Laplacian smoothing)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.concatenate([e, e[:, ::-1]])
    n = len(points)
    adj = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    adj.data[:] = 1.0  # shared edges counted once
    deg = np.asarray(adj.sum(axis=1)).reshape(-1)
    pts = points.copy()
    for _ in range(rounds):
        mean = (adj @ pts) / np.maximum(deg, 1.0)[:, None]
        pts[movable] = 0.5 * pts[movable] + 0.5 * mean[movable]
    return pts


def _edge_set(faces: np.ndarray) -> set[tuple[int, int]]:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.sort(e, axis=1)
    return {(int(a), int(b)) for a, b in e}


def outline_mesh(
    outline: Outline, edge_length: float, clearance: float = 0.6, smoothing: int = 3
) -> ClothMesh:
    """A flat triangle mesh filling `outline`, edges ≈ `edge_length` (m), keypoints as vertices.

    The vertices are shifted so the outline's bounding box is centred at the origin (z = 0).
    Raises ConfigError for a bad edge length or when the outline is too fine for it (a mesh
    that would have sliver triangles, a missing outline edge or more than one piece).
    """
    require(
        math.isfinite(edge_length) and MIN_EDGE_LENGTH <= edge_length <= MAX_EDGE_LENGTH,
        f"edge_length must be in [{MIN_EDGE_LENGTH}, {MAX_EDGE_LENGTH}] m, got {edge_length!r}",
    )
    require(0.0 < clearance < 1.0, f"clearance must be in (0, 1) edge lengths, got {clearance!r}")
    boundary, keypoints = resample(outline, edge_length)
    nb = len(boundary)
    lo, hi = boundary.min(axis=0), boundary.max(axis=0)
    inner = lattice(lo, hi, edge_length)
    inner = inner[points_inside(inner, boundary)]
    if len(inner):
        inner = inner[distance_to_outline(inner, boundary) >= clearance * edge_length]
    points = np.concatenate([boundary, inner])
    faces = _triangulate(points, boundary)
    if smoothing > 0 and len(inner):
        movable = np.arange(len(points)) >= nb
        points = _smooth(points, faces, movable, smoothing)
        faces = _triangulate(points, boundary)

    used = np.zeros(len(points), bool)
    used[faces.ravel()] = True
    require(
        bool(used[:nb].all()),
        "the outline is too fine for this edge length: some outline vertices belong to no "
        f"triangle (edge_length {edge_length!r} m)",
    )
    remap = np.cumsum(used) - 1
    points, faces = points[used], remap[faces]
    _check_mesh(points, faces, nb, edge_length)
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    vertices = np.concatenate([points - centre, np.zeros((len(points), 1))], axis=1)
    return ClothMesh(
        vertices=vertices, faces=faces.astype(np.int64), keypoints=keypoints, grid_shape=None
    )


def _check_mesh(points: np.ndarray, faces: np.ndarray, nb: int, edge_length: float) -> None:
    """ConfigError unless the mesh is one piece, bounded by the outline, free of slivers."""
    edges = _edge_set(faces)
    missing = [i for i in range(nb) if (min(i, (i + 1) % nb), max(i, (i + 1) % nb)) not in edges]
    if missing:
        raise ConfigError(
            f"the outline is too fine for edge_length {edge_length!r} m: {len(missing)} outline "
            "edges are not mesh edges"
        )
    n = len(points)
    e = np.array(sorted(edges))
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    pieces, _ = connected_components(graph, directed=False)
    if pieces != 1:
        raise ConfigError(
            f"the outline mesh falls into {pieces} pieces at edge_length {edge_length!r} m"
        )
    worst = math.degrees(float(triangle_angles(points, faces).min()))
    if worst < MIN_ANGLE_DEG:
        raise ConfigError(
            f"the outline mesh has a {worst:.1f}° triangle at edge_length {edge_length!r} m "
            f"(at least {MIN_ANGLE_DEG}° needed); the outline has a feature too small for it"
        )


def mesh_boundary_loops(faces: np.ndarray) -> list[list[int]]:
    """Vertex loops of the mesh boundary (edges used by one triangle), in the faces' winding."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    _, inverse, counts = np.unique(
        np.sort(e, axis=1), axis=0, return_inverse=True, return_counts=True
    )
    border = e[counts[inverse.reshape(-1)] == 1]
    nxt = {int(a): int(b) for a, b in border}
    loops: list[list[int]] = []
    while nxt:
        start = next(iter(nxt))
        loop = [start]
        cur = nxt.pop(start)
        while cur != start:
            loop.append(cur)
            cur = nxt.pop(cur)
        loops.append(loop)
    return loops
