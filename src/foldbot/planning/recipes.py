"""Towel fold recipes computed from the perceived corner keypoints — never from fixed coordinates.

Corners are named in the world frame relative to the robot (see perception.keypoints):
near_left, near_right, far_right, far_left (near = closer to the robot, left = +y); in that order
they go counter-clockwise around the cloth seen from above.

A recipe is a sequence of stages. Each stage is one fold (one fold line [x, y, dx, dy], moving side
to its left, as metrics.md requires) computed from the four corners perceived at the START of that
stage: the pipeline re-observes the cloth after every stage, so stage k sees the folded outline's
corners, labelled by the same rule. A stage yields one-gripper pick-and-place actions, one corner
grasp after the other; a grasp of a corner of a folded stack catches all its layers.

Recipes (`RECIPES`; the CLI offers them as `--recipe`, so the half fold's axis is a recipe name):
- "half"     1 stage. The far edge onto the near edge: the line joins the midpoints of the left and
             right sides. Grasps: far_left, then far_right.
- "half_y"   1 stage. The left edge onto the right edge: the line joins the midpoints of the near and
             far edges. Grasps: far_left, then near_left.
- "half_long" 1 stage. "half" or "half_y", whichever carries the far-apart pair of corners (the fold
             line runs along the longer side); "half" unless the depth exceeds the width by 10 %.
- "quarter"  2 stages. Stage 1 is "half"; stage 2 is "half_y" on the folded rectangle's perceived
             corners, i.e. a line perpendicular to the first through the folded rectangle's centre.
             Both cells fold it in "quarter_y"'s order (`folded_as`); "quarter_x" asks for this one.
- "quarter_x" quarter's own order, as written above, folded as given (`folded_as` maps only
             "quarter"): far half onto near half first, then the stack's left half onto its right.
- "quarter_y" 2 stages: the same folds the other way round, "half_y" then "half" on the folded
             rectangle. Both cells fold "quarter" this way (`folded_as`): one arm, carrying the
             stack by its edge's middle, diverged on 2 of 40 towels this way against 6 in
             quarter's order, 39.2 against 44.4 mm mean fold error; the two-arm cell carries this
             order's first stage as a pair (docs/experiments.md).
- "diagonal" 1 stage. The triangle fold: a far corner Q is laid on the side across from it, at the
             length of the shorter side it shares with a neighbouring corner P, so the line runs
             from P at 45° between P's two sides and the carried triangle lands on the cloth. On a
             square towel this is the corner-onto-corner diagonal. Of the far corners, and of each
             one's neighbours along a side no longer than P's other side (5 % slack, for noise),
             the one chosen moves Q most toward the robot (most negative world x displacement),
             the direction the arm reaches best; exact ties carry far_left, pivoting on near_left.
- "diagonal_corners" 1 stage. The line runs through two opposite corners; the one action carries a
             free far corner over it (the far corner whose place lies most toward the robot; exact
             ties: far_left). For a non-square towel the mirrored triangle overhangs the staying
             part, and even the exact goal scores 0.81–0.94 normalized performance, near the
             success bar of 0.8; "diagonal" folded 20 of 20 towel_loop towels where this folded 16
             (docs/experiments.md).
- "thirds"   2 stages. Stage 1: the near third onto the middle — the line crosses the left and
             right sides at 1/3 of the way from the near corner to the far corner. Grasps:
             near_left, then near_right. Stage 2: the far third on top — the line at 2/3 of the
             ORIGINAL depth from the near edge. After stage 1 the perceived outline spans from the
             stage-1 crease to the far edge, i.e. 2/3 of the original depth, so that line is the
             outline's midline: it joins the midpoints of the perceived left and right sides, and
             the far side moves. Grasps: far_left, then far_right. This order lays the stack's
             top layer toward the robot (the other order, far third first, folded worse:
             docs/experiments.md). The midline is where stage 1 laid the near third's free edge,
             so the line moves `crease_room` toward the far edge: a crease folded right on that
             edge pushes the whole laid third back toward the robot (by 2–3 cm in the simulated
             cloth), a crease just past it wraps around it.

A stage's labels rely on the labelling rule, which is stable while a rectangle's yaw stays away from
±45° (mod 90°), where two corners tie for "near_left"; there, noise can rotate the labels by one, and
a second stage would fold along the other axis of the folded rectangle.

Place points are the grasp points mirrored across the stage's fold line, lifted by `place_lift`.
Each fold line's point lies on the cloth outline and its direction spans the cloth (the point plus
the direction is the other end of the crease), so drawing [p, p + d] shows the crease.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from foldbot.errors import ConfigError
from foldbot.metrics import FoldLine
from foldbot.perception.keypoints import label_corners, max_area_quad
from foldbot.planning.actions import FoldAction, FoldPlan

CORNER_NAMES = ("near_left", "near_right", "far_right", "far_left")
"""Corner labels in counter-clockwise order (seen from above, world frame)."""
RECIPES = (
    "half",
    "half_y",
    "half_long",
    "quarter",
    "quarter_x",
    "quarter_y",
    "diagonal",
    "diagonal_corners",
    "thirds",
)
"""Recipe names accepted by plan_stage / plan_recipe (and the CLI's --recipe)."""
RECIPE_HELP = {
    "half": "far half onto the near half (1 stage)",
    "half_y": "left half onto the right half (1 stage)",
    "half_long": "in half across the longer side, the shorter carry (half or half_y; 1 stage)",
    "quarter": "in quarters, two halves (2 stages), folded in quarter_y's order",
    "quarter_x": "far half onto the near half, then the folded rectangle's left half onto its "
    "right half (2 stages)",
    "quarter_y": "left half onto the right half, then the folded rectangle's far half onto its "
    "near half (2 stages)",
    "diagonal": "a far corner onto the side across, at its shorter side's length: a triangle "
    "(on a square, onto the opposite corner; 1 stage)",
    "diagonal_corners": "a far corner across the line through its two neighbours (1 stage)",
    "thirds": "near third onto the middle, then the far third on top (2 stages)",
}
"""One line per recipe, for CLI help."""
MIN_SIDE = 1e-3
"""Shortest allowed side of the perceived corner quad (m); shorter means coincident corners."""
MIN_TURN_SINE = 0.02
"""Smallest allowed sine of the turn at each corner (~1.1°); smaller means collinear corners."""

Line = tuple[float, float, float, float]


@dataclass(frozen=True)
class _Fold:
    """One stage's fold: its line and the corners it carries, in grasp order."""

    line: Line
    moving: tuple[str, ...]


def _mirror(point: np.ndarray, line: Line) -> np.ndarray:
    """Reflect a point's x, y across the line [x, y, dx, dy]; z is kept."""
    return FoldLine(*line).reflect_xy(np.asarray(point, dtype=float))


def _require_corners(corners: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The four labelled corners as float xyz arrays; ConfigError if any is missing or malformed,
    or if they do not form a proper counter-clockwise quad (coincident or collinear corners)."""
    missing = [n for n in CORNER_NAMES if n not in corners]
    if missing:
        raise ConfigError(f"fold planning needs the corners {CORNER_NAMES}, missing {missing}")
    c = {}
    for name in CORNER_NAMES:
        value = np.asarray(corners[name], dtype=float).reshape(-1)
        if value.shape != (3,) or not np.all(np.isfinite(value)):
            raise ConfigError(
                f"corner {name} = {corners[name]!r} must be a finite world point (x, y, z)"
            )
        c[name] = value
    quad = np.array([c[n][:2] for n in CORNER_NAMES])
    sides = np.roll(quad, -1, axis=0) - quad  # side k: corner k → k+1
    lengths = np.linalg.norm(sides, axis=1)
    if lengths.min() < MIN_SIDE:
        k = int(np.argmin(lengths))
        raise ConfigError(
            f"degenerate corner quad: {CORNER_NAMES[k]} and {CORNER_NAMES[(k + 1) % 4]} are "
            f"{lengths[k] * 1000:.2f} mm apart (at least {MIN_SIDE * 1000:g} mm needed)"
        )
    prev = np.roll(sides, 1, axis=0)  # side arriving at corner k
    turn = (prev[:, 0] * sides[:, 1] - prev[:, 1] * sides[:, 0]) / (np.roll(lengths, 1) * lengths)
    if turn.min() < MIN_TURN_SINE:
        k = int(np.argmin(turn))
        kind = "collinear with its neighbours" if abs(turn[k]) < MIN_TURN_SINE else "reflex"
        raise ConfigError(
            f"degenerate corner quad: {CORNER_NAMES[k]} is {kind} (turn sine {turn[k]:.3g}); "
            f"the corners must form a convex quad in counter-clockwise order {CORNER_NAMES}"
        )
    return c


def _oriented_line(a: np.ndarray, b: np.ndarray, probe: np.ndarray) -> Line:
    """The line from a to b, or from b to a, whichever has `probe` on its left (moving) side."""
    d = b[:2] - a[:2]
    rel = probe[:2] - a[:2]
    if -d[1] * rel[0] + d[0] * rel[1] < 0:
        a, d = b, -d
    return (float(a[0]), float(a[1]), float(d[0]), float(d[1]))


def _edge_fold(
    c: dict[str, np.ndarray],
    moving: tuple[str, str],
    staying: tuple[str, str],
    fraction: float,
    room: float = 0.0,
) -> _Fold:
    """Fold whose line crosses the two sides staying[i]→moving[i] at `fraction` of their length
    from the staying corner, plus `room` (m) further along them; the moving corners are carried,
    in the given order."""

    def crossing(i: int) -> np.ndarray:
        side = c[moving[i]] - c[staying[i]]
        return c[staying[i]] + (fraction + room / float(np.linalg.norm(side[:2]))) * side

    a, b = crossing(0), crossing(1)
    probe = (c[moving[0]] + c[moving[1]]) / 2
    return _Fold(_oriented_line(a, b, probe), moving)


def _half_x(c: dict[str, np.ndarray]) -> _Fold:
    """Far half onto the near half."""
    return _edge_fold(c, ("far_left", "far_right"), ("near_left", "near_right"), 0.5)


def _half_y(c: dict[str, np.ndarray]) -> _Fold:
    """Left half onto the right half."""
    return _edge_fold(c, ("far_left", "near_left"), ("far_right", "near_right"), 0.5)


LONG_SIDE_MARGIN = 1.1
"""half_long folds along y only when the near–far depth exceeds the left–right width by this
factor, so near-square towels keep the `half` axis whatever the perception noise."""


def _depth_and_width(c: dict[str, np.ndarray]) -> tuple[float, float]:
    """Mean near–far depth and left–right width of the corner quad (m)."""
    depth = np.linalg.norm((c["far_left"] + c["far_right"] - c["near_left"] - c["near_right"])[:2])
    width = np.linalg.norm((c["far_left"] + c["near_left"] - c["far_right"] - c["near_right"])[:2])
    return float(depth) / 2, float(width) / 2


def _half_long(c: dict[str, np.ndarray]) -> _Fold:
    """Half fold whose carried corners are the far-apart pair: one gripper carries one corner after
    the other, and a corner close to the carried one is dragged along by the first carry."""
    depth, width = _depth_and_width(c)
    return _half_y(c) if depth > LONG_SIDE_MARGIN * width else _half_x(c)


def _near_third(c: dict[str, np.ndarray]) -> _Fold:
    """Near third onto the middle third: the line at 1/3 of each side from the near edge."""
    return _edge_fold(c, ("near_left", "near_right"), ("far_left", "far_right"), 2.0 / 3.0)


def _far_third(c: dict[str, np.ndarray], crease_room: float = 0.0) -> _Fold:
    """Far third on top, from the outline after _near_third: that outline's midline, far moving,
    moved `crease_room` toward the far edge so the crease clears the laid near third's free edge.
    (Folding a towel deeper than wide across its width instead, so the carried edges are the long
    ones, was mixed across suites and is not used: docs/experiments.md.)"""
    return _edge_fold(c, ("far_left", "far_right"), ("near_left", "near_right"), 0.5, crease_room)


TRIANGLE_SLACK = 1.05
"""The triangle fold pivots on a corner P only where the carried corner's side from P is at most
this factor longer than P's other side (else the laid triangle overhangs; the slack takes
perception noise on near-square towels)."""


def _triangle(c: dict[str, np.ndarray]) -> _Fold:
    """The triangle fold: a far corner Q laid on the side P–R across from it, |PQ| from P, for its
    neighbour P and P's other neighbour R; the line from P bisects the angle QPR. Of the allowed
    (Q, P), the one that moves Q most toward the robot (ties: far_left, then near_left first)."""
    best: tuple[float, _Fold] | None = None
    for carried in ("far_left", "far_right"):
        k = CORNER_NAMES.index(carried)
        for pivot in (CORNER_NAMES[(k + 1) % 4], CORNER_NAMES[(k - 1) % 4]):
            j = CORNER_NAMES.index(pivot)
            other = CORNER_NAMES[(2 * j - k) % 4]  # P's neighbour that is not Q
            p, q, r = c[pivot], c[carried], c[other]
            along_q, along_r = (q - p)[:2], (r - p)[:2]
            side_q, side_r = float(np.hypot(*along_q)), float(np.hypot(*along_r))
            if side_q > TRIANGLE_SLACK * side_r:
                continue
            laid = p[:2] + along_r * (side_q / side_r)  # where Q lands, on side P–R
            end = p.copy()
            # The crease's far end: on Q's other side, |PQ| from Q.
            end[:2] = p[:2] + along_q + (laid - p[:2])
            line = _oriented_line(p, end, q)
            dx = float(laid[0] - q[0])
            if best is None or dx < best[0] - 1e-12:
                best = (dx, _Fold(line, (carried,)))
    if best is None:  # unreachable for a convex quad: one of each Q's two sides is the shorter
        raise ConfigError("no corner allows a triangle fold of this outline")
    return best[1]


def _corner_diagonal(c: dict[str, np.ndarray]) -> _Fold:
    """A far corner over the diagonal through its two neighbours: the far corner whose place lies
    most toward the robot (exact tie: far_left)."""
    options = (
        ("far_left", "near_left", "far_right"),  # carried corner, line through these two
        ("far_right", "near_right", "far_left"),
    )
    folds = []
    for carried, a, b in options:
        line = _oriented_line(c[a], c[b], c[carried])
        dx = float(_mirror(c[carried], line)[0] - c[carried][0])  # world x displacement
        folds.append((dx, _Fold(line, (carried,))))
    (dx_left, left), (dx_right, right) = folds
    return right if dx_right < dx_left - 1e-12 else left


_GRASP_LAYERS: dict[tuple[str, int], int] = {}
"""Layers at the corners a stage grasps, where more than one (`FoldAction.layers`: the closed loop
then closes the jaws at the table, under the whole stack, a little inside the perceived corner).
Empty: for quarter's second stage, (quarter, 1) → 2 folded worse than a top-layer grasp in two
trials (seeds 0–3: fold errors 150–184 mm against 57–208 mm, and one diverged soft body), and again
with the jaws placed where depth showed both layers (seeds 0–5: 159–368 mm, 3 diverged;
docs/experiments.md)."""

_STAGES: dict[str, tuple[Callable[[dict[str, np.ndarray]], _Fold], ...]] = {
    "half": (_half_x,),
    "half_y": (_half_y,),
    "half_long": (_half_long,),
    "quarter": (_half_x, _half_y),
    "quarter_x": (_half_x, _half_y),
    "quarter_y": (_half_y, _half_x),
    "diagonal": (_triangle,),
    "diagonal_corners": (_corner_diagonal,),
    "thirds": (_near_third, _far_third),
}


_CREASE_ROOM_STAGES = frozenset({("thirds", 1)})
"""Stages whose fold line lies along the free edge of a layer an earlier stage laid: they take
`crease_room` (other stages ignore it)."""
MAX_CREASE_ROOM = 0.05
"""Largest accepted crease room (m): a few cloth thicknesses, far more than a crease needs."""


_STACK_STAGES = frozenset({("quarter", 1), ("quarter_x", 1), ("quarter_y", 1)})
"""Stages that carry a stack an earlier stage folded (its corners are several layers)."""
FOLD_ORDERS = {"quarter": "quarter_y"}
"""The order a cell folds a recipe in, where it differs from the recipe's own: quarter as
quarter_y, left onto right first (see "quarter_y" above)."""


def carries_stack(recipe: str, stage_index: int) -> bool:
    """Whether a stage carries cloth an earlier stage folded (quarter's second stage): the
    closed loop does not lay such a corner again with one arm (docs/experiments.md)."""
    return (recipe, stage_index) in _STACK_STAGES


def folded_as(recipe: str) -> str:
    """The recipe whose stages a cell plans for `recipe`: the same folds, in the order FOLD_ORDERS
    gives (quarter: quarter_y), or the recipe itself."""
    if recipe not in _STAGES:
        raise ConfigError(f"unknown recipe {recipe!r}; allowed: {', '.join(RECIPES)}")
    return FOLD_ORDERS.get(recipe, recipe)


def takes_crease_room(recipe: str, stage_index: int) -> bool:
    """Whether a stage's fold line lies along an earlier layer's free edge, so that plan_stage
    moves it by `crease_room` (thirds' second stage)."""
    return (recipe, stage_index) in _CREASE_ROOM_STAGES


def recipe_stages(recipe: str) -> int:
    """Number of stages (folds, each planned on freshly perceived corners) of a recipe."""
    if recipe not in _STAGES:
        raise ConfigError(f"unknown recipe {recipe!r}; allowed: {', '.join(RECIPES)}")
    return len(_STAGES[recipe])


def _stage_fold(
    recipe: str, stage_index: int, corners: dict[str, np.ndarray], crease_room: float = 0.0
) -> _Fold:
    """Validate the recipe, stage index, corners and crease room, and compute that stage's fold."""
    n = recipe_stages(recipe)
    if isinstance(stage_index, bool) or not isinstance(stage_index, int | np.integer):
        raise ConfigError(f"stage index {stage_index!r} must be an integer in [0, {n - 1}]")
    if not 0 <= stage_index < n:
        raise ConfigError(
            f"stage index {stage_index} is out of range for recipe {recipe!r} "
            f"({n} stage{'s' if n > 1 else ''}: 0..{n - 1})"
        )
    room = float(crease_room) if isinstance(crease_room, int | float | np.floating) else None
    if isinstance(crease_room, bool) or room is None or not 0.0 <= room <= MAX_CREASE_ROOM:
        raise ConfigError(
            f"crease_room = {crease_room!r} must be a number in [0, {MAX_CREASE_ROOM}] (m)"
        )
    stage = _STAGES[recipe][int(stage_index)]
    c = _require_corners(corners)
    return stage(c, room) if takes_crease_room(recipe, int(stage_index)) else stage(c)


def plan_stage(
    recipe: str,
    stage_index: int,
    corners: dict[str, np.ndarray],
    place_lift: float = 0.004,
    crease_room: float = 0.0,
) -> FoldPlan:
    """Plan one stage of a recipe on the corners perceived at its start: its one fold line and the
    one-gripper pick-and-place actions (grasp a corner, release at its mirror, lifted).

    The release height is `place_lift` above the higher of the grasped corner and the corner
    nearest the place point, so a corner laid onto a thicker stack (thirds' second stage) is not
    pushed into it. `crease_room` (m, ≥ 0) moves a fold line that lies along an earlier layer's
    free edge (thirds' second stage) that far onto its moving side; the closed loop passes the
    height that layer rose, seen in depth (about one cloth thickness)."""
    fold = _stage_fold(recipe, stage_index, corners, crease_room)
    c = _require_corners(corners)
    layers = _GRASP_LAYERS.get((recipe, int(stage_index)), 1)
    actions = []
    for name in fold.moving:
        place = _mirror(c[name], fold.line)
        target = min(CORNER_NAMES, key=lambda n: float(np.linalg.norm(c[n][:2] - place[:2])))
        place[2] = max(c[name][2], c[target][2]) + place_lift
        actions.append(
            FoldAction(grasp=c[name], place=place, fold_line=fold.line, label=name, layers=layers)
        )
    return FoldPlan(recipe=recipe, fold_lines=(fold.line,), actions=tuple(actions))


def plan_recipe(recipe: str, corners: dict[str, np.ndarray], place_lift: float = 0.004) -> FoldPlan:
    """Plan the first stage of a named recipe on the perceived corners (see plan_stage)."""
    return plan_stage(recipe, 0, corners, place_lift)


def recipe_fold_lines(recipe: str, corners: dict[str, np.ndarray]) -> tuple[Line, ...]:
    """Every fold line of `recipe`, in the order a cell folds it (folded_as), planned from one
    set of corners: each later stage on the four corners of the outline the earlier stages
    predict (predicted_outline's largest quad, labelled by the perception's rule, as a camera
    would find them), no crease room. The geometric goal of the whole recipe on a cloth whose
    corners are known (an environment's goal, from ground truth); a cell instead plans each
    stage on the corners it perceives then."""
    order = folded_as(recipe)
    c = _require_corners(corners)
    lines: list[Line] = []
    for k in range(recipe_stages(order)):
        if k:
            outline = predicted_outline(order, k - 1, c)
            if len(outline) < 4:
                raise ConfigError(
                    f"recipe {recipe!r}: stage {k} needs a four-cornered outline, stage {k - 1} "
                    f"predicts {len(outline)} corners"
                )
            quad = outline[max_area_quad(outline[:, :2])]
            c = {name: quad[i] for name, i in label_corners(quad).items()}
        lines.append(_stage_fold(order, k, c).line)
    return tuple(lines)


def half_fold(
    corners: dict[str, np.ndarray], axis: str = "x", place_lift: float = 0.004
) -> FoldPlan:
    """Half fold across x (far onto near, recipe "half") or y (left onto right, "half_y")."""
    if axis not in ("x", "y"):
        raise ConfigError(f"half fold axis must be 'x' or 'y', got {axis!r}")
    return plan_stage("half" if axis == "x" else "half_y", 0, corners, place_lift)


# --- predicted outline ---------------------------------------------------------------------------


def _clip(poly: np.ndarray, side: np.ndarray, keep_positive: bool) -> np.ndarray:
    """Sutherland–Hodgman: the part of a convex polygon (N×2) where side ≥ 0 (or ≤ 0)."""
    s = side if keep_positive else -side
    out = []
    n = len(poly)
    for i in range(n):
        p, q = poly[i], poly[(i + 1) % n]
        sp, sq = s[i], s[(i + 1) % n]
        if sp >= 0:
            out.append(p)
        if (sp > 0 and sq < 0) or (sp < 0 and sq > 0):
            out.append(p + (sp / (sp - sq)) * (q - p))
    return np.array(out).reshape(-1, 2)


def _signed_area(poly: np.ndarray) -> float:
    """Shoelace signed area of a polygon (N×2); positive when counter-clockwise."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - y * np.roll(x, -1)))


def _strictly_inside(p: np.ndarray, poly: np.ndarray, tol: float) -> bool:
    """Whether p lies inside the convex counter-clockwise polygon, farther than tol from its edges."""
    n = len(poly)
    if n < 3:
        return False
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        e = b - a
        length = np.hypot(*e)
        if length <= tol:
            continue
        if (e[0] * (p[1] - a[1]) - e[1] * (p[0] - a[0])) / length <= tol:
            return False
    return True


def _edge_crossings(p: np.ndarray, q: np.ndarray) -> list[np.ndarray]:
    """Points where an edge of polygon p crosses an edge of polygon q (parallel edges skipped)."""
    out = []
    for i in range(len(p)):
        a, b = p[i], p[(i + 1) % len(p)]
        for j in range(len(q)):
            c, d = q[j], q[(j + 1) % len(q)]
            r, s = b - a, d - c
            den = r[0] * s[1] - r[1] * s[0]
            if abs(den) <= 1e-15 * max(np.hypot(*r) * np.hypot(*s), 1e-300):
                continue
            w = c - a
            t = (w[0] * s[1] - w[1] * s[0]) / den
            u = (w[0] * r[1] - w[1] * r[0]) / den
            if -1e-12 <= t <= 1 + 1e-12 and -1e-12 <= u <= 1 + 1e-12:
                out.append(a + t * r)
    return out


def _fold_outline(quad: np.ndarray, line: FoldLine) -> np.ndarray:
    """Top-view outline (M×2, counter-clockwise) of a convex quad folded along a line: the union of
    the staying part and the mirrored moving part.

    Both parts are convex and share the crease chord, on the same side of the line, so their union
    is star-shaped about the chord's midpoint: its boundary is the candidate points (both parts'
    vertices and edge crossings) not strictly inside either part, sorted by angle about that point.
    """
    side = line.side(quad)
    staying = _clip(quad, side, keep_positive=False)
    moving = _clip(quad, side, keep_positive=True)
    scale = float(np.max(np.linalg.norm(quad - quad.mean(axis=0), axis=1)))
    tol = 1e-9 * max(scale, 1e-3)
    if len(moving) < 3 or abs(_signed_area(moving)) <= tol * scale:
        return staying
    mirrored = line.reflect_xy(moving)[::-1]  # a reflection flips orientation; restore CCW
    if len(staying) < 3 or abs(_signed_area(staying)) <= tol * scale:
        return mirrored
    candidates = [*staying, *mirrored, *_edge_crossings(staying, mirrored)]
    points: list[np.ndarray] = []
    for p in candidates:
        if _strictly_inside(p, staying, tol) or _strictly_inside(p, mirrored, tol):
            continue
        if all(np.hypot(*(p - o)) > 10 * tol for o in points):
            points.append(p)
    pts = np.array(points)
    chord = staying[np.abs(line.side(staying)) <= 10 * tol]
    centre = chord.mean(axis=0) if len(chord) else staying.mean(axis=0)
    d = np.array([line.dx, line.dy]) / np.hypot(line.dx, line.dy)
    rel = pts - centre
    u = rel @ d
    v = -(rel @ np.array([-d[1], d[0]]))  # toward the staying side
    v = np.where(v > 0, v, 0.0)  # round-off below the line → on it (angle 0 or π, never −π)
    pts = pts[np.argsort(np.arctan2(v, u), kind="stable")]
    # Drop vertices that lie on the straight edge between their neighbours.
    keep = []
    n = len(pts)
    for i in range(n):
        a, b, c = pts[i - 1], pts[i], pts[(i + 1) % n]
        cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
        if abs(cross) > tol * scale:
            keep.append(b)
    out = np.array(keep)
    return out if _signed_area(out) > 0 else out[::-1]


def predicted_outline(
    recipe: str, stage_index: int, corners: dict[str, np.ndarray], crease_room: float = 0.0
) -> np.ndarray:
    """Top-view outline (N×3, counter-clockwise, at the corners' mean z) the cloth should have after
    a stage, to compare with the perceived mask: the corner quad folded along the stage's line
    (`crease_room` as for plan_stage)."""
    fold = _stage_fold(recipe, stage_index, corners, crease_room)
    c = _require_corners(corners)
    quad = np.array([c[n][:2] for n in CORNER_NAMES])
    xy = _fold_outline(quad, FoldLine(*fold.line))
    z = float(np.mean([c[n][2] for n in CORNER_NAMES]))
    return np.column_stack([xy, np.full(len(xy), z)])


def predicted_cover(
    recipe: str,
    stage_index: int,
    corners: dict[str, np.ndarray],
    crease_band: float = 0.0,
    crease_room: float = 0.0,
) -> np.ndarray:
    """Top-view region (N×3, counter-clockwise, at the corners' mean z) a stage lays its moved cloth
    on: the corner quad's moving part mirrored across the stage's fold line, less the band of
    `crease_band` (m) along the line where the crease's bend stands (empty when nothing is left;
    `crease_room` as for plan_stage)."""
    fold = _stage_fold(recipe, stage_index, corners, crease_room)
    c = _require_corners(corners)
    quad = np.array([c[n][:2] for n in CORNER_NAMES])
    line = FoldLine(*fold.line)
    moving = _clip(quad, line.side(quad), keep_positive=True)
    if len(moving) < 3:
        return np.zeros((0, 3))
    xy = line.reflect_xy(moving)[::-1]
    if crease_band > 0:
        xy = _clip(xy, line.side(xy) + crease_band * np.hypot(line.dx, line.dy), False)
    if len(xy) < 3:
        return np.zeros((0, 3))
    z = float(np.mean([c[n][2] for n in CORNER_NAMES]))
    return np.column_stack([xy, np.full(len(xy), z)])
