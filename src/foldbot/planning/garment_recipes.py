"""Garment fold recipes (T-shirt, pants): every fold line computed from the perceived keypoints.

A garment is planned once, from the keypoints perceived on the flat garment (a folded garment hides
them): the fold lines come from the garment's own frame (up = from the hem / leg ends to the
shoulders / waist, right = up turned −90°, so "left" keypoints have negative u), and a later
stage's grasp points are the first observation's points carried through the earlier folds'
reflections. The closed loop (foldbot.garment_loop) corrects each grasp onto the cloth it sees.

Recipes (`GARMENT_RECIPES`):
- tshirt "retail" — sleeves and sides in, then hem up (3 stages):
  1. the left side with its sleeve onto the body: line parallel to the body axis at u = −a;
     grasps left_sleeve, then left_hem (the hem corner, which carries the side's body strip,
     placed last, so the sleeve's carry does not drag it back: carried first it fell back;
     docs/experiments.md). `a` is half the body's half-width, widened when needed so the
     mirrored sleeve end stays short of the other side's line (a ≥ c/3, c = the cuff's |u|);
  2. the right side likewise at u = +a (right_sleeve, right_hem);
  3. hem up: the line across the body halfway between the hem and the shoulders, carried from
     the tip (see below), up to two actions.
- pants "leg_over_leg" — leg over leg, then in half (2 stages):
  1. the left leg onto the right one: the line is the garment's axis (through the midpoints of
     the waist and of the leg ends); grasps: left_waist, then the left leg's hem middle (the long
     leg placed last, so the waist's carry does not drag it off its place);
  2. in half: the line across halfway between the leg ends and the waist, up to two actions: the
     top leg (the one the first stage laid, found in depth) from its own end, then what is left
     from the tip (`top_first`).

A stage "carried from the tip" (`GarmentStage.from_tip`) folds a stack: the closed loop grasps the
cloth left on the moving side where it reaches farthest from the line, places it at its mirror,
and repeats while cloth is left there (at most the planned number of actions). That takes the
layers in the order the fold's goal stacks them and never pinches two layers in one grasp (which
the soft-body solver does not survive). The planned grasps (the stack's hem middle) say which end
of the outline to take when several points tie. With `top_first`, the first action takes the
stack's top layer from where it reaches farthest instead: the leg laid on the other ends a few
centimetres short of the tip, so a tip grasp holds only the bottom layer and the top one, held by
nothing, slides off it into the crease.

Each fold line is [x, y, dx, dy] with the moving side on its left (metrics.md); its point lies on
the garment's outline and its direction spans the garment, so [p, p + d] draws the crease.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldbot.errors import ConfigError
from foldbot.garments.pants import PANTS_KEYPOINTS
from foldbot.garments.tshirt import TSHIRT_KEYPOINTS
from foldbot.metrics import FoldLine
from foldbot.planning.actions import FoldAction

Line = tuple[float, float, float, float]

GARMENT_RECIPES: dict[str, tuple[str, ...]] = {
    "tshirt": ("retail",),
    "pants": ("leg_over_leg",),
}
"""Fold recipes per garment kind (the towel's are planning.recipes.RECIPES)."""
GARMENT_RECIPE_HELP = {
    "retail": "T-shirt: sleeves and sides in, then hem up (3 stages)",
    "leg_over_leg": "pants: left leg onto the right, then in half (2 stages)",
}
PLANNED_FROM: dict[str, tuple[str, ...]] = {
    "retail": tuple(n for n in TSHIRT_KEYPOINTS if n.endswith(("_shoulder", "_sleeve", "_hem"))),
    "leg_over_leg": tuple(n for n in PANTS_KEYPOINTS if n != "crotch"),
}
"""The keypoints each garment recipe's lines and grasps are computed from (the neck, armpits and
crotch help recognise a garment, but no fold is planned from them)."""
STACK_INSET = 0.01
"""A grasp on a folded stack's corner is set this far (m) inside it, so the jaws close on every
layer rather than on the bare table beside the crease."""
MIN_GARMENT_SIZE = 0.05
"""Smallest allowed body width / length (m) between perceived keypoints."""


@dataclass(frozen=True)
class GarmentFrame:
    """The garment's frame in the table plane: origin, up (towards neck / waist) and right."""

    origin: np.ndarray
    up: np.ndarray
    right: np.ndarray

    def uv(self, point: np.ndarray) -> tuple[float, float]:
        """(u, v) coordinates of a world point (x, y used)."""
        d = np.asarray(point, dtype=float)[:2] - self.origin
        return float(d @ self.right), float(d @ self.up)

    def xy(self, u: float, v: float) -> np.ndarray:
        """World (x, y) of garment coordinates (u, v)."""
        return self.origin + u * self.right + v * self.up


@dataclass(frozen=True)
class GarmentStage:
    """One fold of a garment plan: its line and its pick-and-place actions in order."""

    fold_line: Line
    actions: tuple[FoldAction, ...]
    from_tip: bool = False
    """True: each action grasps the cloth left on the moving side where it reaches farthest from
    the line (as seen just before it), not its planned point; the planned grasps give the action
    budget and the end of the outline to take when several points tie."""
    top_first: bool = False
    """With `from_tip`: the first action carries the stack's top layer (the one the stage before
    laid, seen in depth) from where that layer reaches farthest, the next ones the rest from the
    tip (pants' legs; the T-shirt's hem stage folded worse so: docs/experiments.md)."""


@dataclass(frozen=True)
class GarmentPlan:
    """A garment recipe instantiated on perceived keypoints: stages planned all at once."""

    recipe: str
    stages: tuple[GarmentStage, ...]

    @property
    def fold_lines(self) -> tuple[Line, ...]:
        return tuple(s.fold_line for s in self.stages)

    def as_dict(self) -> dict:
        """JSON-ready form (the ROS planner node's reply)."""
        return {
            "recipe": self.recipe,
            "stages": [
                {
                    "fold_line": [float(v) for v in s.fold_line],
                    "actions": [a.as_dict() for a in s.actions],
                    "from_tip": s.from_tip,
                    "top_first": s.top_first,
                }
                for s in self.stages
            ],
        }

    @classmethod
    def from_dict(cls, d: dict) -> GarmentPlan:
        """The plan from its `as_dict()` form."""
        return cls(
            d["recipe"],
            tuple(
                GarmentStage(
                    tuple(float(v) for v in s["fold_line"]),
                    tuple(FoldAction.from_dict(a) for a in s["actions"]),
                    bool(s.get("from_tip", False)),
                    bool(s.get("top_first", False)),
                )
                for s in d["stages"]
            ),
        )


def recipe_keypoints(recipe: str) -> tuple[str, ...]:
    """Keypoints a garment recipe is planned from (PLANNED_FROM); ConfigError for an unknown
    recipe."""
    if recipe in PLANNED_FROM:
        return PLANNED_FROM[recipe]
    allowed = ", ".join(r for rs in GARMENT_RECIPES.values() for r in rs)
    raise ConfigError(f"unknown garment recipe {recipe!r}; allowed: {allowed}")


def _require_keypoints(recipe: str, keypoints: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The recipe's keypoints as finite xyz arrays; ConfigError naming what is missing or bad."""
    names = recipe_keypoints(recipe)
    missing = [n for n in names if n not in keypoints]
    if missing:
        raise ConfigError(f"recipe {recipe!r} needs the keypoints {names}, missing {missing}")
    out = {}
    for n in names:
        value = np.asarray(keypoints[n], dtype=float).reshape(-1)
        if value.shape != (3,) or not np.all(np.isfinite(value)):
            raise ConfigError(f"keypoint {n} = {keypoints[n]!r} must be a finite world point")
        out[n] = value
    return out


def _unit(v: np.ndarray, what: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if n < MIN_GARMENT_SIZE:
        raise ConfigError(
            f"degenerate garment keypoints: {what} is {n * 1000:.1f} mm long "
            f"(at least {MIN_GARMENT_SIZE * 1000:g} mm needed)"
        )
    return v / n


def garment_frame(bottom: np.ndarray, top: np.ndarray) -> GarmentFrame:
    """The frame whose origin is `bottom` (x, y) and whose up points at `top`."""
    up = _unit(np.asarray(top, float)[:2] - np.asarray(bottom, float)[:2], "the garment's axis")
    return GarmentFrame(np.asarray(bottom, float)[:2].copy(), up, np.array([up[1], -up[0]]))


def _line(frame: GarmentFrame, start_uv: tuple[float, float], dir_uv: tuple[float, float]) -> Line:
    p = frame.xy(*start_uv)
    d = dir_uv[0] * frame.right + dir_uv[1] * frame.up
    return (float(p[0]), float(p[1]), float(d[0]), float(d[1]))


def _mirror(point: np.ndarray, line: Line) -> np.ndarray:
    return FoldLine(*line).reflect_xy(np.asarray(point, dtype=float))


def _action(grasp: np.ndarray, line: Line, label: str, lift: float, layers: int = 1) -> FoldAction:
    place = _mirror(grasp, line)
    place[2] = grasp[2] + lift
    return FoldAction(grasp=grasp, place=place, fold_line=line, label=label, layers=layers)


def _plan_tshirt(k: dict[str, np.ndarray], lift: float, thickness: float) -> GarmentPlan:
    hem_mid = (k["left_hem"] + k["right_hem"]) / 2
    top_mid = (k["left_shoulder"] + k["right_shoulder"]) / 2
    f = garment_frame(hem_mid, top_mid)
    (lu, _), (ru, _) = f.uv(k["left_hem"]), f.uv(k["right_hem"])
    half_width = (ru - lu) / 2
    if half_width < MIN_GARMENT_SIZE / 2:
        raise ConfigError(
            f"degenerate T-shirt keypoints: left_hem is not left of right_hem "
            f"(body half-width {half_width * 1000:.1f} mm along the garment's right axis)"
        )
    cuff = max(-f.uv(k["left_sleeve"])[0], f.uv(k["right_sleeve"])[0])
    a = min(max(0.5 * half_width, cuff / 3 + 0.01), 0.8 * half_width)
    v_top = f.uv(top_mid)[1]
    z = float(np.mean([k[n][2] for n in ("left_hem", "right_hem")]))
    left = _line(f, (-a, 0.0), (0.0, v_top))  # moving side: u < −a (left of "up")
    right = _line(f, (a, v_top), (0.0, -v_top))  # moving side: u > +a
    hem_up = _line(f, (a, v_top / 2), (-2 * a, 0.0))  # moving side: v < v_top / 2 (the hem)
    s1 = GarmentStage(
        left,
        (
            _action(k["left_sleeve"], left, "left_sleeve", lift),
            _action(k["left_hem"], left, "left_hem", lift),
        ),
    )
    s2 = GarmentStage(
        right,
        (
            _action(k["right_sleeve"], right, "right_sleeve", lift),
            _action(k["right_hem"], right, "right_hem", lift),
        ),
    )
    xy = f.xy(0.0, STACK_INSET)
    hem = np.array([xy[0], xy[1], z + thickness])
    tip = tuple(_action(hem, hem_up, label, lift) for label in ("hem", "hem_rest"))
    return GarmentPlan("retail", (s1, s2, GarmentStage(hem_up, tip, from_tip=True)))


def _plan_pants(k: dict[str, np.ndarray], lift: float, thickness: float) -> GarmentPlan:
    legs = ("left_leg_outer", "left_leg_inner", "right_leg_outer", "right_leg_inner")
    bottom = np.mean([k[n] for n in legs], axis=0)
    top = (k["left_waist"] + k["right_waist"]) / 2
    f = garment_frame(bottom, top)
    lu, ru = f.uv(k["left_waist"])[0], f.uv(k["right_waist"])[0]
    if ru - lu < MIN_GARMENT_SIZE:
        raise ConfigError(
            f"degenerate pants keypoints: left_waist is not left of right_waist "
            f"(waist width {(ru - lu) * 1000:.1f} mm along the garment's right axis)"
        )
    v_top = f.uv(top)[1]
    axis = _line(f, (0.0, 0.0), (0.0, v_top))  # moving side: u < 0, the left leg
    left_end = (k["left_leg_outer"] + k["left_leg_inner"]) / 2
    right_end = (k["right_leg_outer"] + k["right_leg_inner"]) / 2
    # Grasp each leg end a little inside its hem, so the jaws close on cloth.
    inset = STACK_INSET * np.r_[f.up, 0.0]
    s1 = GarmentStage(
        axis,
        (
            _action(k["left_waist"], axis, "left_waist", lift),
            _action(left_end + inset, axis, "left_leg", lift),
        ),
    )
    width = max(f.uv(k[n])[0] for n in ("right_waist", "right_leg_outer"))
    half = _line(f, (width, v_top / 2), (-width, 0.0))  # moving side: v < v_top / 2, the legs
    stack = right_end + inset
    stack[2] = right_end[2] + thickness
    legs = tuple(_action(stack, half, label, lift) for label in ("legs", "legs_rest"))
    s2 = GarmentStage(half, legs, from_tip=True, top_first=True)
    return GarmentPlan("leg_over_leg", (s1, s2))


def plan_garment(
    recipe: str,
    keypoints: dict[str, np.ndarray],
    place_lift: float = 0.004,
    thickness: float = 0.0,
) -> GarmentPlan:
    """Plan every stage of a garment recipe from the keypoints perceived on the flat garment.

    A grasp on a stacked part is planned at the stack's predicted top (`thickness` per layer);
    each place point is its grasp point mirrored across the stage's line, `place_lift` higher."""
    k = _require_keypoints(recipe, keypoints)
    if not (np.isfinite(place_lift) and 0.0 <= place_lift <= 0.05):
        raise ConfigError(f"place_lift must be in [0, 0.05] m, got {place_lift!r}")
    if not (np.isfinite(thickness) and 0.0 <= thickness <= 0.05):
        raise ConfigError(f"thickness must be in [0, 0.05] m, got {thickness!r}")
    if recipe == "retail":
        return _plan_tshirt(k, place_lift, thickness)
    return _plan_pants(k, place_lift, thickness)


def _clip(poly: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Sutherland–Hodgman against one half-plane: the part of a polygon (N×2) where side ≥ 0
    (a concave polygon may come back with zero-width bridges along the line: harmless to fill)."""
    out = []
    n = len(poly)
    for i in range(n):
        p, q = poly[i], poly[(i + 1) % n]
        sp, sq = side[i], side[(i + 1) % n]
        if sp >= 0:
            out.append(p)
        if (sp > 0 > sq) or (sp < 0 < sq):
            out.append(p + (sp / (sp - sq)) * (q - p))
    return np.array(out, dtype=float).reshape(-1, 2)


def fold_outline(parts: list[np.ndarray], line: Line) -> list[np.ndarray]:
    """The top-view outline pieces (each N×2) after folding `parts` along `line`: each piece's
    staying part, plus its moving part mirrored across the line (the plan's predicted shape)."""
    fl = FoldLine(*line)
    out = []
    for poly in parts:
        poly = np.asarray(poly, dtype=float)[:, :2]
        s = fl.side(poly)
        for piece, flip in ((_clip(poly, -s), False), (_clip(poly, s), True)):
            if len(piece) >= 3:
                out.append(fl.reflect_xy(piece) if flip else piece)
    return out
