"""Two-arm spread for flattening, from perception alone: take two adjacent perceived corners, lift
them until the towel hangs free, spread them one nominal side apart over the far half of the
workspace, hang still, then lay the towel towards the near side at 45° and let go — as a person
lays out a towel. World frame, metres.

Chosen because corner pulls plateau on a heap: in `scripts/measure_spread.py` (ideal grippers)
this motion flattened 12 of 20 crumpled towels from the true corners, the cell's pulls 5 of 20
(docs/experiments.md). The robot knows the towel's nominal size, never its state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from foldbot.errors import FoldbotError, require
from foldbot.perception.keypoints import CORNER_LABELS
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.planning.flatten import (
    _JAW_REACH_BELOW,
    FlattenConfig,
    _raster_cell,
    _surface_at,
    surface_window,
    table_z,
)
from foldbot.planning.motion import MotionConfig, Segment, action_segments, line_path
from foldbot.planning.tool import GRIPPER_DOWN, gripper_leaning_quaternion, slerp_quaternions

LEAN_MODES = ("sides", "apart")
"""How plan_spread leans two tilted tools apart: along ±y (each arm's own side), or along the
line between the two corners."""


@dataclass(frozen=True)
class SpreadConfig:
    """Shape and speed of the two-arm spread."""

    hang_margins: tuple[float, ...] = (0.10, 0.05, 0.0)
    """How far above the table the hanging towel's far side is held (m), tried in turn until
    both arms reach the hold points (a larger towel needs a higher hold)."""
    max_hold_height: float = 0.50
    """Highest hold above the table (m): the arms' reach over the far side of the workspace."""
    hold_far_x: float = 0.62
    """Farthest the hold points go along x (m): where the arms still reach that high."""
    hang_time: float = 1.0
    """Still time at the hold (s), so the hanging towel stops swinging before it is laid."""
    descend_speed: float = 0.03
    """TCP speed of the last approach to a corner (m/s): slow, so the jaws and palm come down
    on a heap without shoving it (towel_crumpled_two_arms: 10 of 20 flattened, against 8 at the
    pulls' 0.17 m/s; 10 diverged, against 8)."""
    slow_descent: float = 0.03
    """Only the last this many metres down to a corner are at `descend_speed`; above them the
    jaws come down at the pulls' speed (MotionConfig.free_speed / 3), so a restless heap waits
    less for the grasp (towel_crumpled_two_arms: 11 of 20 flattened and 8 diverged, against 9
    and 11 slow all the way down)."""
    lift_speed: float = 0.25
    """TCP speed lifting and spreading (m/s)."""
    lay_speed: float = 0.10
    """TCP speed laying the towel down (m/s): slow, so the towel lays instead of heaping."""
    release_height: float = 0.02
    """The held corners are let go this high above the table (m)."""
    center_xy: tuple[float, float] = (0.45, 0.0)
    """Where the laid towel is centred (m): the cell's workspace centre
    (CellLayout.workspace_center_xy)."""
    grasp_inset: float = 0.008
    """Each grasp lies this far inside the perceived corner (m, towards the perceived centre):
    the jaws catch cloth within ~1 cm of the TCP, and a corner's mesh point is at the corner."""
    top_depth: float = 0.002
    """The jaws close this far below the perceived top surface at the grasp (m): the top layer,
    the corner the camera sees, not the cloth under it."""
    seek_cloth: float = 0.10
    """How far (m) a grasp aimed at a perceived corner with no cloth seen under it (its cell of
    the top-view surface raster) goes in, towards the perceived centre, to the first cloth seen,
    then `grasp_inset` past it; 0: aimed at the corner as seen. A heap's rounded tip puts the
    corner the outline's sides meet at (perception.keypoints.find_corners) out on the table,
    and a spread aimed there closes its jaws on nothing, again and again; a corner on the
    outline is taken a few mm further in (towel_crumpled_two_arms over 40 towels: 20 of 254
    grasps missed against 38 of 295 at 0, 31 flattened against 29, folds 24 against 22; seeking
    only where no cloth is seen within a cell, seeds 0–19: 17 of 144 missed, 14 flattened, as
    at 0)."""
    grasp_tilt: float = 0.0
    """Where no pair of corners can be spread gripper down, the pairs are tried again with the
    tools tilted this much (rad; 0: never, a one-arm pull instead), at every hang margin, each
    wrist leaning away from the other arm (`grasp_lean`), so arms that would meet over two
    corners close together keep apart. Planned on two UR5s for 60 random pairs of corners
    6–20 cm apart, 21 could be spread gripper down, 48 at 0.35 rad (20°) along ±y, 50 at 0.5,
    56 at 0.35 leaning apart. Off: over towel_crumpled_two_arms' seeds 0–39 at 0.35, 5 towels
    took a tilted spread; leaning apart 31 flattened and 24 folded, as gripper down (seed 39
    flattened instead of diverging, seed 14 ended at 0.85 instead of flattened), along ±y 31
    and 23 (30 and 23 before the grasps rose for the leaning palm)."""
    grasp_lean: str = "apart"
    """How the tools lean apart at `grasp_tilt` (LEAN_MODES): "apart", each wrist away from the
    other corner along the line between them; "sides", the +y arm's towards +y and the other's
    towards −y. Of those 60 pairs at 0.35 rad, "apart" spread every one "sides" could and 8
    more lying near x, where the forearms reach for one y from either side."""
    fault_grasp_offset: float = 0.0
    """Fault injection for tests (m; 0 in use): the first spread's grasps, its retry too, are
    aimed this far outside the perceived corners, onto bare table, so the recovery from a missed
    spread can be exercised (flatten.run_spreads)."""
    pull_from: float | None = None
    """At or above this perceived coverage the cell pulls (one arm, planning.flatten's pulls)
    instead of spreading: a spread lifts the whole towel, a pull moves one short corner or edge.
    None: spreads up to the target (towel_crumpled_two_arms over 40 towels at 0.8: flattened 21
    either way, folds 18 against 20; a spread from 0.8–0.9 often lays the towel at 0.98–1.00,
    the pulls that replaced it 0.90–0.97)."""

    def __post_init__(self) -> None:
        v = self.pull_from
        require(
            v is None or (isinstance(v, int | float) and math.isfinite(v) and 0.0 <= v <= 1.5),
            f"SpreadConfig.pull_from must be None or in [0, 1.5], got {v!r}",
        )
        require(
            len(self.hang_margins) >= 1
            and all(isinstance(m, int | float) and 0.0 <= m <= 0.3 for m in self.hang_margins),
            f"SpreadConfig.hang_margins must be 1 or more values in [0, 0.3] m, "
            f"got {self.hang_margins!r}",
        )
        require(
            self.grasp_lean in LEAN_MODES,
            f"SpreadConfig.grasp_lean must be one of {', '.join(LEAN_MODES)}, "
            f"got {self.grasp_lean!r}",
        )
        for name, lo, hi in (
            ("max_hold_height", 0.1, 1.0),
            ("hold_far_x", 0.2, 1.0),
            ("hang_time", 0.0, 10.0),
            ("descend_speed", 0.005, 1.0),
            ("slow_descent", 0.005, 0.08),
            ("lift_speed", 0.01, 1.0),
            ("lay_speed", 0.01, 1.0),
            ("release_height", 0.0, 0.2),
            ("grasp_inset", 0.0, 0.1),
            ("top_depth", 0.0, 0.02),
            ("seek_cloth", 0.0, 0.2),
            ("fault_grasp_offset", 0.0, 0.2),
            ("grasp_tilt", 0.0, 0.6),
        ):
            v = getattr(self, name)
            require(
                isinstance(v, int | float) and math.isfinite(v) and lo <= v <= hi,
                f"SpreadConfig.{name} must be in [{lo:.4g}, {hi:.4g}], got {v!r}",
            )


@dataclass(frozen=True)
class SpreadAction:
    """One arm's part of a spread: grasp a corner, hold it at `hold`, lay it to `release`."""

    grasp: np.ndarray
    """(3,) world xyz where the jaws close on the corner."""
    hold: np.ndarray
    """(3,) where the corner is held while the towel hangs."""
    touch: np.ndarray
    """(3,) straight below `hold`, where the hanging towel's far side meets the table."""
    release: np.ndarray
    """(3,) where the corner is let go, after the 45° lay."""
    label: str = ""
    hang_time: float = 1.0
    descend_speed: float = 0.03
    slow_descent: float = 0.03
    lift_speed: float = 0.25
    lay_speed: float = 0.10
    first_lift: float = 0.10
    """Straight up this far (m) off the heap before the rise to the hold, which is a straight
    line: a corner far out is not lifted high where the arm cannot reach."""
    tilt: float = 0.0
    """The tool's tilt at the grasp (rad; planning.tool.gripper_leaning_quaternion: > 0 leans
    the wrist towards `tilt_heading`, +y unless set), turned to on the approach and back to gripper-down on the rise to
    the hold; 0: gripper down all along. Two corners close together are taken with each wrist
    leaning away from the other arm."""
    tilt_heading: float = math.pi / 2
    """The world heading (rad about z from +x) the wrist leans towards at `tilt` > 0
    (planning.tool.gripper_leaning_quaternion): π/2, towards +y, unless a spread leans the
    tools apart along the line between its corners (plan_spread's `lean`)."""

    @property
    def place(self) -> np.ndarray:
        """Where the carried corner ends (as a FoldAction's place)."""
        return self.release

    def as_dict(self) -> dict:
        d: dict = {"label": self.label}
        d.update({k: [float(v) for v in getattr(self, k)] for k in SPREAD_POINTS})
        d.update({k: float(getattr(self, k)) for k in SPREAD_SCALARS})
        return d

    @classmethod
    def from_dict(cls, d: dict) -> SpreadAction:
        """The action from its `as_dict()` form (a speed or length left out takes its default);
        FoldbotError naming the field that is missing or not a finite number."""
        points = {}
        for k in SPREAD_POINTS:
            v = np.asarray(d.get(k, ()), dtype=float).reshape(-1)
            if v.shape != (3,) or not np.isfinite(v).all():
                raise FoldbotError(
                    f"a spread action's {k!r} must be 3 finite numbers, got {d.get(k)!r}"
                )
            points[k] = v
        scalars = {}
        for k in SPREAD_SCALARS:
            if k in d:
                v = d[k]
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                    raise FoldbotError(
                        f"a spread action's {k!r} must be a finite number, got {v!r}"
                    )
                scalars[k] = float(v)
        return cls(**points, label=str(d.get("label", "")), **scalars)


SPREAD_POINTS = ("grasp", "hold", "touch", "release")
"""SpreadAction's points (world xyz, m), as as_dict writes them."""
SPREAD_SCALARS = (
    "hang_time",
    "descend_speed",
    "slow_descent",
    "lift_speed",
    "lay_speed",
    "first_lift",
    "tilt",
    "tilt_heading",
)
"""SpreadAction's times (s), speeds (m/s) and lengths (m), as as_dict writes them."""


@dataclass(frozen=True)
class SpreadPlan:
    """A spread planned on one observation: the two arms' parts (the +y one first)."""

    actions: tuple[SpreadAction, SpreadAction]
    corners: tuple[str, str]
    """The perceived corners taken (CORNER_LABELS), in the actions' order."""
    width: float
    """How far apart the corners are held (m): the nominal side they are taken to span."""
    hang: float
    """How far the towel is expected to hang below them (m): nominal area / width."""
    margin: float
    """The hanging towel's far side is held this far above the table (m)."""
    palm_clear: bool = True
    """False when at either grasp the palm would meet heaped cloth before the jaws reach the
    corner (see FlattenConfig.palm_clearance): pressing a heap into the table blows the
    simulated cloth up."""


def corner_pairs(
    state: ClothState,
    laid: np.ndarray | None = None,
    laid_radius: float = 0.06,
    missed: np.ndarray | None = None,
) -> list[tuple[str, str]]:
    """The four pairs of adjacent perceived corners (counter-clockwise neighbours), the one the
    estimator is surest of first: ranked by the less confident corner of each pair. A pair whose
    corners both lie within `laid_radius` (m) of the points `laid` (N×3: where the last spread
    let go) comes late: spreading the same edge again lays the towel as before, while the
    opposite edge lifts the side that was laid first (folded under, if anything). A pair whose
    corners both lie within it of the points `missed` (where the last spread's grasps missed,
    its retry too) comes last: nothing moved, and the same grasps would miss again."""
    if not state.detected:
        raise FoldbotError(f"no cloth to spread: {state.reason}")
    missing = [k for k in CORNER_LABELS if k not in state.keypoints]
    if missing:
        raise FoldbotError(f"a spread needs the 4 perceived corners; missing {', '.join(missing)}")
    conf = [float(state.keypoints[k][1]) for k in CORNER_LABELS]
    xy = state.keypoint_array(CORNER_LABELS)[:, :2]

    def near(points: np.ndarray | None) -> np.ndarray:
        if points is None or not len(points):
            return np.zeros(4, bool)
        d = np.linalg.norm(xy[:, None] - np.asarray(points, dtype=float)[None, :, :2], axis=2)
        return d.min(axis=1) <= laid_radius

    near_laid, near_missed = near(laid), near(missed)
    ranked = sorted(
        range(4),
        key=lambda i: (
            bool(near_missed[i] and near_missed[(i + 1) % 4]),
            bool(near_laid[i] and near_laid[(i + 1) % 4]),
            -min(conf[i], conf[(i + 1) % 4]),
            i,
        ),
    )
    return [(CORNER_LABELS[i], CORNER_LABELS[(i + 1) % 4]) for i in ranked]


def spread_width(seen: float, width: float, height: float) -> float:
    """The nominal side two adjacent corners seen `seen` m apart are taken to span: the shorter
    unless they are seen nearer the longer (a heap shows its corners closer than they are, and
    a slack edge lays better than one pulled past its length)."""
    short, long = sorted((float(width), float(height)))
    return long if seen > 0.5 * (short + long) else short


def _first_cloth(
    surface: np.ndarray, xy: np.ndarray, inward: np.ndarray, flat: FlattenConfig, reach: float
) -> float:
    """How far (m) from `xy` along the unit `inward` the first raster cell of `surface` with
    cloth seen lies, looked for up to `reach` (m) in half-cell steps; 0 where `xy`'s own cell
    has cloth, `reach` is 0, or none is found within it."""
    if reach <= 0.0:
        return 0.0
    ny, nx = surface.shape
    for t in np.arange(0.0, reach + 1e-9, flat.raster / 2):
        i, j = _raster_cell(xy + t * inward, flat)
        if 0 <= i < nx and 0 <= j < ny and math.isfinite(surface[j, i]):
            return float(t)
    return 0.0


PALM_UNDERSIDE = 0.045
"""The palm's underside above the TCP (m; the URDF's gripper_base_link box, 1–6 cm above the
flange, the TCP 10.5 cm)."""
PALM_HALF_DEPTH = 0.025
"""Half the palm's side across the fingers' closing axis (m): the edge a lean lowers."""


def palm_underside_rise(offsets: np.ndarray, tilt: float) -> np.ndarray:
    """How much higher (m) the palm's underside lies over points `offsets` (m, horizontal, along
    the way the wrist leans from the TCP) with the tool leaning `tilt` rad about its closing
    axis than gripper down: the underside turns with the tool, so it comes lower on the side
    the wrist leans to (its edge there 11 mm lower at 0.35 rad, 3.9 cm out) and higher on the
    other; past its edges, the edge's height."""
    t = abs(float(tilt))
    offsets = np.asarray(offsets, dtype=float)
    if t == 0.0:
        return np.zeros_like(offsets)
    centre = PALM_UNDERSIDE * math.sin(t)  # the underside's middle, out along the lean
    across = np.clip(
        (offsets - centre) / math.cos(t), -PALM_HALF_DEPTH, PALM_HALF_DEPTH
    )  # along the underside, from its middle
    return PALM_UNDERSIDE * math.cos(t) - across * math.sin(t) - PALM_UNDERSIDE


def _palm_heap(
    surface: np.ndarray, xy: np.ndarray, flat: FlattenConfig, tilt: float, heading: float
) -> float:
    """The highest cloth (m above the table) the palm must clear over a grasp at `xy`, counted as
    gripper down counts it (the top surface within `palm_radius`), each raster cell lowered by
    how much higher the leaning palm's underside lies over it (palm_underside_rise; the wrist
    leaning `tilt` rad towards `heading`); NaN where no cloth is known there."""
    if tilt == 0.0:
        return _surface_at(surface, xy, flat, flat.palm_radius)
    heights, cells = surface_window(surface, xy, flat, flat.palm_radius)
    if not heights.size:
        return float("nan")
    toward = math.copysign(1.0, tilt) * np.array([math.cos(heading), math.sin(heading)])
    offsets = (cells[:, 0] - xy[0]) * toward[0] + (cells[:, 1] - xy[1]) * toward[1]
    return float(np.max(heights - palm_underside_rise(offsets, tilt)))


def _grasp_point(
    state: ClothState,
    label: str,
    surface: np.ndarray | None,
    flat: FlattenConfig,
    cfg: SpreadConfig,
    tilt: float = 0.0,
    heading: float = 0.0,
) -> tuple[np.ndarray, bool]:
    """Where the jaws close on the perceived corner `label`: `cfg.grasp_inset` inside it (inside
    the first cloth seen inward of it, where none is seen under it: cfg.seek_cloth), just
    under the top surface there, raised (as flattening pulls are) until the palm clears the
    heap around (the tool leaning `tilt` rad towards `heading`: _palm_heap); and whether the
    jaws still reach the cloth at that height."""
    corner = np.asarray(state.keypoints[label][0], dtype=float)
    centre = state.keypoint_array(CORNER_LABELS).mean(axis=0)
    inward = centre[:2] - corner[:2]
    inward = inward / max(float(np.linalg.norm(inward)), 1e-9)
    onto = (
        0.0 if surface is None else _first_cloth(surface, corner[:2], inward, flat, cfg.seek_cloth)
    )
    xy = corner[:2] + inward * (onto + cfg.grasp_inset - cfg.fault_grasp_offset)
    return _grasp_at(state, xy, surface, flat, cfg, tilt, heading)


def _grasp_at(
    state: ClothState,
    xy: np.ndarray,
    surface: np.ndarray | None,
    flat: FlattenConfig,
    cfg: SpreadConfig,
    tilt: float = 0.0,
    heading: float = 0.0,
) -> tuple[np.ndarray, bool]:
    """Where the jaws close at table point `xy`: just under the top surface there, raised until
    the palm (leaning `tilt` rad towards `heading`) clears the heap around; and whether the jaws
    still reach the cloth at that height."""
    z_table = table_z(state.table_plane, xy)
    level, reached = flat.grasp_height, True
    if surface is not None:
        here = _surface_at(surface, xy, flat, flat.raster)
        heap = _palm_heap(surface, xy, flat, tilt, heading)
        if math.isfinite(here):
            level = max(level, here - cfg.top_depth)
        if math.isfinite(heap):
            level = max(level, heap - flat.palm_clearance)
        reached = not math.isfinite(here) or here >= level - _JAW_REACH_BELOW
    return np.array([xy[0], xy[1], z_table + level]), reached


def plan_spread(
    state: ClothState,
    expected_size: tuple[float, float],
    cfg: SpreadConfig,
    flat: FlattenConfig,
    surface: np.ndarray | None = None,
    margin: float | None = None,
    pair: tuple[str, str] | None = None,
    tilt: float = 0.0,
    lean: str = "sides",
) -> SpreadPlan:
    """The spread of the towel of nominal `expected_size` (w, h; m) seen in `state`: the two
    adjacent corners `pair` (default: those the estimator is surest of, corner_pairs), held one
    nominal side apart (spread_width) over cfg.center_xy + half the hang along x, the hanging
    far side `margin` (default the first of cfg.hang_margins) above the table, then laid to end
    centred on the workspace. `surface` (planning.flatten.cloth_surface) puts each grasp on the
    top layer at the corner, with the palm clear of the heap (SpreadPlan.palm_clear). `tilt`
    (rad) leans the tools at the grasps (SpreadAction.tilt), each wrist away from the other
    arm: `lean` "sides", the +y arm's towards +y and the other's towards −y; "apart", each
    along the line from the other corner to its own (LEAN_MODES)."""
    w, h = (float(v) for v in expected_size)
    require(
        math.isfinite(w) and math.isfinite(h) and w > 0.0 and h > 0.0,
        f"expected width × height must be > 0 m, got {w!r} × {h!r}",
    )
    margin = cfg.hang_margins[0] if margin is None else float(margin)
    require(lean in LEAN_MODES, f"lean must be one of {', '.join(LEAN_MODES)}, got {lean!r}")
    labels = corner_pairs(state)[0] if pair is None else pair
    picked = [_grasp_point(state, k, surface, flat, cfg) for k in labels]
    grasps = [g for g, _ in picked]
    # The corner further along +y is held on the +y side, so the arms' paths do not cross.
    order = sorted(range(2), key=lambda i: -float(grasps[i][1]))
    leaning: list[dict] = [{}, {}]
    for side, i in zip((1.0, -1.0), order, strict=True):
        away = grasps[i][:2] - grasps[1 - i][:2]
        leaning[i] = (
            {"tilt": side * tilt, "tilt_heading": math.pi / 2}
            if lean == "sides"
            else {"tilt": abs(tilt), "tilt_heading": math.atan2(away[1], away[0])}
        )
    if tilt:  # the grasps' xy stay; their height keeps the leaning palm clear
        picked = [
            _grasp_point(state, k, surface, flat, cfg, lean_i["tilt"], lean_i["tilt_heading"])
            for k, lean_i in zip(labels, leaning, strict=True)
        ]
    return _spread_plan(state, picked, labels, order, leaning, (w, h), cfg, flat, margin)


def plan_spread_at(
    state: ClothState,
    points: tuple[np.ndarray, np.ndarray],
    expected_size: tuple[float, float],
    cfg: SpreadConfig,
    flat: FlattenConfig,
    surface: np.ndarray | None = None,
    margin: float | None = None,
) -> SpreadPlan:
    """A spread from two given table points (x, y; world m) instead of two perceived corners,
    gripper down: each grasped just under the top surface seen there, the palm clear of the heap,
    then held, hung and laid as plan_spread's. For a policy that chooses where to grasp
    (foldbot.envs' TowelSpread); the plan's `corners` are "pick_a" and "pick_b"."""
    w, h = (float(v) for v in expected_size)
    require(
        math.isfinite(w) and math.isfinite(h) and w > 0.0 and h > 0.0,
        f"expected width × height must be > 0 m, got {w!r} × {h!r}",
    )
    xy = [np.asarray(p, dtype=float).reshape(-1)[:2] for p in points]
    require(
        len(xy) == 2 and all(v.shape == (2,) and np.all(np.isfinite(v)) for v in xy),
        f"a spread takes two finite table points (x, y), got {points!r}",
    )
    margin = cfg.hang_margins[0] if margin is None else float(margin)
    picked = [_grasp_at(state, v, surface, flat, cfg) for v in xy]
    order = sorted(range(2), key=lambda i: -float(picked[i][0][1]))
    leaning: list[dict] = [{}, {}]
    return _spread_plan(
        state, picked, ("pick_a", "pick_b"), order, leaning, (w, h), cfg, flat, margin
    )


def _spread_plan(
    state: ClothState,
    picked: list[tuple[np.ndarray, bool]],
    labels: tuple[str, str],
    order: list[int],
    leaning: list[dict],
    expected_size: tuple[float, float],
    cfg: SpreadConfig,
    flat: FlattenConfig,
    margin: float,
) -> SpreadPlan:
    """The spread once its grasps are chosen: `picked` (grasp point, jaws reach cloth) per label,
    `order` the +y arm's grasp first, `leaning` each grasp's tool tilt (SpreadAction fields)."""
    w, h = expected_size
    grasps = [g for g, _ in picked]
    seen = float(np.linalg.norm(grasps[0][:2] - grasps[1][:2]))
    width = spread_width(seen, w, h)
    hang = w * h / width
    cx, cy = (float(v) for v in cfg.center_xy)
    hold_x = min(cx + hang / 2, cfg.hold_far_x)
    x0, _x1, _y0, _y1 = flat.workspace
    release_x = max(hold_x - hang, x0 + flat.margin)
    lift = min(hang + margin, cfg.max_hold_height)
    actions = []
    for side, i in zip((1.0, -1.0), order, strict=True):
        y = cy + side * width / 2
        z_hold = table_z(state.table_plane, np.array([hold_x, y])) + lift
        z_touch = min(
            table_z(state.table_plane, np.array([hold_x, y])) + hang + 0.005, z_hold - 0.02
        )
        z_rel = table_z(state.table_plane, np.array([release_x, y])) + cfg.release_height
        actions.append(
            SpreadAction(
                grasp=grasps[i],
                hold=np.array([hold_x, y, z_hold]),
                touch=np.array([hold_x, y, z_touch]),
                release=np.array([release_x, y, z_rel]),
                label=f"spread {labels[i]}",
                hang_time=cfg.hang_time,
                descend_speed=cfg.descend_speed,
                slow_descent=cfg.slow_descent,
                lift_speed=cfg.lift_speed,
                lay_speed=cfg.lay_speed,
                **leaning[i],
            )
        )
    return SpreadPlan(
        (actions[0], actions[1]),
        (labels[order[0]], labels[order[1]]),
        width,
        hang,
        margin,
        all(ok for _, ok in picked),
    )


MARGIN_FREE_SEGMENTS = frozenset({"approach", "come_down", "descend"})
"""spread_segments' steps that do not depend on the hang margin: a pair infeasible in one of them
is infeasible at every margin."""


def spread_segments(
    action: SpreadAction, current: np.ndarray, motion: MotionConfig
) -> list[Segment]:
    """The segments one arm runs for its part of a spread, from TCP position `current`: approach,
    come down to `slow_descent` over the corner, descend slowly and close, lift straight up off
    the heap, rise and spread to the hold, hang (still, `hang_time`), lower until the towel
    touches, lay at 45° and open, retreat. Both arms' lists have the same steps."""
    up = np.array([0.0, 0.0, 1.0])
    grasp_tcp = action.grasp + up * motion.grasp_depth
    pre_grasp = action.grasp + up * motion.approach_height
    slow_from = grasp_tcp + up * min(action.slow_descent, float(pre_grasp[2] - grasp_tcp[2]))
    lifted = grasp_tcp + up * min(action.first_lift, max(action.hold[2] - grasp_tcp[2], 0.0) / 2)
    release_tcp = action.release + up * motion.grasp_depth
    approach = line_path(current, pre_grasp)
    come_down = line_path(pre_grasp, slow_from, 0.005)
    descend = line_path(slow_from, grasp_tcp, 0.005)
    lift = line_path(grasp_tcp, lifted)
    rise = line_path(lifted, action.hold)
    tilted = gripper_leaning_quaternion(action.tilt, action.tilt_heading) if action.tilt else None

    def turned(points: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray | None:
        """The orientations along `points`, from `start` to `end`; None untilted (gripper
        down, the executor's own)."""
        if tilted is None:
            return None
        return slerp_quaternions(start, end, np.linspace(0.0, 1.0, len(points)))

    return [
        Segment(
            "approach",
            approach,
            motion.free_speed,
            orientations=turned(approach, GRIPPER_DOWN, tilted),
        ),
        Segment(
            "come_down",
            come_down,
            motion.free_speed / 3,
            orientations=turned(come_down, tilted, tilted),
        ),
        Segment(
            "descend",
            descend,
            action.descend_speed,
            "close",
            orientations=turned(descend, tilted, tilted),
        ),
        Segment("lift", lift, action.lift_speed, orientations=turned(lift, tilted, tilted)),
        Segment(
            "spread",
            rise,
            action.lift_speed,
            dwell=action.hang_time,
            orientations=turned(rise, tilted, GRIPPER_DOWN),
        ),
        Segment("lower", line_path(action.hold, action.touch), action.lay_speed),
        Segment("lay", line_path(action.touch, release_tcp), action.lay_speed, "open"),
        Segment(
            "retreat",
            line_path(release_tcp, release_tcp + up * motion.retreat_height),
            motion.free_speed,
        ),
    ]


ACTION_KINDS = ("fold", "spread")
"""What one arm's part of a motion planned together is (action_as_dict's `kind`)."""


def action_as_dict(action: FoldAction | SpreadAction) -> dict:
    """One arm's action as JSON-ready data that names its kind, for a planner in another process
    (the ROS planner node): a pick-and-place or a spread."""
    return {"kind": "spread" if isinstance(action, SpreadAction) else "fold", **action.as_dict()}


def action_from_dict(d: dict) -> FoldAction | SpreadAction:
    """The action from its action_as_dict() form (no `kind`: a pick-and-place)."""
    kind = d.get("kind", "fold")
    if kind not in ACTION_KINDS:
        raise FoldbotError(f"unknown action kind {kind!r}; allowed: {', '.join(ACTION_KINDS)}")
    body = {k: v for k, v in d.items() if k != "kind"}
    return SpreadAction.from_dict(body) if kind == "spread" else FoldAction.from_dict(body)


def motion_segments(
    action: FoldAction | SpreadAction, current: np.ndarray, motion: MotionConfig
) -> list[Segment]:
    """The segments that execute `action` from TCP position `current`: a spread's, or a
    pick-and-place's (planning.motion.action_segments)."""
    if isinstance(action, SpreadAction):
        return spread_segments(action, current, motion)
    return action_segments(action, current, motion)
