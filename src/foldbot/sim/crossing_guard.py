"""Keeps the simulated cloth from passing through itself: a mesh point found on the far side of a
nearby triangle of its own cloth is put back on the side it came from.

Bullet's cloth–cloth contact pushes a mesh point out of the contact distance of the triangles
around it, whichever side it is on, so a point pressed through a layer (a heap dropped, a stack
squeezed) stays through it, and the cloth is tangled for good: no real cloth can be, and a
tangled heap cannot be laid flat (docs/experiments.md, "A cloth through itself"). The guard
remembers, for every mesh point lying close over a triangle's face, which side it lies on; a point
found over the face on the other side is moved back along the face's normal to one collision
margin on its own side, where Bullet's contact then keeps it. Sides are learned as points come
close, so the guard must watch from the flat start. It does not catch an edge sliding through
another edge between their points (a version that pushed such edges apart made heaps blow up),
and a point that comes close already through, or that goes round the cloth's border and back
through, is learned on its new side: guarded heaps still pass through themselves, far less.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

INSIDE_SLACK = 0.02
"""A point is over a face where each barycentric coordinate of its projection is ≥ −this."""
NEAR_SLACK = 0.3
"""… and near it (its side remembered) where each is ≥ −this and it lies within the track
distance of the face's plane."""
NEIGHBOUR_EDGES = 1.0
"""Faces whose centroid lay within this many mesh edges of a point in the flat cloth are its
neighbours, not watched."""


class CrossingGuard:
    """A physics step hook (SimWorld.add_step_hook): every `every` steps, put back the mesh points
    of `cloth` that went through one of its faces. `restored` counts the points put back."""

    def __init__(
        self,
        cloth,
        every: int = 1,
        track_distance: float | None = None,
        restore_distance: float | None = None,
    ) -> None:
        if every < 1:
            raise ValueError(f"crossing guard: every must be ≥ 1 physics step, got {every!r}")
        self.cloth = cloth
        self.every = every
        self.track_distance = 4.0 * cloth.margin if track_distance is None else track_distance
        """How far (m) from a face's plane a point's side is remembered: four margins, twice the
        cloth–cloth contact distance."""
        self.restore_distance = cloth.margin if restore_distance is None else restore_distance
        """How far (m) from the face a point put back is laid, on its own side."""
        self.faces = cloth.node_faces()
        rest = cloth.node_positions()  # the flat start: the cell builds the guard with the cloth
        n_nodes = len(rest)
        # Per face and corner: is the edge opposite the corner on the cloth's border? A point can
        # go round a border edge to the other side; round an inner edge it would cross the next face.
        opposite = np.stack(
            [self.faces[:, [1, 2]], self.faces[:, [2, 0]], self.faces[:, [0, 1]]], axis=1
        )
        keys = np.sort(opposite, axis=2).reshape(-1, 2)
        _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
        self.border = (counts[inverse.ravel()] == 1).reshape(-1, 3)
        longest = np.linalg.norm(rest[self.faces] - rest[np.roll(self.faces, 1, axis=1)], axis=2)
        self.reach = 0.6 * float(longest.max()) + self.track_distance
        """Search radius (m) around a face's centroid for points near it."""
        centroid = rest[self.faces].mean(axis=1)
        self.neighbour = (
            np.linalg.norm(rest[:, None, :] - centroid[None, :, :], axis=2)
            < NEIGHBOUR_EDGES * float(cloth.mesh.edge_length)
        ) | (self.faces[None, :, :] == np.arange(n_nodes)[:, None, None]).any(axis=2)
        """Per point and face: the face is the point's own or lies round it in the flat cloth,
        where the point cannot go through it (a fold bends the cloth between them)."""
        self.side = np.zeros((n_nodes, len(self.faces)), dtype=np.int8)
        """+1 / −1: the side of the face (its normal's or the other) a point near it lies on;
        0: not near."""
        self._near = (np.zeros(0, dtype=int), np.zeros(0, dtype=int))
        self.restored = 0

    def __call__(self, world) -> None:
        if world.steps % self.every == 0:
            self.check()

    def check(self) -> int:
        """Learn the sides of the points near each face, put back those found on the other side;
        returns how many were put back."""
        x = self.cloth.node_positions()
        tri = x[self.faces]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(normal, axis=1)
        normal /= np.maximum(length, 1e-12)[:, None]
        pairs = cKDTree(x).sparse_distance_matrix(
            cKDTree(tri.mean(axis=1)), self.reach, output_type="ndarray"
        )
        vi, fi = pairs["i"].astype(int), pairs["j"].astype(int)
        keep = ~self.neighbour[vi, fi] & (length[fi] > 1e-12)
        vi, fi = vi[keep], fi[keep]
        a = tri[fi, 0]
        height = np.einsum("ij,ij->i", x[vi] - a, normal[fi])
        close = np.abs(height) < self.track_distance
        vi, fi, a, height = vi[close], fi[close], a[close], height[close]
        normal_p = normal[fi]
        foot = x[vi] - height[:, None] * normal_p
        bary = barycentric(foot, a, tri[fi, 1], tri[fi, 2])
        # Only points near a face matter (a side is kept for them alone), and they are few: the
        # rest of the check runs on those pairs only.
        near = (bary >= -NEAR_SLACK).all(axis=1)
        vi, fi, height, bary = vi[near], fi[near], height[near], bary[near]
        foot, normal_p = foot[near], normal_p[near]
        out = bary < -INSIDE_SLACK
        over = ~out.any(axis=1)
        round_border = (out & self.border[fi]).any(axis=1)
        sign = np.where(height >= 0, 1, -1).astype(np.int8)
        old = self.side[vi, fi]
        crossed = over & (old != 0) & (sign != old)
        # A side is learned over the face and kept while the point is beyond an inner edge; beyond
        # the border it is forgotten (the point may come back round on the other side).
        side = np.where(over, np.where(old != 0, old, sign), np.where(round_border, 0, old))
        self.side[self._near] = 0
        remember = side != 0
        self.side[vi[remember], fi[remember]] = side[remember]
        self._near = (vi[remember], fi[remember])
        if not crossed.any():
            return 0
        # Each crossed point goes back onto its own side of the face it went deepest through.
        idx = np.flatnonzero(crossed)
        idx = idx[np.argsort(-np.abs(height[idx]))]
        _, first = np.unique(vi[idx], return_index=True)
        fix = idx[first]
        x[vi[fix]] = foot[fix] + (old[fix] * self.restore_distance)[:, None] * normal_p[fix]
        self.cloth.set_node_positions(x)
        self.restored += len(fix)
        return len(fix)


def barycentric(q: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (N×3) of points q in triangles (a, b, c), row by row."""
    v0, v1, v2 = b - a, c - a, q - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    den = d00 * d11 - d01 * d01
    den = np.where(np.abs(den) < 1e-18, 1e-18, den)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return np.column_stack([1.0 - v - w, v, w])
