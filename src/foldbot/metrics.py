"""Fold and flatten metrics computed from ground-truth cloth vertices (spec: notes/metrics.md).

Pure numpy/scipy, no simulator import, so anyone can recompute every number of an episode from
`cloth.npz` and the fold lines alone. All lengths are metres except `fold_error_mm`.

Choices where metrics.md leaves room (kept here so the numbers stay comparable):
- "Flat start height" is each vertex's own initial z: goal z_i = z_i(initial) + n_i · thickness.
- A vertex exactly on a fold line (side value == 0) stays; it is neither moved nor paired.
- SoftGym pairing: moving side A is taken in the initial configuration; each A vertex is paired
  with the staying vertex nearest (in the table plane) to its mirror image across the line in the
  initial configuration. On a regular grid with the line on a grid symmetry this is the exact
  mirrored vertex. `fixation_dist` averages over the paired partners (a partner used twice counts
  twice), like SoftGym's index lists. `group_dist` is the plain 3-D distance, so a perfect fold of a
  cloth of thickness t has group_dist = t and normalized = 1 − t / group_dist_start (≈ 1).
- Multi-fold recipes: the first fold's performance is judged on the final state, whose staying
  side B was legitimately moved by later folds. Taken literally (fixation against B's start) a
  perfect quarter fold scores ≈ 0.44 and could never succeed, so `score_episode` measures fixation
  against B's goal under the whole recipe. For a one-fold recipe that goal is B's start, i.e.
  SoftGym exactly; `performance_start` is still computed with final := initial.
- Coverage is not clipped to 1 (a stretched cloth can exceed it).
- `perfect_fold_error_mm` is foldbot's own diagnostic, not a metrics.md figure: what a physically
  perfect fold, lying flat, would score. The layer rule stacks a fold above every earlier layer
  even where none lies beneath (a T-shirt's second side fold goes on layer 3 over one layer), so
  for some recipes even that fold scores far from 0. It changes no other number.
- `perfect_normalized` is its counterpart for the normalized performance: what a fold that lands
  every vertex on the layer rule's goal scores. SoftGym's pairing (the nearest vertex where the
  mesh has no mirror partner) and the cloth's thickness keep it under 1, on a coarse mesh near
  the 0.8 that success asks, so the margin a fold has is the distance to it, not to 1.
- `self_crossings` of the final cloth is a diagnostic on ground truth too: a simulated fold that
  passed through itself is reported, and scored as metrics.md says all the same.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from foldbot.errors import ConfigError

FOLD_SUCCESS_MIN_NORMALIZED = 0.8
"""Minimum SoftGym normalized performance of the first fold for a fold episode to succeed."""
FOLD_SUCCESS_ERROR_FACTOR = 0.05
"""Fold error limit as a fraction of √(flat cloth area) (15 mm for a 0.3 m × 0.3 m towel)."""
FLATTEN_SUCCESS_MIN_COVERAGE = 0.9
"""Minimum coverage for a flatten episode to succeed."""
MAX_COVERAGE_RESOLUTION = 0.002
"""Coarsest allowed coverage raster cell, metres (metrics.md: ≤ 2 mm)."""
_MAX_RASTER_PIXELS = 64_000_000
_RASTER_BATCH_ELEMENTS = 4_000_000


@dataclass(frozen=True)
class FoldLine:
    """A fold line in the table plane (world frame): point (x, y) and direction (dx, dy), metres.

    The moving side is the one to the left of the direction: (−dy, dx) · (p − (x, y)) > 0.
    """

    x: float
    y: float
    dx: float
    dy: float

    def __post_init__(self) -> None:
        for name in ("x", "y", "dx", "dy"):
            raw = getattr(self, name)
            try:
                value = float(raw)
            except (TypeError, ValueError):
                raise ConfigError(f"FoldLine.{name} = {raw!r} must be a finite number") from None
            if not math.isfinite(value):
                raise ConfigError(f"FoldLine.{name} = {raw!r} must be a finite number")
            object.__setattr__(self, name, value)
        if math.hypot(self.dx, self.dy) <= 1e-12:
            raise ConfigError(
                f"FoldLine direction (dx, dy) = ({self.dx!r}, {self.dy!r}) must be non-zero"
            )

    @classmethod
    def coerce(cls, value: FoldLine | Sequence[float]) -> FoldLine:
        """Return `value` as a FoldLine; accepts a FoldLine or a sequence [x, y, dx, dy]."""
        if isinstance(value, FoldLine):
            return value
        items = list(value) if isinstance(value, Sequence | np.ndarray) else []
        if isinstance(value, str | bytes) or len(items) != 4:
            raise ConfigError(f"fold line {value!r} must be [x, y, dx, dy] (4 numbers)")
        return cls(*items)

    def as_list(self) -> list[float]:
        """Return [x, y, dx, dy] as plain floats (the result.json form)."""
        return [self.x, self.y, self.dx, self.dy]

    def side(self, xy: np.ndarray) -> np.ndarray:
        """Signed side value (−dy, dx) · (p − (x, y)) of each point (N×2+, only x, y used)."""
        xy = np.asarray(xy, dtype=float)
        return -self.dy * (xy[..., 0] - self.x) + self.dx * (xy[..., 1] - self.y)

    def moving_mask(self, xy: np.ndarray) -> np.ndarray:
        """Boolean mask of points strictly on the moving (left) side of the line."""
        return self.side(xy) > 0.0

    def reflect_xy(self, points: np.ndarray) -> np.ndarray:
        """Mirror the x, y of points (N×2 or N×3) across the line; other columns are unchanged."""
        out = np.array(points, dtype=float, copy=True)
        norm = math.hypot(self.dx, self.dy)
        nx, ny = -self.dy / norm, self.dx / norm
        s = nx * (out[..., 0] - self.x) + ny * (out[..., 1] - self.y)
        out[..., 0] -= 2.0 * s * nx
        out[..., 1] -= 2.0 * s * ny
        return out


def as_fold_lines(fold_lines: Iterable[FoldLine | Sequence[float]]) -> tuple[FoldLine, ...]:
    """Coerce a sequence of fold lines ([x, y, dx, dy] or FoldLine) into a tuple of FoldLine."""
    if isinstance(fold_lines, FoldLine):
        return (fold_lines,)
    if isinstance(fold_lines, str | bytes) or not isinstance(fold_lines, Iterable):
        raise ConfigError(f"fold_lines = {fold_lines!r} must be a list of [x, y, dx, dy]")
    return tuple(FoldLine.coerce(line) for line in fold_lines)


def _points(name: str, value: Any) -> np.ndarray:
    """Validate a V×3 finite float array of vertex positions."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise ConfigError(
            f"{name} must be a non-empty V×3 array of positions, got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} contains non-finite values (NaN or inf)")
    return arr


