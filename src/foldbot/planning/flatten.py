"""Flattening pulls from perception alone: fit the item's expected flat outline to the perceived
cloth, find where the cloth falls shortest of it, and pull the nearest cloth edge out there.

The robot is told which item it handles (a towel of nominal width × height), never the cloth's
state: the expected rectangle is placed where it overlaps the perceived top-view outline most,
inside the workspace, and each pull grasps the outline point nearest the rectangle's worst-covered
corner or edge midpoint (a little inside the edge, at table level so the jaws hold every layer
there) and places it just beyond that point. World frame, metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from foldbot.errors import FoldbotError, require
from foldbot.perception.geometry import backproject
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.types import Observation

TARGET_NAMES = (
    "corner_a",
    "edge_ab",
    "corner_b",
    "edge_bc",
    "corner_c",
    "edge_cd",
    "corner_d",
    "edge_da",
)
"""Pull targets on the expected outline, counter-clockwise: its corners and edge midpoints."""
GRASP_LAYERS = ("all", "top")
"""FlattenConfig.grasp_layer values."""
_JAW_REACH_BELOW = 0.004
"""The closing jaws catch cloth down to ~5 mm below the grasp point (ClothGrasp); with margin."""


@dataclass(frozen=True)
class FlattenConfig:
    """When flattening stops and how each pick-and-place pull is placed."""

    target_coverage: float = 0.9
    """Stop once the perceived coverage (top-view area / expected flat area) reaches this."""
    max_actions: int = 6
    """Most pulls before giving up (a pull's grasp retries, nothing carried, are part of it)."""
    finish_coverage: float | None = 0.97
    """Once the target is reached, pulls go on while the perceived coverage is under this and
    actions remain: a laid edge left wavy, a corner folded under, pulled out before the fold
    (towel_crumpled_two_arms over 80 towels, with `min_pull` 1 cm: folds 39 against 35 at 0.95
    and 2 cm; docs/experiments.md). A finishing pull that takes the coverage back under the
    target ends the finishing. None: stop at the target."""
    grasp_inset: float = 0.015
    """The grasp lies this far inside the perceived outline (m), so the jaws land on cloth."""
    grasp_height: float = 0.004
    """Lowest grasp point height above the perceived table (m)."""
    grasp_layer: str = "all"
    """all: the jaws close at the table and hold every layer at the edge (a pull drags the
    whole edge); top: they close just under the perceived top surface there and hold the top
    layer only, so pulling a folded edge unrolls the fold instead of dragging both layers."""
    top_depth: float = 0.002
    """top: the grasp point lies this far below the perceived top surface (m); the jaws catch
    cloth from ~5 mm below it, less than one simulated layer's thickness (≥ 6.7 mm)."""
    release_height: float = 0.03
    """The grasped point is let go this high above the table (m): the gripper's palm (~4.5 cm
    above the jaw tips) then stays clear of cloth heaped at the place point; pressing a heap
    into the table made the simulated cloth blow up (measured)."""
    palm_clearance: float = 0.04
    """A grasp where the perceived cloth within `palm_radius` rises more than this above the
    grasp point (m) would push the palm into the heap: such pulls are tried last."""
    palm_radius: float = 0.06
    """Half the palm's longest side (m): where the descending palm meets cloth."""
    retries: int = 1
    """A failed grasp is retried this often within the same pull, each time …"""
    retry_step: float = 0.015
    """… this much further inside the cloth (m): the simulated jaws hold mesh points only, which
    lie up to 3 cm apart on a large towel, so a grasp can close between them."""
    missed_radius: float = 0.02
    """A pull whose grasp lies within this of a spot where an earlier pull's every try missed
    (m) is tried after the others (0: no memory): a missed grasp moves nothing, so the next plan
    from the same view would try the same spot again."""
    max_inset: float = 0.10
    """Farthest inside the edge (m) a grasp moves looking for cloth high enough to catch with
    the palm clear of the heap."""
    overshoot: float = 0.01
    """The grasped point is placed this far beyond the expected outline (m), along the pull."""
    min_pull: float = 0.01
    """Targets the cloth falls less than this short of (m) are not worth a pull. A corner a
    spread folded under leaves a chamfer the best-fitting rectangle falls only 1–2 cm short
    of: 2 cm left it under (the oracle's pulls were measured at 2 cm)."""
    yaw_step: float = math.radians(5.0)
    """Yaw step (rad) of the search for the expected outline's best-overlapping pose."""
    raster: float = 0.005
    """Cell size (m) of the top-view raster the expected outline is fitted on."""
    workspace: tuple[float, float, float, float] = (0.22, 0.75, -0.30, 0.30)
    """(x_min, x_max, y_min, y_max) of the table region flattening works in (m): the cell's 0.6 m
    workspace square centred at (0.45, 0) without its 7 cm nearest the robot base, where the
    wrist pressing cloth into the table launched it off the table on release (measured)."""
    margin: float = 0.02
    """The expected outline and every place point stay this far inside the workspace (m)."""
    settle_time: float = 0.3
    """Wait after each pull, arm parked, before re-observing (s)."""
    keep_yaw: bool = True
    """After the first pull keep the expected outline's yaw and refit only its position, so
    later pulls work towards the same goal instead of a re-guessed one."""

    @property
    def stop_coverage(self) -> float:
        """The perceived coverage flattening stops at: the target, or the finishing coverage
        where that is higher."""
        finish = self.finish_coverage
        return self.target_coverage if finish is None else max(self.target_coverage, finish)

    def __post_init__(self) -> None:
        require(
            math.isfinite(self.target_coverage) and 0.0 < self.target_coverage <= 1.5,
            f"FlattenConfig.target_coverage must be in (0, 1.5], got {self.target_coverage!r}",
        )
        require(
            self.finish_coverage is None
            or (
                isinstance(self.finish_coverage, int | float)
                and math.isfinite(self.finish_coverage)
                and 0.0 < self.finish_coverage <= 1.5
            ),
            "FlattenConfig.finish_coverage must be None or in (0, 1.5], "
            f"got {self.finish_coverage!r}",
        )
        require(
            isinstance(self.max_actions, int)
            and not isinstance(self.max_actions, bool)
            and 0 <= self.max_actions <= 50,
            f"FlattenConfig.max_actions must be an integer in [0, 50], got {self.max_actions!r}",
        )
        for name, lo, hi in (
            ("grasp_inset", 0.0, 0.1),
            ("grasp_height", 0.0, 0.05),
            ("top_depth", 0.0, 0.02),
            ("release_height", 0.0, 0.2),
            ("palm_clearance", 0.0, 0.5),
            ("palm_radius", 0.0, 0.2),
            ("max_inset", 0.0, 0.3),
            ("retry_step", 0.0, 0.1),
            ("missed_radius", 0.0, 0.2),
            ("overshoot", 0.0, 0.1),
            ("min_pull", 0.0, 0.2),
            ("yaw_step", math.radians(0.5), math.radians(45.0)),
            ("raster", 0.001, 0.02),
            ("margin", 0.0, 0.1),
            ("settle_time", 0.0, 5.0),
        ):
            v = getattr(self, name)
            require(
                isinstance(v, int | float) and math.isfinite(v) and lo <= v <= hi,
                f"FlattenConfig.{name} must be in [{lo:.4g}, {hi:.4g}], got {v!r}",
            )
        require(
            self.grasp_layer in GRASP_LAYERS,
            f"FlattenConfig.grasp_layer must be one of {', '.join(GRASP_LAYERS)}, "
            f"got {self.grasp_layer!r}",
        )
        require(
            isinstance(self.retries, int)
            and not isinstance(self.retries, bool)
            and 0 <= self.retries <= 5,
            f"FlattenConfig.retries must be an integer in [0, 5], got {self.retries!r}",
        )
        x0, x1, y0, y1 = self.workspace
        require(
            all(math.isfinite(v) for v in self.workspace) and x1 - x0 > 0.1 and y1 - y0 > 0.1,
            f"FlattenConfig.workspace (x_min, x_max, y_min, y_max) must span > 0.1 m each way, "
            f"got {self.workspace!r}",
        )


@dataclass(frozen=True)
class ExpectedOutline:
    """The expected flat rectangle placed on the perceived cloth (table plane, m)."""

    center: np.ndarray
    """(2,) centre."""
    yaw: float
    """Rotation of its width axis from world x (rad)."""
    corners: np.ndarray
    """4×2 corners, counter-clockwise."""
    overlap: float
    """Share of its area the perceived cloth covers."""


@dataclass(frozen=True)
class Pull:
    """A candidate pull: the pick-and-place and the shortfall it addresses."""

    action: FoldAction
    target: str
    """Which point of the expected outline it fills (TARGET_NAMES)."""
    shortfall: float
    """How far (m) the cloth falls short of that point."""
    palm_ok: bool = True
    """False when the palm would meet heaped cloth on the way down (see palm_clearance)."""


def perceived_coverage(state: ClothState, expected_area: float) -> float:
    """Perceived top-view cloth area over the item's expected flat area (0 with no cloth)."""
    require(
        math.isfinite(expected_area) and expected_area > 0.0,
        f"expected_area must be a finite area > 0 m², got {expected_area!r}",
    )
    return float(state.coverage_m2) / expected_area if state.detected else 0.0


def _rect(center: np.ndarray, yaw: float, width: float, height: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    ax, ay = np.array([c, s]) * width / 2, np.array([-s, c]) * height / 2
    return np.array([center - ax - ay, center + ax - ay, center + ax + ay, center - ax + ay])


def _grid_shape(cfg: FlattenConfig) -> tuple[int, int]:
    """(rows along y, cols along x) of the top-view raster over the workspace."""
    x0, x1, y0, y1 = cfg.workspace
    return math.ceil((y1 - y0) / cfg.raster) + 1, math.ceil((x1 - x0) / cfg.raster) + 1


def fit_expected_outline(
    outline_xy: np.ndarray,
    width: float,
    height: float,
    cfg: FlattenConfig,
    yaw: float | None = None,
) -> ExpectedOutline:
    """The width × height rectangle (inside the workspace) that the outline polygon covers most;
    with `yaw` given only its position is searched."""
    x0, _x1, y0, _y1 = cfg.workspace
    res = cfg.raster
    ny, nx = _grid_shape(cfg)
    grid = np.zeros((ny, nx), np.float32)
    pix = (np.asarray(outline_xy, float)[:, :2] - [x0, y0]) / res
    cv2.fillPoly(grid, [np.round(pix * 16).astype(np.int32)], 1.0, lineType=cv2.LINE_8, shift=4)
    cloth_cells = float(grid.sum())
    centroid = pix.mean(axis=0) if cloth_cells == 0 else np.argwhere(grid > 0).mean(axis=0)[::-1]
    best = None
    yaws = np.arange(0.0, math.pi, cfg.yaw_step) if yaw is None else [yaw]
    for yaw in yaws:
        corners = _rect(np.zeros(2), float(yaw), width, height) / res
        half = np.abs(corners).max(axis=0)  # (hx, hy) in cells
        k = np.ceil(half).astype(int)
        kernel = np.zeros((2 * k[1] + 1, 2 * k[0] + 1), np.float32)
        cv2.fillPoly(
            kernel, [np.round((corners + k) * 16).astype(np.int32)], 1.0, cv2.LINE_8, shift=4
        )
        overlap = cv2.filter2D(grid, -1, kernel, borderType=cv2.BORDER_CONSTANT)
        m = cfg.margin / res
        lo = np.ceil(half + m).astype(int)
        hi = np.floor(np.array([nx, ny]) - 1 - half - m).astype(int)
        # A rectangle wider than the workspace is centred on it along that axis.
        for a in range(2):
            if lo[a] > hi[a]:
                lo[a] = hi[a] = (nx, ny)[a] // 2
        sub = overlap[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1]
        # Among equal overlaps prefer the centre nearest the cloth's centroid.
        jj, ii = np.mgrid[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1]
        score = sub - 1e-3 * np.hypot(ii - centroid[0], jj - centroid[1])
        j, i = np.unravel_index(int(np.argmax(score)), score.shape)
        value = float(sub[j, i]) / max(float(kernel.sum()), 1.0)
        if best is None or value > best[0] + 1e-9:
            centre = np.array([x0 + (lo[0] + i) * res, y0 + (lo[1] + j) * res])
            best = (value, centre, float(yaw))
    value, centre, yaw = best
    return ExpectedOutline(centre, yaw, _rect(centre, yaw, width, height), value)


def cloth_surface(obs: Observation, state: ClothState, cfg: FlattenConfig) -> np.ndarray:
    """Top-view raster (cfg.raster cells over cfg.workspace) of the cloth's top surface height
    above the perceived table (m), from the depth image; NaN where no cloth is seen."""
    ny, nx = _grid_shape(cfg)
    out = np.full((ny, nx), np.nan, np.float32)
    if not state.detected or not state.mask.any():
        return out
    depth = np.asarray(obs.depth, dtype=float)
    v, u = np.nonzero(state.mask & np.isfinite(depth) & (depth > 0))
    if v.size == 0:
        return out
    pts = backproject(np.c_[u, v], depth[v, u], obs.intrinsics, obs.T_world_camera)
    a, b, c, d = (float(k) for k in np.asarray(state.table_plane, dtype=float).reshape(4))
    h = pts @ np.array([a, b, c]) + d
    x0, _x1, y0, _y1 = cfg.workspace
    i = np.round((pts[:, 0] - x0) / cfg.raster).astype(int)
    j = np.round((pts[:, 1] - y0) / cfg.raster).astype(int)
    # The arm above the cloth (hidden cloth in the amodal mask) is no cloth surface.
    ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny) & (h > -0.01) & (h < 0.2)
    flat = np.full(ny * nx, -np.inf)
    np.maximum.at(flat, j[ok] * nx + i[ok], h[ok])
    flat[~np.isfinite(flat)] = np.nan
    return flat.reshape(ny, nx).astype(np.float32)


def _raster_cell(xy: np.ndarray, cfg: FlattenConfig) -> tuple[int, int]:
    """(column i along x, row j along y) of the top-view raster cell holding world `xy`; may lie
    off the raster."""
    x0, _x1, y0, _y1 = cfg.workspace
    return round((xy[0] - x0) / cfg.raster), round((xy[1] - y0) / cfg.raster)


def surface_window(
    surface: np.ndarray, xy: np.ndarray, cfg: FlattenConfig, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """The known surface heights (m) of the raster cells within `radius` (m, at least one cell)
    of `xy`, and those cells' world xy (K × 2); empty off the raster (cloth can lie beyond the
    flattening workspace)."""
    ny, nx = surface.shape
    i, j = _raster_cell(xy, cfg)
    r = max(1, math.ceil(radius / cfg.raster))
    j0, j1, i0, i1 = max(0, j - r), min(ny, j + r + 1), max(0, i - r), min(nx, i + r + 1)
    if j0 >= j1 or i0 >= i1:
        return np.zeros(0), np.zeros((0, 2))
    jj, ii = np.mgrid[j0:j1, i0:i1]
    win = surface[j0:j1, i0:i1]
    keep = np.isfinite(win) & ((ii - i) ** 2 + (jj - j) ** 2 <= r * r)
    x0, _x1, y0, _y1 = cfg.workspace
    cells = np.c_[x0 + ii[keep] * cfg.raster, y0 + jj[keep] * cfg.raster]
    return win[keep], cells


def _surface_at(surface: np.ndarray, xy: np.ndarray, cfg: FlattenConfig, radius: float) -> float:
    """Highest surface height (m) within `radius` (m) of `xy`; NaN where none is known (also
    off the raster: cloth can lie beyond the flattening workspace)."""
    heights, _ = surface_window(surface, xy, cfg, radius)
    return float(heights.max()) if heights.size else float("nan")


def table_z(plane: np.ndarray, xy: np.ndarray) -> float:
    """Height (m) of the table plane (a, b, c, d) under the point `xy`."""
    a, b, c, d = (float(v) for v in np.asarray(plane, dtype=float).reshape(4))
    if c < 0.5:
        raise FoldbotError(
            f"the perceived table plane {plane!r} is not horizontal enough to plan on"
        )
    return -(a * xy[0] + b * xy[1] + d) / c


def expected_outline_world(fit: ExpectedOutline, table_plane: np.ndarray) -> np.ndarray:
    """The expected rectangle's 4 corners on the perceived table (4×3, world, m), to draw."""
    return np.array([[x, y, table_z(table_plane, np.array([x, y]))] for x, y in fit.corners])


def _targets(rect: np.ndarray) -> np.ndarray:
    """The 8 pull targets: corners and edge midpoints, counter-clockwise (TARGET_NAMES)."""
    out = []
    for k in range(4):
        out += [rect[k], 0.5 * (rect[k] + rect[(k + 1) % 4])]
    return np.array(out)


def _pull_line(grasp_xy: np.ndarray, place_xy: np.ndarray) -> tuple[float, float, float, float]:
    """The carry's perpendicular bisector, grasp on its moving (left) side, as a fold line."""
    mid = 0.5 * (grasp_xy + place_xy)
    u = grasp_xy - mid
    n = float(np.linalg.norm(u))
    u = u / n if n > 1e-9 else np.array([1.0, 0.0])
    return (float(mid[0]), float(mid[1]), float(u[1]), float(-u[0]))


def _nearest_on_outline(poly: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The point of the closed polygon's boundary (N×2) nearest `point`."""
    a, b = poly, np.roll(poly, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", point - a, ab) / np.maximum((ab**2).sum(axis=1), 1e-18), 0, 1)
    foot = a + t[:, None] * ab
    return foot[int(np.argmin(np.linalg.norm(foot - point, axis=1)))]


def grasp_level(
    surface: np.ndarray | None, xy: np.ndarray, cfg: FlattenConfig
) -> tuple[float, bool]:
    """Grasp height above the table (m) at `xy` — table level, raised until the palm clears the
    heap around — and whether cloth reaches up to the jaws there."""
    if surface is None:
        return cfg.grasp_height, True
    heap = _surface_at(surface, xy, cfg, cfg.palm_radius)
    if not math.isfinite(heap):
        return cfg.grasp_height, True
    level = max(cfg.grasp_height, heap - cfg.palm_clearance)
    here = _surface_at(surface, xy, cfg, cfg.raster)
    if cfg.grasp_layer == "top" and math.isfinite(here):
        level = max(level, here - cfg.top_depth)
    return level, not math.isfinite(here) or here >= level - _JAW_REACH_BELOW


def _edge_grasp(
    contour: np.ndarray,
    centroid: np.ndarray,
    nearest: np.ndarray,
    direction: np.ndarray,
    surface: np.ndarray | None,
    cfg: FlattenConfig,
) -> tuple[np.ndarray, float, bool]:
    """Grasp point (xy), its height above the table and whether the palm clears the heap: the
    first spot from `grasp_inset` inside the edge (against the pull) up to `max_inset` where the
    jaws, raised so the palm clears the cloth around, still reach cloth."""
    inward = -direction
    first = nearest + inward * cfg.grasp_inset
    if cv2.pointPolygonTest(contour, (float(first[0]), float(first[1])), False) < 0:
        # A thin part: step in towards the cloth's centroid instead.
        inward = centroid - nearest
        inward = inward / max(float(np.linalg.norm(inward)), 1e-9)
        first = nearest + inward * cfg.grasp_inset
    level, ok = grasp_level(surface, first, cfg)
    if ok:
        return first, level, True
    steps = int((cfg.max_inset - cfg.grasp_inset) / cfg.raster)
    for k in range(1, steps + 1):
        xy = first + inward * (k * cfg.raster)
        if cv2.pointPolygonTest(contour, (float(xy[0]), float(xy[1])), False) < 0:
            break
        lv, ok = grasp_level(surface, xy, cfg)
        if ok:
            return xy, lv, True
    return first, level, False


def pull_action(
    grasp: np.ndarray, place_xy: np.ndarray, table_plane: np.ndarray, cfg: FlattenConfig, label: str
) -> FoldAction:
    """A flattening pull: grasp at `grasp` (x, y, z; world, m), carry and let go
    `cfg.release_height` above the table at `place_xy`, kept `cfg.margin` inside the workspace."""
    x0, x1, y0, y1 = cfg.workspace
    m = cfg.margin
    place_xy = np.clip(np.asarray(place_xy, float), [x0 + m, y0 + m], [x1 - m, y1 - m])
    z_p = table_z(table_plane, place_xy) + cfg.release_height
    grasp = np.asarray(grasp, dtype=float).reshape(3)
    return FoldAction(
        grasp=grasp,
        place=np.array([place_xy[0], place_xy[1], z_p]),
        fold_line=_pull_line(grasp[:2], place_xy),
        label=label,
    )


def plan_pulls(
    state: ClothState,
    width: float,
    height: float,
    cfg: FlattenConfig,
    surface: np.ndarray | None = None,
    yaw: float | None = None,
) -> tuple[ExpectedOutline, list[Pull]]:
    """The expected outline fitted to `state` (at `yaw` if given) and every worthwhile pull,
    largest shortfall first (pulls whose palm would meet a heap last). `surface` (see
    cloth_surface) lets grasps rise so the palm clears heaped cloth."""
    require(
        math.isfinite(width) and math.isfinite(height) and width > 0.0 and height > 0.0,
        f"expected width × height must be > 0 m, got {width!r} × {height!r}",
    )
    if not state.detected:
        raise FoldbotError(f"no cloth to flatten: {state.reason}")
    outline = np.asarray(state.outline_world, dtype=float).reshape(-1, 3)
    if len(outline) < 3:
        raise FoldbotError(f"the perceived outline has {len(outline)} points, 3 are needed")
    poly = outline[:, :2]
    fit = fit_expected_outline(poly, width, height, cfg, yaw)
    contour = poly.astype(np.float32).reshape(-1, 1, 2)
    centroid = poly.mean(axis=0)
    pulls = []
    for name, target in zip(TARGET_NAMES, _targets(fit.corners), strict=True):
        inside = cv2.pointPolygonTest(contour, (float(target[0]), float(target[1])), True)
        shortfall = max(0.0, -float(inside))
        if shortfall < cfg.min_pull:
            continue
        nearest = _nearest_on_outline(poly, target)
        pull = target - nearest
        direction = pull / max(float(np.linalg.norm(pull)), 1e-9)
        grasp_xy, h_g, palm_ok = _edge_grasp(contour, centroid, nearest, direction, surface, cfg)
        z_g = table_z(state.table_plane, grasp_xy) + h_g
        action = pull_action(
            np.array([grasp_xy[0], grasp_xy[1], z_g]),
            target + direction * cfg.overshoot,
            state.table_plane,
            cfg,
            f"pull {name}",
        )
        pulls.append(Pull(action, name, shortfall, palm_ok))
    pulls.sort(key=lambda pl: (not pl.palm_ok, -pl.shortfall))
    return fit, pulls


def plan_pull(
    state: ClothState, width: float, height: float, cfg: FlattenConfig
) -> FoldAction | None:
    """The next flattening pull, or None when the perceived coverage has reached the target
    (or no point of the expected outline is short by `min_pull` or more)."""
    if perceived_coverage(state, width * height) >= cfg.target_coverage:
        return None
    _fit, pulls = plan_pulls(state, width, height, cfg)
    return pulls[0].action if pulls else None