def _faces(value: Any, n_vertices: int) -> np.ndarray:
    """Validate an F×3 integer array of vertex indices in [0, n_vertices)."""
    arr = np.asarray(value)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ConfigError(f"faces must be an F×3 integer array, got shape {arr.shape}")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise ConfigError(f"faces must have an integer dtype, got {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.size and (arr.min() < 0 or arr.max() >= n_vertices):
        raise ConfigError(
            f"faces index range [{arr.min()}, {arr.max()}] is outside [0, {n_vertices - 1}]"
        )
    return arr


def _thickness(value: Any) -> float:
    """Validate a finite, non-negative cloth thickness in metres."""
    try:
        t = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"thickness = {value!r} must be a finite number ≥ 0 (m)") from None
    if not math.isfinite(t) or t < 0.0:
        raise ConfigError(f"thickness = {value!r} must be a finite number ≥ 0 (m)")
    return t


def _same_shape(a_name: str, a: np.ndarray, b_name: str, b: np.ndarray) -> None:
    """Raise ConfigError unless two vertex arrays have the same shape."""
    if a.shape != b.shape:
        raise ConfigError(f"{a_name} shape {a.shape} differs from {b_name} shape {b.shape}")


def fold_goal(
    initial: np.ndarray,
    fold_lines: Iterable[FoldLine | Sequence[float]],
    thickness: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Goal vertices (V×3) and layer indices (V,) of a fold recipe, composed fold by fold.

    Each fold reflects the x, y of the vertices left of its line (tested on the previous goal),
    sets their layer to 2·n_max + 1 − n, and the goal z is the vertex's initial z + n · thickness.
    """
    start = _points("initial", initial)
    t = _thickness(thickness)
    lines = as_fold_lines(fold_lines)
    goal = start.copy()
    layers = np.zeros(start.shape[0], dtype=np.int64)
    for line in lines:
        moving = line.moving_mask(goal)
        n_max = int(layers.max())
        goal[moving] = line.reflect_xy(goal[moving])
        layers[moving] = 2 * n_max + 1 - layers[moving]
    goal[:, 2] = start[:, 2] + layers * t
    return goal, layers


def fold_error_mm(final: np.ndarray, goal: np.ndarray) -> float:
    """Mean 3-D distance of final vertices to their goal, in mm (FabricFlowNet's measure)."""
    f = _points("final", final)
    g = _points("goal", goal)
    _same_shape("final", f, "goal", g)
    return float(1000.0 * np.mean(np.linalg.norm(f - g, axis=1)))


_INSIDE_CHUNK_ELEMENTS = 2_000_000


def _inside_any(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """For each 2-D point, whether it lies in at least one of the triangles (T×3×2, edges
    inclusive)."""
    out = np.zeros(points.shape[0], dtype=bool)
    if tris.shape[0] == 0:
        return out
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    det = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
    keep = np.abs(det) > 1e-18
    a, b, c, det = a[keep], b[keep], c[keep], det[keep]
    step = max(1, _INSIDE_CHUNK_ELEMENTS // max(det.size, 1))
    tol = 1e-9
    for s in range(0, points.shape[0], step):
        px = points[s : s + step, 0, None] - c[None, :, 0]
        py = points[s : s + step, 1, None] - c[None, :, 1]
        l1 = ((b[:, 1] - c[:, 1]) * px + (c[:, 0] - b[:, 0]) * py) / det
        l2 = ((c[:, 1] - a[:, 1]) * px + (a[:, 0] - c[:, 0]) * py) / det
        out[s : s + step] = ((l1 >= -tol) & (l2 >= -tol) & (1.0 - l1 - l2 >= -tol)).any(axis=1)
    return out


def physical_layers(goal: np.ndarray, layers: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """How many sheets of cloth physically lie under each vertex in the goal (V,): the number of
    distinct lower layer indices whose goal triangles cover the vertex in the table plane. A
    triangle across a crease (its vertices on two layers) is the hinge joining two sheets and
    counts for each of them, not for layers the rule skipped between them.

    metrics.md's layer rule lifts a fold's moving side above every layer folded so far
    (2·n_max + 1 − n), also where nothing of those layers lies beneath it: two side folds that do
    not overlap put the second on layer 3 over a single sheet. A cloth resting on what is under
    it cannot reach that height; this count is the height it can reach.
    """
    g = _points("goal", goal)
    n = np.asarray(layers, dtype=np.int64).reshape(-1)
    if n.shape[0] != g.shape[0]:
        raise ConfigError(f"layers has {n.shape[0]} entries, goal has {g.shape[0]} vertices")
    tris = _faces(faces, g.shape[0])
    face_layers = n[tris]
    counts = np.zeros(g.shape[0], dtype=np.int64)
    for value in np.unique(face_layers):
        above = n > value
        sheet = tris[(face_layers == value).any(axis=1)]
        if above.any() and sheet.size:
            counts[above] += _inside_any(g[above, :2], g[sheet][:, :, :2])
    return counts


def perfect_fold_error_mm(
    initial: np.ndarray,
    faces: np.ndarray,
    fold_lines: Iterable[FoldLine | Sequence[float]],
    thickness: float,
) -> float:
    """The fold error (mm) of a physically perfect fold: every vertex at its goal in the table
    plane, lying flat on the sheets beneath it (`physical_layers`), scored against the layer
    rule's goal heights. 0 where every fold lands on all earlier layers (half, quarter,
    diagonal). Not a lower bound: a real stack stands higher than flat sheets, nearer the rule."""
    start = _points("initial", initial)
    t = _thickness(thickness)
    goal, layers = fold_goal(start, fold_lines, t)
    return _perfect_fold_mm(goal, layers, faces, t)


def perfect_normalized(
    initial: np.ndarray,
    fold_lines: Iterable[FoldLine | Sequence[float]],
    thickness: float,
) -> float:
    """The first fold's normalized performance (as score_episode judges it) of a fold that lands
    every vertex on the layer rule's goal: under 1 by the cloth's `thickness` (m) between a
    folded vertex and its partner, and where the mesh has no exact mirror partner by the
    pairing's offset, which a coarse mesh makes large."""
    start = _points("initial", initial)
    lines = as_fold_lines(fold_lines)
    if not lines:
        raise ConfigError("fold_lines is empty; a perfect fold needs at least one fold line")
    goal, _ = fold_goal(start, lines, _thickness(thickness))
    return _normalized_at_goal(start, goal, lines)


def _normalized_at_goal(start: np.ndarray, goal: np.ndarray, lines: tuple[FoldLine, ...]) -> float:
    """The first fold's normalized performance of the cloth lying exactly on `goal`."""
    return softgym_performance(start, goal, lines[0], staying_reference=goal).normalized


def _perfect_fold_mm(
    goal: np.ndarray, layers: np.ndarray, faces: np.ndarray, thickness: float
) -> float:
    """Mean height (mm) the layer rule asks above the sheets physically under each vertex."""
    resting = physical_layers(goal, layers, faces)
    return float(1000.0 * thickness * np.mean(np.abs(layers - resting)))


@dataclass(frozen=True)
class FoldPerformance:
    """SoftGym ClothFold performance of one fold (distances in metres)."""

    group_dist: float
    fixation_dist: float
    performance: float
    performance_start: float
    normalized: float


def fold_pairs(
    initial: np.ndarray, fold_line: FoldLine | Sequence[float]
) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays (A, B): moving vertices and their mirror partners on the staying side."""
    start = _points("initial", initial)
    line = FoldLine.coerce(fold_line)
    side = line.side(start)
    group_a = np.flatnonzero(side > 0.0)
    staying = np.flatnonzero(side <= 0.0)
    if group_a.size == 0 or staying.size == 0:
        raise ConfigError(
            f"fold line {line.as_list()} does not split the cloth: {group_a.size} vertices on the "
            f"moving side, {staying.size} on the staying side (both must be > 0)"
        )
    mirror = line.reflect_xy(start[group_a])[:, :2]
    _, nearest = cKDTree(start[staying, :2]).query(mirror)
    return group_a, staying[np.asarray(nearest, dtype=np.int64)]


def softgym_performance(
    initial: np.ndarray,
    final: np.ndarray,
    fold_line: FoldLine | Sequence[float],
    staying_reference: np.ndarray | None = None,
) -> FoldPerformance:
    """SoftGym ClothFold performance and its normalized form for one fold along `fold_line`.

    `staying_reference` (V×3) is where the staying side B should be; None means its start
    position (SoftGym exactly). `score_episode` passes the goal of the whole recipe, which equals
    the start for a one-fold recipe and keeps later folds from counting as fixation error.
    """
    start = _points("initial", initial)
    end = _points("final", final)
    _same_shape("final", end, "initial", start)
    if staying_reference is None:
        ref = start
    else:
        ref = _points("staying_reference", staying_reference)
        _same_shape("staying_reference", ref, "initial", start)
    group_a, group_b = fold_pairs(start, fold_line)

    def perf(pos: np.ndarray) -> tuple[float, float, float]:
        group = float(np.mean(np.linalg.norm(pos[group_a] - pos[group_b], axis=1)))
        fixation = float(np.mean(np.linalg.norm(pos[group_b] - ref[group_b], axis=1)))
        return group, fixation, -group - 1.2 * fixation

    _, _, perf_start = perf(start)
    if perf_start > -1e-12:
        raise ConfigError(
            f"SoftGym performance_start = {perf_start!r} is 0 for fold line "
            f"{FoldLine.coerce(fold_line).as_list()}: the moving vertices already lie on their "
            "mirror partners in the initial configuration, so normalized performance is undefined"
        )
    group, fixation, performance = perf(end)
    normalized = (performance - perf_start) / (0.0 - perf_start)
    return FoldPerformance(group, fixation, performance, perf_start, float(normalized))


def flat_area(initial: np.ndarray, faces: np.ndarray) -> float:
    """Area (m²) of the cloth lying flat: the sum of its triangle areas in the start state."""
    start = _points("initial", initial)
    tris = _faces(faces, start.shape[0])
    if tris.shape[0] == 0:
        raise ConfigError("faces is empty; the flat cloth area needs at least one triangle")
    a, b, c = start[tris[:, 0]], start[tris[:, 1]], start[tris[:, 2]]
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


def _raster_union(xy: np.ndarray, tris: np.ndarray, resolution: float) -> int:
    """Count raster cells whose centre lies in at least one triangle (edges inclusive)."""
    lo = xy.min(axis=0) - 2.0 * resolution
    p = (xy - lo) / resolution  # pixel units; cell (i, j) has its centre at (j + 0.5, i + 0.5)
    width, height = (np.ceil(p.max(axis=0)).astype(np.int64) + 2).tolist()
    if width * height > _MAX_RASTER_PIXELS:
        extent = (xy.max(axis=0) - xy.min(axis=0)).tolist()
        raise ConfigError(
            f"cloth extent {extent} m needs a {width}×{height} raster at {resolution} m; "
            f"allowed up to {_MAX_RASTER_PIXELS} cells (did the simulation diverge?)"
        )
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    keep = np.abs(cross) > 1e-12
    a, b, c, cross = a[keep], b[keep], c[keep], cross[keep]
    flip = cross < 0  # make every triangle counter-clockwise
    b, c = np.where(flip[:, None], c, b), np.where(flip[:, None], b, c)
    corners = np.stack([a, b, c], axis=1)  # T×3×2
    j0 = np.ceil(corners[:, :, 0].min(axis=1) - 0.5).astype(np.int64)
    j1 = np.floor(corners[:, :, 0].max(axis=1) - 0.5).astype(np.int64)
    i0 = np.ceil(corners[:, :, 1].min(axis=1) - 0.5).astype(np.int64)
    i1 = np.floor(corners[:, :, 1].max(axis=1) - 0.5).astype(np.int64)
    bw, bh = j1 - j0 + 1, i1 - i0 + 1
    valid = (bw > 0) & (bh > 0)
    mask = np.zeros((height, width), dtype=bool)
    order = np.flatnonzero(valid)[np.argsort((bw * bh)[valid], kind="stable")]
    start = 0
    while start < order.size:
        # grow a batch of similarly sized bounding boxes up to the element budget
        cells = int(bw[order[start]] * bh[order[start]])
        count = max(1, _RASTER_BATCH_ELEMENTS // max(cells, 1))
        idx = order[start : start + count]
        w_max, h_max = int(bw[idx].max()), int(bh[idx].max())
        while idx.size > 1 and idx.size * w_max * h_max > _RASTER_BATCH_ELEMENTS:
            idx = idx[: idx.size // 2]
            w_max, h_max = int(bw[idx].max()), int(bh[idx].max())
        start += idx.size
        dj, di = np.meshgrid(np.arange(w_max), np.arange(h_max))
        jj = j0[idx, None, None] + dj[None]  # B×h×w
        ii = i0[idx, None, None] + di[None]
        px, py = jj + 0.5, ii + 0.5
        inside = (jj <= j1[idx, None, None]) & (ii <= i1[idx, None, None])
        tri = corners[idx]
        for k in range(3):
            ax, ay = tri[:, k, 0, None, None], tri[:, k, 1, None, None]
            bx, by = tri[:, (k + 1) % 3, 0, None, None], tri[:, (k + 1) % 3, 1, None, None]
            edge = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
            inside &= edge >= -1e-9
        mask[ii[inside], jj[inside]] = True
    return int(mask.sum())


def coverage(
    vertices: np.ndarray,
    faces: np.ndarray,
    flat_area: float,
    resolution: float = MAX_COVERAGE_RESOLUTION,
) -> float:
    """Union area of the triangles projected on the table (xy), over the flat cloth area.

    Rasterised at `resolution` metres (≤ 2 mm): a cell counts when its centre lies in a triangle.
    """
    pts = _points("vertices", vertices)
    tris = _faces(faces, pts.shape[0])
    try:
        area = float(flat_area)
        res = float(resolution)
    except (TypeError, ValueError):
        raise ConfigError(
            f"flat_area = {flat_area!r} and resolution = {resolution!r} must be numbers"
        ) from None
    if not math.isfinite(area) or area <= 0.0:
        raise ConfigError(f"flat_area = {flat_area!r} must be a finite area > 0 (m²)")
    if not math.isfinite(res) or not 0.0 < res <= MAX_COVERAGE_RESOLUTION:
        raise ConfigError(
            f"resolution = {resolution!r} must be in (0, {MAX_COVERAGE_RESOLUTION}] m (metrics.md)"
        )
    if tris.shape[0] == 0:
        return 0.0
    cells = _raster_union(pts[:, :2], tris, res)
    return float(cells * res * res / area)


def self_crossings(vertices: np.ndarray, faces: np.ndarray) -> int:
    """How many (edge, triangle) pairs of the mesh, sharing no vertex, cross: the edge passes
    through the triangle. A real cloth never does (it cannot pass through itself); a simulated
    one that has is tangled, and no flattening lays it flat. 0 for any untangled cloth, folded or
    crumpled; a diagnostic on ground truth, not a metric of metrics.md."""
    return int(self_crossing_pairs(vertices, faces).shape[0])


def self_crossing_pairs(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The crossings that self_crossings counts, as rows (edge's first vertex, edge's second
    vertex, triangle's index in `faces`), sorted: which part of the cloth passed through which
    (scripts/trace_crossings.py). Empty (0×3) for an untangled cloth."""
    pts = _points("vertices", vertices)
    tris = _faces(faces, pts.shape[0])
    if tris.shape[0] == 0:
        return np.zeros((0, 3), dtype=np.int64)
    edges = np.unique(np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    p, q, r = (pts[tris[:, k]][None] for k in range(3))
    normal = np.cross(q - p, r - p)
    found = []
    for lo in range(0, edges.shape[0], 256):  # chunks keep the edge × triangle arrays small
        e = edges[lo : lo + 256]
        a, b = pts[e[:, 0]][:, None], pts[e[:, 1]][:, None]
        # a and b on opposite sides of the triangle's plane …
        sides = np.einsum("...i,...i->...", normal, a - p) * np.einsum(
            "...i,...i->...", normal, b - p
        )
        # … and the line ab passing inside the triangle: the same turn round all three sides
        d = b - a
        turns = [
            np.einsum("...i,...i->...", np.cross(d, u - a), w - a)
            for u, w in ((p, q), (q, r), (r, p))
        ]
        inside = ((turns[0] > 0) & (turns[1] > 0) & (turns[2] > 0)) | (
            (turns[0] < 0) & (turns[1] < 0) & (turns[2] < 0)
        )
        shared = (e[:, :1, None] == tris[None]).any(axis=2) | (e[:, 1:, None] == tris[None]).any(
            axis=2
        )
        ei, ti = np.nonzero((sides < 0) & inside & ~shared)
        found.append(np.column_stack([e[ei], ti]))
    return np.concatenate(found).astype(np.int64)


def fold_error_limit_mm(flat_area_m2: float) -> float:
    """Largest fold error (mm) a successful fold may have: 0.05 · √(flat area), in mm."""
    area = float(flat_area_m2)
    if not math.isfinite(area) or area <= 0.0:
        raise ConfigError(f"flat_area_m2 = {flat_area_m2!r} must be a finite area > 0 (m²)")
    return 1000.0 * FOLD_SUCCESS_ERROR_FACTOR * math.sqrt(area)


def success(normalized: float, fold_error_mm: float, flat_area_m2: float) -> bool:
    """Fold success: normalized ≥ 0.8 and fold error ≤ 0.05·√area (15 mm for a 0.09 m² towel)."""
    limit = fold_error_limit_mm(flat_area_m2)
    n, e = float(normalized), float(fold_error_mm)
    if not (math.isfinite(n) and math.isfinite(e)):
        return False
    # 1e-9 mm slack so the stated 15 mm boundary is inclusive despite √0.09 rounding
    return n >= FOLD_SUCCESS_MIN_NORMALIZED and e <= limit + 1e-9


def keypoint_errors_mm(
    perceived: dict[str, Sequence[float]], truth: dict[str, Sequence[float]]
) -> dict[str, float]:
    """3-D distance (mm) of each perceived keypoint from the true one of the same name (the
    names both have), as `eval-perception` measures them."""
    out = {}
    for name in perceived:
        if name in truth:
            p = np.asarray(perceived[name], dtype=float).reshape(3)
            t = np.asarray(truth[name], dtype=float).reshape(3)
            out[name] = float(1000.0 * np.linalg.norm(p - t))
    return out


def flatten_success(coverage: float) -> bool:
    """Flatten success: coverage ≥ 0.9."""
    c = float(coverage)
    return math.isfinite(c) and c >= FLATTEN_SUCCESS_MIN_COVERAGE


@dataclass(frozen=True)
class FoldScore:
    """Every metric of a fold episode: what result.json reports and `rescore` recomputes."""

    fold_error_mm: float
    normalized_performance: float  # SoftGym, first fold
    coverage: float
    success: bool
    flat_area_m2: float
    perfect_fold_error_mm: float
    """What a physically perfect fold, lying flat, would score (see perfect_fold_error_mm)."""
    perfect_normalized: float
    """The normalized performance of a fold that lands every vertex on its goal: the most this
    mesh and thickness can score (see perfect_normalized)."""
    self_crossings: int
    """Mesh edges through the final cloth's own triangles (self_crossings): 0 for a cloth that
    has not passed through itself, which no real cloth does."""

    def as_dict(self) -> dict[str, float | bool]:
        """Return the metrics as a plain dict (keys as in result.json)."""
        return asdict(self)


def score_episode(
    initial: np.ndarray,
    final: np.ndarray,
    faces: np.ndarray,
    fold_lines: Iterable[FoldLine | Sequence[float]],
    thickness: float,
) -> FoldScore:
    """Score a fold episode from ground truth alone: the one entry point for every metric."""
    start = _points("initial", initial)
    end = _points("final", final)
    _same_shape("final", end, "initial", start)
    tris = _faces(faces, start.shape[0])
    lines = as_fold_lines(fold_lines)
    if not lines:
        raise ConfigError("fold_lines is empty; a fold episode needs at least one fold line")
    goal, layers = fold_goal(start, lines, thickness)
    error = fold_error_mm(end, goal)
    perfect = _perfect_fold_mm(goal, layers, tris, _thickness(thickness))
    normalized = softgym_performance(start, end, lines[0], staying_reference=goal).normalized
    area = flat_area(start, tris)
    cov = coverage(end, tris, area)
    return FoldScore(
        fold_error_mm=error,
        normalized_performance=normalized,
        coverage=cov,
        success=success(normalized, error, area),
        flat_area_m2=area,
        perfect_fold_error_mm=perfect,
        perfect_normalized=_normalized_at_goal(start, goal, lines),
        self_crossings=self_crossings(end, tris),
    )
