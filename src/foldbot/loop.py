"""The closed fold loop — observe → plan a stage → per action: grasp where the corner is now,
carry, place → re-observe → retry or go on → verify the stage — written once against `FoldCell`.

`FoldCell` (`foldbot.cell`) is what the loop needs from a robot cell, in process or over ROS;
`foldbot.carry` moves what the loop decides to carry. The loop sees only observations
(ClothState from images) and the cell's reports; never ground truth.

A cell with two arms (`FoldCell.arms`) carries a stage's two corners at once, one arm each
(`two_arm_actions`, through `carry.carry_pair`, which the garment loop's pairs share);
everything else, and every fallback, runs one arm at a time.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import ConvexHull

from foldbot.carry import (
    arms_apart,
    carry_pair,
    execute_action,
    execute_as_planned,
    line_points,
    show_action,
)
from foldbot.cell import FoldCell
from foldbot.errors import FoldbotError
from foldbot.grasp_points import (
    finish_action,
    inset_grasp,
    inset_toward,
    nearest_keypoint,
    outline_corners,
    place_is_corner,
    regrasp_point,
    stack_grasp_point,
)
from foldbot.perception.keypoints import label_corners, max_area_quad
from foldbot.perception.layers import deepest_gap, laid_corner, laid_layer_mask, layer_cover
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState, fold_check_iou
from foldbot.planning.actions import FoldAction, FoldPlan, edge_middle
from foldbot.planning.recipes import (
    carries_stack,
    predicted_cover,
    predicted_outline,
    recipe_stages,
    takes_crease_room,
)
from foldbot.types import Observation

STACK_EDGE_LAYERS = 2
"""Layers at the middle of the edge of quarter's stack that one arm carries (stack_edge): both
layers' free edges lie there one over the other, and the jaws close at the table, under both
(grasped at the stack's top, 4 of 18 such grasps missed and 2 of 20 folds diverged, against 1)."""
LAY_BACK_OUTWARD = 0.01
"""A corner that slipped is laid back this far (m) beyond where it was grasped, away from the
cloth's centre, so the edge it hung from comes down taut."""
MAX_CLOTH_CREASE_ROOM = 0.02
"""Cap (m) on a crease room taken from the cloth: a laid layer seen rising more than this is
bunched cloth, not one layer (and a coarse mesh's layer thickness can exceed it)."""


@dataclass(frozen=True)
class LoopConfig:
    """The closed loop's decisions (see pipeline.EpisodeConfig for their meaning)."""

    recipe: str = "half"
    retries: int = 1
    """How often a failed grasp or an off placement is redone per action (a grasp that slipped
    in its carry once more besides)."""
    place_tolerance: float = 0.03
    regrasp_radius: float = 0.06
    regrasp_label_radius: float = 0.25
    fault_grasp_offset: float = 0.0
    verify_iou: float = 0.8
    place_lift: float = 0.004
    require_full_view: bool = True
    """Refuse to plan when the cloth's mask touches the image border (vision)."""
    closed_loop: bool = True
    """False: the open-loop baseline (see run_open_loop)."""
    layer_thickness: float = 0.0
    """Height of one cloth layer (m): where the open loop expects a folded stack's corners."""
    stack_grasp_height: float = 0.004
    """A stack (FoldAction.layers > 1) is grasped this high above the perceived table (m)."""
    stack_inset: float = 0.01
    """A stack's corner, or a corner retried after a missed grasp, is grasped this far (m) inside
    the perceived corner, toward the cloth's centre, at the table (stack_grasp_height): a crease is
    rounded, so its cloth lies inside and below the corner the camera sees."""
    finish_actions: int = 1
    """After a stage's planned actions, at most this many extra actions carry cloth still left
    past the fold line (more than MIN_LEFT) over it, from its tip (0 = off)."""
    crease_band: float = 0.02
    """When a stage's laid layer is checked in depth, the band (m) along the fold line where the
    crease bends is left out of the region it should cover."""
    crease_room: float | None = None
    """Room (m) a fold line along the free edge of an earlier stage's laid layer (thirds' second
    stage) leaves that edge, so the crease wraps it instead of pushing the layer back. None: the
    height the previous stage's laid layer rose, seen in depth (about one cloth thickness), or
    `layer_thickness` where depth told nothing and in the open loop."""
    relay_corners: bool = True
    """After the recipe's last stage, when its corners were carried one after another: each corner
    laid before the stage's last carry (which drags it) on a corner of the outline the stage should
    leave is looked for in depth, where the laid layer ends, and one found more than
    `relay_tolerance` off its place is picked there, at the layer's top, and laid again, once
    (relay_laid_corners; docs/experiments.md, Laying a laid corner again)."""
    relay_tolerance: float = 0.008
    """How far (m) a laid corner seen in depth may lie from its place before it is laid again."""
    relay_reach: float = 0.2
    """A laid-layer corner farther than this (m) from the place is not the corner laid there."""
    top_layer_first: bool = True
    """A garment stage that asks for it (GarmentStage.top_first: pants' legs) has its stack's top
    layer, the one the stage before laid, carried first from where that layer reaches farthest
    past the line (seen in depth), then the rest from the tip: carried together, the unheld top
    layer slid off into the crease (docs/experiments.md). False: the whole stack from its tip."""
    relay_min_rise: float = 0.004
    """A pixel whose surface rose at least this much (m) over a stage is cloth the stage laid."""
    relay_side: float = 0.015
    """A laid corner is laid again only when it lies within this (m) of the line through its place
    across the fold line (the side it should end on): a corner that sprang back along its side.
    Off that line the layer's corner is a ridge of bunched cloth, not the corner laid there."""
    relay_stadium: bool = True
    """A relay's carry goes straight up, over a half circle and straight down
    (planning.motion.stadium_arc), in seconds. False: the fold carries' half-sine arc, whose tip
    over a relay's few mm is so tight that the arm crawls along it for up to two minutes
    (docs/experiments.md, A relay that crawls)."""
    pair_descent: float | None = 0.04
    """Where two arms carry a stage's two corners at once (two_arm_actions), their arcs end this
    high (m) over the places and the corners come straight down, slowly: a towel's layer held by
    two corners sags between them, and brought down along the arc the middle of its edge touched
    down short of its place (docs/experiments.md, Coming straight down onto the place). None: as
    one arm carries (MotionConfig.place_height). Garment pairs keep the arc (pants fold worse)."""
    slip_lay_back: bool = True
    """When one arm's first carry of a stage slips: the corner that fell is laid back where it was
    grasped (lay_back_slipped_corner) and the stage is planned again from a fresh observation,
    once per stage. The fall bunches the edge the corner hung from; carried on from where it fell,
    the bunch is folded in (docs/experiments.md, Laying a slipped corner back). False: the corner
    is grasped again where it is seen and carried on."""
    slip_lay_back_lift: float = 0.05
    """How high (m) a slipped corner is lifted as it is laid back (0: the motion's lowest carry
    arc, 5 cm). Lifted 15 cm, it dragged the whole towel 3–5 cm (docs/experiments.md)."""
    stack_edge_carry: bool = True
    """A stage that carries a folded stack (recipes.carries_stack: quarter's second) is one carry
    by one arm, in either cell: its edge grasped once, midway between the two corners, at the
    table under both layers, and that middle laid on the middle of their places
    (planning.actions.edge_middle). False: one arm carries the corners one after the other,
    which drags the stack beneath along, and two arms carry them together where they are far
    enough apart (docs/experiments.md, One arm carries the stack by its edge's middle)."""


@dataclass
class FoldRecord:
    """What a fold did, for the episode's result.json and pictures."""

    fold_lines: list[tuple[float, float, float, float]] = field(default_factory=list)
    actions: list[dict] = field(default_factory=list)
    stages: list[dict] = field(default_factory=list)
    initial_overlay: np.ndarray | None = None
    initial_state: ClothState | None = None
    """What perception saw in the frame the first stage was planned from (for the benchmark's
    first-frame keypoint error)."""
    stage_overlays: list[np.ndarray] = field(default_factory=list)
    """The perception overlay of each closed-loop stage's closing observation."""
    plan_overlays: list[np.ndarray] = field(default_factory=list)
    """From the second closed-loop stage on, each stage's plan (the grasps and places carried, the
    fold line) over the state it was planned from: with the oracle that state has the folded
    outline's corners, not the closing observation's mesh corners (`FoldCell.start_stage`). A
    garment's grasps are shown as aimed from that frame (garment_loop.aimed_actions)."""
    final_state: ClothState | None = None
    final_obs: Observation | None = None


def write_fold_overlays(
    record: FoldRecord, write_image: Callable[[str, np.ndarray], object]
) -> None:
    """Write the record's pictures: overlay_initial.png (with stage 1's plan), overlay_stageK.png
    per stage done, overlay_planK.png per stage K ≥ 2 planned, and overlay_final.png once the
    fold has finished (after an error, those made up to it)."""
    if record.initial_overlay is not None:
        write_image("overlay_initial.png", record.initial_overlay)
    for k, image in enumerate(record.stage_overlays, start=1):
        write_image(f"overlay_stage{k}.png", image)
    for k, image in enumerate(record.plan_overlays, start=2):
        write_image(f"overlay_plan{k}.png", image)
    if record.final_obs is not None and record.final_state is not None:
        write_image("overlay_final.png", draw_overlay(record.final_obs, record.final_state))


def fold_and_picture(
    fold: Callable[..., FoldRecord],
    cfg: LoopConfig,
    cell: FoldCell,
    write_image: Callable[[str, np.ndarray], object],
    log: Callable[[str], None] = print,
) -> FoldRecord:
    """Run `fold` (run_fold or run_garment_fold) on `cell` and write its pictures
    (write_fold_overlays), also when it ends in an error: then those made up to it, and the
    error is raised on."""
    record = FoldRecord()
    try:
        fold(cfg, cell, log, record=record)
    except Exception:
        with contextlib.suppress(Exception):  # the error itself is what must surface
            write_fold_overlays(record, write_image)
        raise
    write_fold_overlays(record, write_image)
    return record


def corners_of(state: ClothState) -> dict[str, np.ndarray]:
    """Perceived keypoint positions by label."""
    return {name: xyz for name, (xyz, _conf) in state.keypoints.items()}


def plan_overlay(
    obs: Observation,
    state: ClothState,
    plan: FoldPlan,
    table_height: float,
    actions: Sequence[FoldAction] | None = None,
) -> np.ndarray:
    """The perception overlay with a stage plan's grasp and place points (of `actions`, the ones
    carried, where they are not the plan's: a stack carried by its edge's middle) and its fold
    line."""
    shown = plan.actions if actions is None else actions
    return actions_overlay(obs, state, shown, plan.fold_lines[0], table_height)


def actions_overlay(
    obs: Observation,
    state: ClothState,
    actions: Sequence[FoldAction],
    fold_line: tuple[float, float, float, float],
    z: float,
    expected_parts: Sequence[np.ndarray] = (),
) -> np.ndarray:
    """The perception overlay with `actions`' grasp and place points and `fold_line` at height
    `z`: the picture of a stage's plan, towel or garment; with `expected_parts` (polygons, each
    N×3, world), the outline the stage was planned on where the frame does not show it (a dry
    run's)."""
    return draw_overlay(
        obs,
        state,
        grasp_points=[a.grasp for a in actions],
        place_points=[a.place for a in actions],
        fold_line=line_points(fold_line, z),
        expected_parts=expected_parts,
    )


def stage_crease_room(cfg: LoopConfig, layer_rise: float | None) -> float:
    """The crease room (m) for the next stage: `cfg.crease_room` if set, else the previous stage's
    laid layer rise seen in depth, else `cfg.layer_thickness`; either at most
    MAX_CLOTH_CREASE_ROOM."""
    if cfg.crease_room is not None:
        return cfg.crease_room
    seen = cfg.layer_thickness if layer_rise is None else layer_rise
    return min(seen, MAX_CLOTH_CREASE_ROOM)


def cut_by_image_edge(state: ClothState) -> bool:
    """Whether the camera sees the cloth only in part: its mask touches the image's border."""
    m = state.mask
    return bool(m.size and (m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any()))


def require_in_view(state: ClothState) -> None:
    """Refuse to plan from a cloth the camera sees only in part (cut_by_image_edge)."""
    if cut_by_image_edge(state):
        raise FoldbotError(
            "the cloth extends beyond the camera's view (its mask touches the image border), "
            "so its corners cannot be seen; use a smaller towel or move the camera"
        )


def run_fold(
    cfg: LoopConfig,
    cell: FoldCell,
    log: Callable[[str], None] = print,
    settle_s: float = 0.3,
    record: FoldRecord | None = None,
) -> FoldRecord:
    """Fold the cloth on `cell` stage by stage in a closed loop (or, with
    `cfg.closed_loop` False, the open-loop baseline); fills and returns `record` (a new one if
    None: a caller holding it keeps the stages done before an error)."""
    rec = FoldRecord() if record is None else record
    cell.park()
    state, obs = cell.observe()
    if not cfg.closed_loop:
        run_open_loop(cfg, cell, state, obs, rec, log)
        return finish_fold(cell, rec)
    layer_rise = None  # how high the previous stage's laid layer rose, seen in depth
    for stage in range(recipe_stages(cfg.recipe)):
        # From stage 2 on, the previous stage's closing observation (arm parked, cloth
        # settled) is where this stage starts, unless the cell asks for a fresh one.
        if stage > 0 and cell.start_stage(stage):
            state, obs = cell.observe()
        planned_again = False
        while True:
            if not state.detected:
                raise FoldbotError(f"no cloth found before fold stage {stage + 1}: {state.reason}")
            if cfg.require_full_view:
                require_in_view(state)
            latest, stage_state, stage_obs = state, state, obs
            corners = corners_of(state)
            room = stage_crease_room(cfg, layer_rise)
            plan, predicted = cell.plan_stage(cfg.recipe, stage, corners, cfg.place_lift, room)
            if not planned_again:
                # The goal stays the one planned before the first action (metrics.md); a stage
                # planned again records its own line in its stage entry.
                rec.fold_lines.append(plan.fold_lines[0])
            if stage == 0 and not planned_again:
                rec.initial_overlay = plan_overlay(obs, state, plan, cell.table_height)
                rec.initial_state = state
            corner_places = outline_corners(np.asarray(predicted, dtype=float).reshape(-1, 3))
            carries = stage_carries(cfg, cell, stage, plan)
            carried, together, edge_of = carries.actions, carries.together, carries.edge_of
            if stage > 0 and not planned_again:
                rec.plan_overlays.append(plan_overlay(obs, state, plan, cell.table_height, carried))
            slipped_first = False
            if together:
                log(f"stage {stage + 1}: {' and '.join(a.label for a in plan.actions)} together")
                entries, latest = two_arm_actions(
                    cfg,
                    cell,
                    plan.actions,
                    latest,
                    log,
                    inject_fault=cfg.fault_grasp_offset > 0 and not rec.actions,
                    predicted_corners=corner_places,
                    re_place=not carries_stack(cfg.recipe, stage),
                )
                rec.actions.extend(entries)
            else:
                for i, planned in enumerate(carried):
                    log(
                        f"stage {stage + 1}, action {i + 1}/{len(carried)}: {planned.label} → place"
                    )
                    entry, latest = single_arm_action(
                        cfg,
                        cell,
                        planned,
                        latest,
                        log,
                        inject_fault=cfg.fault_grasp_offset > 0 and not rec.actions,
                        predicted_corners=corner_places,
                        edge_of=edge_of,
                        lay_back_slip=cfg.slip_lay_back and i == 0 and not planned_again,
                    )
                    rec.actions.append(entry)
                    if entry.get("plan_again"):
                        slipped_first = True
                        break
            if slipped_first:
                # The stage's first carry slipped and its corner was laid back: plan the stage
                # again from where the cloth lies now (once).
                log(f"stage {stage + 1}: planned again from a fresh observation")
                planned_again = True
                cell.park()
                cell.wait(settle_s)
                state, obs = cell.observe()
                continue
            break
        cell.park()
        cell.wait(settle_s)
        state, obs = cell.observe()
        for _ in range(cfg.finish_actions):
            extra = finish_action(state, obs, carried[-1])
            if extra is None:
                break
            log(f"stage {stage + 1}: cloth left past the fold line; carrying it over from its tip")
            cell.use_arm(cell.arm_for(extra.grasp))
            entry = execute_as_planned(cell, state, extra)
            entry.update(kind="finish_stage")
            if cell.arms > 1:
                entry["arm"] = cell.active_arm
            rec.actions.append(entry)
            cell.park()
            cell.wait(settle_s)
            state, obs = cell.observe()
        if cfg.relay_corners and stage == recipe_stages(cfg.recipe) - 1 and not together:
            # The stage's later carries drag the corners laid before them (one at a time).
            state, obs, relays = relay_laid_corners(
                cfg, cell, carried[:-1], corner_places, (stage_state, stage_obs),
                (state, obs), log, settle_s,
            )  # fmt: skip
            rec.actions.extend(relays)
        cover = predicted_cover(cfg.recipe, stage, corners, cfg.crease_band, room)
        laid = (
            layer_cover(stage_obs, stage_state.table_plane, obs, state.table_plane, cover)
            if len(cover) >= 3 and state.detected and stage_state.detected
            else None
        )
        gap = deepest_gap(laid, obs)
        iou = (
            fold_check_iou(state.mask, predicted, obs.intrinsics, obs.T_world_camera)
            if state.detected
            else 0.0
        )
        rec.stages.append(
            {
                "stage": stage,
                "fold_line": list(plan.fold_lines[0]),
                "predicted_outline": np.asarray(predicted).tolist(),
                "mask_iou_vs_predicted": iou,
                "verified": iou >= cfg.verify_iou,
                # Seen in depth: how high the laid layer rose, and how far into the region it
                # should cover it left a gap (0: none; None: the region told nothing).
                "laid_layer_rise_m": None if laid is None else laid.layer_rise,
                "laid_layer_gap_m": None if laid is None else (0.0 if gap is None else gap.depth),
                # The room the fold line left an earlier layer's free edge (None: no such edge).
                "crease_room_m": room if takes_crease_room(cfg.recipe, stage) else None,
            }
        )
        layer_rise = None if laid is None else laid.layer_rise
        rec.stage_overlays.append(
            draw_overlay(obs, state, uncovered=None if laid is None else laid.exposed)
        )
        seen_gap = ""
        if laid is not None:
            depth_mm = 0.0 if gap is None else gap.depth * 1000
            seen_gap = f"; in depth, the laid layer left a gap {depth_mm:.0f} mm deep"
        log(f"stage {stage + 1} done: mask IoU with the predicted shape {iou:.2f}{seen_gap}")
    return finish_fold(cell, rec)


@dataclass(frozen=True)
class StageCarries:
    """What the closed loop carries in a stage, decided from its plan before anything moves: the
    actions (the plan's corners, or one by a folded stack's edge middle), whether two arms carry
    them together, and the two corners an edge middle is aimed between (None: corners)."""

    actions: tuple[FoldAction, ...]
    together: bool
    edge_of: tuple[FoldAction, FoldAction] | None


def stage_carries(cfg: LoopConfig, cell: FoldCell, stage: int, plan: FoldPlan) -> StageCarries:
    """How the closed loop carries stage `stage`'s `plan` (the fold and the dry run alike): a
    folded stack by its edge's middle, one arm, in either cell (stack_edge); else a two-arm cell
    carries a stage's two corners together where two grippers fit at both ends (arms_apart);
    everything else one arm at a time."""
    edge_of = stack_edge(cfg, stage, plan.actions)
    if edge_of is not None:
        return StageCarries((edge_middle(edge_of, STACK_EDGE_LAYERS),), False, edge_of)
    together = cell.arms > 1 and len(plan.actions) == 2 and arms_apart(plan.actions)
    return StageCarries(tuple(plan.actions), together, None)


def first_aim(
    cfg: LoopConfig, state: ClothState, action: FoldAction, centre: np.ndarray
) -> FoldAction:
    """`action` as the closed loop's first try aims it where no newer frame shows its corner (a
    dry run's later stages): a stack's grasp (more than one layer) at the table under every
    layer, `cfg.stack_inset` toward `centre` (x, y: the stack's predicted middle), as aim_grasp
    has it; a single layer's as planned."""
    if action.layers <= 1:
        return action
    corner = np.asarray(action.grasp, dtype=float)
    lowered = dataclasses.replace(
        action, grasp=stack_grasp_point(state, corner, cfg.stack_grasp_height)
    )
    return inset_toward(lowered, corner, np.asarray(centre, dtype=float), cfg.stack_inset)


def stack_edge(
    cfg: LoopConfig, stage: int, actions: Sequence[FoldAction]
) -> tuple[FoldAction, FoldAction] | None:
    """The two corners a stage carries by their edge's middle, one arm (cfg.stack_edge_carry: a
    folded stack's, recipes.carries_stack), or None: they are carried as corners."""
    if cfg.stack_edge_carry and carries_stack(cfg.recipe, stage) and len(actions) == 2:
        return (actions[0], actions[1])
    return None


def relay_laid_corners(
    cfg: LoopConfig,
    cell: FoldCell,
    actions: Sequence[FoldAction],
    predicted_corners: np.ndarray,
    before: tuple[ClothState, Observation],
    after: tuple[ClothState, Observation],
    log: Callable[[str], None] = print,
    settle_s: float = 0.3,
) -> tuple[ClothState, Observation, list[dict]]:
    """After a stage (arm parked, cloth settled): each corner the stage laid on a corner of the
    outline it should leave that relay_action finds off its place is picked where the laid layer
    ends and laid on its place again, once, re-observing after each. Returns the newest state and
    observation and the relays' result.json entries (kind "relay_corner"). `before`: the stage's
    first observation; `after`: the newest, taken once the stage ended."""
    state, obs = after
    entries: list[dict] = []
    for planned in actions:
        if not place_is_corner(planned.place, predicted_corners):
            continue
        action, why = relay_action(cfg, planned, before, (state, obs))
        if action is None:
            if why:
                log(f"  {planned.label}: {why}")
            continue
        log(f"  {planned.label}: {why}; laying it again")
        cell.use_arm(cell.arm_for(action.grasp))
        entry = execute_as_planned(cell, state, action)
        entry.update(kind="relay_corner", reason=why)
        if cell.arms > 1:
            entry["arm"] = cell.active_arm
        entries.append(entry)
        cell.park()
        cell.wait(settle_s)
        state, obs = cell.observe()
    return state, obs, entries


def relay_action(
    cfg: LoopConfig,
    planned: FoldAction,
    before: tuple[ClothState, Observation],
    after: tuple[ClothState, Observation],
) -> tuple[FoldAction | None, str]:
    """Whether the corner `planned` laid must be laid again, from the stage's first and newest
    observations: the layer the stage laid is the surface that rose over it, seen in depth (the
    outline cannot show it: the layer beneath keeps the outline), and its corner nearest the place
    is where the laid corner lies. The action picks it there, at the layer's top, and lays it on
    the place, when it lies more than `cfg.relay_tolerance` off, along its side (within
    `cfg.relay_side` of the line through the place across the fold line: a corner that sprang
    back); off that side the layer's corner is a ridge of bunched cloth, and it is left. Returns
    the action, or None, and why."""
    (before_state, before_obs), (state, obs) = before, after
    if not (state.detected and before_state.detected):
        return None, ""
    laid = laid_layer_mask(
        before_obs, before_state.table_plane, obs, state.table_plane, cfg.relay_min_rise
    )
    seen = laid_corner(laid, obs, planned.place)
    if seen is None:
        return None, "no laid layer seen in depth"
    corner = seen.corner
    off = float(np.linalg.norm(corner[:2] - planned.place[:2]))
    if off <= cfg.relay_tolerance:
        return None, ""
    if off > cfg.relay_reach:
        return None, f"the laid layer's nearest corner is {off * 1000:.0f} mm away: not this one"
    aside = side_offset(planned, corner)
    if aside > cfg.relay_side:
        return None, (
            f"the laid layer's corner nearest its place lies {aside * 1000:.0f} mm off the side "
            "it should end on (bunched cloth); left as it is"
        )
    action = FoldAction(
        grasp=seen.grasp,
        place=planned.place,
        fold_line=planned.fold_line,
        label=f"relay_{planned.label}",
        carry="stadium" if cfg.relay_stadium else "arc",
    )
    return action, f"laid {off * 1000:.0f} mm off its place, seen in depth"


def side_offset(planned: FoldAction, point: np.ndarray) -> float:
    """How far (m, in the table plane) `point` lies from the line through `planned`'s place point
    across its fold line: the side a corner laid there runs along toward the crease."""
    dx, dy = planned.fold_line[2:]
    along = np.array([dx, dy]) / np.hypot(dx, dy)
    return float(abs(along @ (np.asarray(point)[:2] - np.asarray(planned.place)[:2])))


def finish_fold(cell: FoldCell, rec: FoldRecord) -> FoldRecord:
    """Clear the planned marks from the overlay, park, let the cloth rest and take the closing
    observation."""
    cell.show()
    cell.park()
    cell.wait(0.5)
    rec.final_state, rec.final_obs = cell.observe()
    return rec


def plan_from_first_view(
    cfg: LoopConfig, cell: FoldCell, state: ClothState, rec: FoldRecord | None = None
) -> list[tuple[FoldPlan, dict[str, np.ndarray]]]:
    """Every stage's plan from one observation's state, as the open loop plans them, each with
    the corners it was planned on (label → x, y, z): a later stage on the corners of the outline
    the plan before predicts, one layer higher. Each stage planned is entered in `rec` where
    given (its fold line), also when a later one fails."""
    if not state.detected:
        raise FoldbotError(f"no cloth found before fold stage 1: {state.reason}")
    if cfg.require_full_view:
        require_in_view(state)
    corners, plans, room = corners_of(state), [], stage_crease_room(cfg, None)
    for stage in range(recipe_stages(cfg.recipe)):
        if stage > 0:
            outline = predicted_outline(cfg.recipe, stage - 1, corners, room)
            if len(outline) > 4:  # an overhang of the mirrored part: its 4 dominant corners
                hull = outline[ConvexHull(outline[:, :2]).vertices]
                outline = hull[max_area_quad(hull[:, :2])]
            if len(outline) != 4:
                raise FoldbotError(
                    f"open loop: the outline predicted after stage {stage} has {len(outline)} "
                    "corners, 4 are needed to plan the next stage"
                )
            labels = label_corners(outline)
            corners = {n: outline[i] + [0.0, 0.0, cfg.layer_thickness] for n, i in labels.items()}
        plan, _predicted = cell.plan_stage(cfg.recipe, stage, corners, cfg.place_lift, room)
        plans.append((plan, corners))
        if rec is not None:
            entry = {"stage": stage, "fold_line": list(plan.fold_lines[0]), "verified": None}
            rec.stages.append(entry)
            rec.fold_lines.append(plan.fold_lines[0])
    return plans


def run_open_loop(
    cfg: LoopConfig,
    cell: FoldCell,
    state: ClothState,
    obs: Observation,
    rec: FoldRecord,
    log: Callable[[str], None] = print,
) -> None:
    """Open loop (the comparison baseline): plan every stage from the first observation — a later
    stage on the corners of the outline the plan predicts, one layer higher — then execute all
    actions back to back: no re-observation, regrasp, retry or stage verification."""
    plans = [plan for plan, _corners in plan_from_first_view(cfg, cell, state, rec)]
    rec.initial_overlay = plan_overlay(obs, state, plans[0], cell.table_height)
    rec.initial_state = state
    for plan in plans:
        for action in plan.actions:
            log(f"open loop: {action.label} → place")
            cell.use_arm(cell.arm_for(action.grasp))
            rec.actions.append(execute_as_planned(cell, state, action))


def corner_to_grasp(
    cfg: LoopConfig, state: ClothState, label: str, action: FoldAction, replacing: bool
) -> np.ndarray | None:
    """Where the corner that `action` grasps is now (None: not seen): a corner to carry is found by
    its label or position and checked against the moving side's tip (regrasp_point); a corner
    `replacing` (placed off, to be picked where it was seen to lie) only by position, since after a
    fold the detector's labels for the new outline's corners need not match the plan's."""
    if replacing:
        return nearest_keypoint(state, action.grasp, cfg.regrasp_radius)
    return regrasp_point(
        state,
        label,
        action.grasp,
        cfg.regrasp_radius,
        cfg.regrasp_label_radius,
        line=action.fold_line,
    )


def closed_loop_action(
    cfg: LoopConfig,
    cell: FoldCell,
    planned: FoldAction,
    latest: ClothState,
    log: Callable[[str], None] = print,
    inject_fault: bool = False,
    predicted_corners: np.ndarray | None = None,
    replacing: bool = False,
    edge_of: tuple[FoldAction, FoldAction] | None = None,
    lay_back_slip: bool = False,
) -> tuple[dict, ClothState]:
    """Execute one pick-and-place, re-observing to grasp the corner where it now is, and
    verifying the placement; a failed grasp or an off placement is redone (bounded). With
    `replacing`, `planned` re-places a corner that was placed off: its grasp is where it was seen.
    With `edge_of`, `planned` carries the middle of those two corners' edge (edge_middle): it is
    grasped midway between where the two are seen. With `lay_back_slip`, a carry that slips ends
    the action: the corner is laid back (lay_back_slipped_corner) and the entry says
    `plan_again`, for the caller to plan the stage again from `state`.

    `latest` is the state of the newest observation (taken after the cloth last moved);
    `predicted_corners` are the corners of the outline the stage should leave: a placement is
    verified only where it should make one of them (see place_is_corner)."""
    check_place = place_is_corner(planned.place, predicted_corners)
    t_sim, t_wall = cell.sim_time, time.perf_counter()
    action, outcome, retries, attempts = planned, {}, 0, []
    state = latest
    while True:
        # Earlier actions move the cloth: grasp the corner where it is now. A corner placed off
        # is picked where it was seen to lie: after a fold, the labels that the corner detector
        # gives the new outline's corners need not match the plan's.
        # After a grasp that closed on no cloth the jaws close at the table inside the corner
        # (aim_grasp); after one that slipped, at the corner where it is now seen, as a first
        # grasp (at the table the jaws take the fallen flap by its fold, and lay it folded).
        last_failed = (
            bool(attempts)
            and not attempts[-1]["grasp_success"]
            and not attempts[-1].get("slipped", False)
        )
        action = aim_grasp(
            cfg,
            state,
            planned,
            action,
            replacing=replacing,
            at_table=last_failed or (planned.layers > 1 and not attempts),
            inject_fault=inject_fault and not attempts,
            edge_of=edge_of,
        )
        show_action(cell, state, action)
        outcome = execute_action(cell, action)
        placed_error = None
        cell.park()
        state, _obs = cell.observe()
        if outcome["grasp_success"] and check_place:
            seen = nearest_keypoint(state, action.place, 2 * cfg.regrasp_radius)
            placed_error = (
                None if seen is None else float(np.linalg.norm(seen[:2] - action.place[:2]))
            )
        ok = outcome["grasp_success"] and (
            placed_error is None or placed_error <= cfg.place_tolerance
        )
        attempts.append(
            {
                "grasp": [float(v) for v in action.grasp],
                "grasp_success": outcome["grasp_success"],
                "grasp_reason": outcome["grasp_reason"],
                "placed_error_m": placed_error,
                **({"slipped": True} if outcome.get("slipped") else {}),
            }
        )
        if outcome.get("slipped") and lay_back_slip:
            log(f"  grasp failed ({outcome['grasp_reason']}); laying the corner back")
            attempts[-1]["laid_back"] = lay_back_slipped_corner(
                cfg, cell, state, planned.label, action.grasp
            )
            cell.park()
            state, _obs = cell.observe()
            break
        # The first slip is retried beyond the budget: the grasp had found the cloth.
        slips = any(a.get("slipped", False) for a in attempts)
        if ok or retries >= cfg.retries + int(slips):
            break
        retries += 1
        replacing = bool(outcome["grasp_success"])
        if replacing:
            # Off placement: pick the misplaced corner where it lies and place it again.
            log(f"  placed {placed_error * 1000:.0f} mm off; re-grasping, retry {retries}")
            action = dataclasses.replace(action, grasp=seen)
        else:
            log(f"  grasp failed ({outcome['grasp_reason']}); re-observed, retry {retries}")
    return {
        "kind": "pick_and_place",
        "label": planned.label,
        "grasp": [float(v) for v in action.grasp],
        "place": [float(v) for v in action.place],
        "grasp_success": outcome["grasp_success"],
        "grasp_reason": outcome["grasp_reason"],
        "grasped_vertices": outcome["grasped_vertices"],
        "placed_error_m": attempts[-1]["placed_error_m"],
        "retries": retries,
        "attempts": attempts,
        "max_tracking_error_m": outcome["max_tracking_error"],
        "sim_seconds": cell.sim_time - t_sim,
        "wall_seconds": time.perf_counter() - t_wall,
        **({"plan_again": True} if "laid_back" in attempts[-1] else {}),
    }, state


def lay_back_slipped_corner(
    cfg: LoopConfig, cell: FoldCell, state: ClothState, label: str, was_at: np.ndarray
) -> dict:
    """Lay the corner `label`, which slipped from the jaws, back where it was grasped (`was_at`),
    LAY_BACK_OUTWARD beyond. The fall bunches the edge the corner hung from; carried on from
    where it fell, the bunch is folded in. The corner is looked for by its label near `was_at`
    (else the keypoint nearest it), grasped at the table `cfg.stack_inset` inside it as after a
    missed grasp (it may lie on a fold of its own edge), lifted `cfg.slip_lay_back_lift` straight
    up, and laid down (a stadium carry); the grasped point is released so that the corner lands
    on its place (shifted_grasp), i.e. with the default inset about where it lay before the carry.
    Returns what was done, for the attempt's record."""
    was_at = np.asarray(was_at, dtype=float)
    seen = regrasp_point(state, label, was_at, cfg.regrasp_radius, cfg.regrasp_label_radius)
    if seen is None:
        return {
            "grasp_success": False,
            "grasp_reason": f"corner {label} not seen (by its label within "
            f"{cfg.regrasp_label_radius} m, or any corner within {cfg.regrasp_radius} m) near "
            "where it was grasped; left where it fell",
        }
    outward = was_at[:2] - state.keypoint_array()[:, :2].mean(axis=0)
    outward = outward / max(float(np.linalg.norm(outward)), 1e-9)
    place = np.array([*(was_at[:2] + outward * LAY_BACK_OUTWARD), was_at[2] + cfg.place_lift])
    action = FoldAction(
        grasp=stack_grasp_point(state, seen, cfg.stack_grasp_height),
        place=place,
        fold_line=(float(seen[0]), float(seen[1]), float(outward[0]), float(outward[1])),
        label=f"lay back {label}",
        carry="stadium",
        lift=cfg.slip_lay_back_lift or None,
    )
    action = inset_grasp(state, action, seen, cfg.stack_inset)
    show_action(cell, state, action)
    outcome = execute_action(cell, action)
    return {
        "grasp": [float(v) for v in action.grasp],
        "place": [float(v) for v in action.place],
        "grasp_success": outcome["grasp_success"],
        "grasp_reason": outcome["grasp_reason"],
    }


def aim_grasp(
    cfg: LoopConfig,
    state: ClothState,
    planned: FoldAction,
    action: FoldAction,
    replacing: bool,
    at_table: bool,
    inject_fault: bool,
    edge_of: tuple[FoldAction, FoldAction] | None = None,
) -> FoldAction:
    """`action` aimed at the corner `planned` grasps as the newest observation `state` shows it
    (corner_to_grasp). With `at_table` (a stack, or a corner the jaws just missed: a crease's
    cloth lies below and inside the corner the camera sees, so the same grasp again would miss
    again) the jaws close at the table, a little inside the perceived corner, under every layer
    there. `inject_fault` aims it `cfg.fault_grasp_offset` outward, onto bare table. With
    `edge_of` (an edge's middle) it is aimed midway between where those two corners are seen,
    and left as it is where either is not seen."""
    if edge_of is not None and not replacing:
        ends = [corner_to_grasp(cfg, state, a.label, a, False) for a in edge_of]
        seen = None if any(e is None for e in ends) else (ends[0] + ends[1]) / 2
    else:
        seen = corner_to_grasp(cfg, state, planned.label, action, replacing)
    if seen is not None:
        action = dataclasses.replace(action, grasp=seen)
    if at_table:
        corner = action.grasp
        action = dataclasses.replace(
            action,
            grasp=stack_grasp_point(state, action.grasp, cfg.stack_grasp_height),
            place=planned.place,
        )
        action = inset_grasp(state, action, corner, cfg.stack_inset)
    if inject_fault:
        outward = action.grasp[:2] - state.keypoint_array().mean(axis=0)[:2]
        outward = outward / max(np.linalg.norm(outward), 1e-9) * cfg.fault_grasp_offset
        action = dataclasses.replace(action, grasp=action.grasp + [*outward, 0.0])
    return action


def single_arm_action(
    cfg: LoopConfig,
    cell: FoldCell,
    planned: FoldAction,
    latest: ClothState,
    log: Callable[[str], None] = print,
    **kwargs: Any,
) -> tuple[dict, ClothState]:
    """closed_loop_action with the arm on the grasp's side of the cell (a two-arm cell records
    which in the entry's `arm`)."""
    arm = cell.arm_for(planned.grasp)
    cell.use_arm(arm)
    entry, state = closed_loop_action(cfg, cell, planned, latest, log, **kwargs)
    if cell.arms > 1:
        entry["arm"] = cell.active_arm
    return entry, state


def two_arm_actions(
    cfg: LoopConfig,
    cell: FoldCell,
    planned: tuple[FoldAction, ...],
    latest: ClothState,
    log: Callable[[str], None] = print,
    inject_fault: bool = False,
    predicted_corners: np.ndarray | None = None,
    re_place: bool = True,
) -> tuple[list[dict], ClothState]:
    """A stage's two corners carried at once, one arm each, so neither drags the other.

    Each arm takes the corner on its side (assign_arms); when the arms' planned motions would
    bring them too close, the other way round, and failing that the corners are carried one arm
    at a time. Each corner is grasped where it is seen now; when a grasp fails, both arms let go, the cell
    re-observes and the pair is redone (the failed corner at the table, inside the corner seen,
    as closed_loop_action retries it), at most `cfg.retries` times. A pair that still fails is
    done one arm at a time (closed_loop_action). Afterwards each placement that should make a
    corner is checked, and with `re_place` a corner placed off is re-placed by the arm on its side
    (not for a folded stack: one arm laying a stack's corner again dragged the stack or blew it
    up, docs/experiments.md)."""

    def aim(
        i: int,
        attempt: int,
        missed: bool,
        state: ClothState,
        _obs: Observation | None,
        previous: FoldAction,
    ) -> FoldAction:
        action = aim_grasp(
            cfg,
            state,
            planned[i],
            previous,
            replacing=False,
            at_table=missed or (planned[i].layers > 1 and attempt == 0),
            inject_fault=inject_fault and attempt == 0 and i == 0,
        )
        if cfg.pair_descent is None:
            return action
        return dataclasses.replace(action, descent=cfg.pair_descent)

    pair = carry_pair(cell, planned, latest, None, aim, cfg.retries, log, "the corners")
    state, actions, outcomes, arms = pair.state, pair.actions, pair.outcomes, pair.arms
    if pair.arms_would_meet is not None:
        entries = []
        for plan_i in planned:
            entry, state = single_arm_action(
                cfg, cell, plan_i, state, log, predicted_corners=predicted_corners
            )
            entry["arms_would_meet"] = pair.arms_would_meet
            entries.append(entry)
        return entries, state
    entries = []
    for i, plan_i in enumerate(planned):
        entry = {
            "kind": "pick_and_place",
            "label": plan_i.label,
            "arm": arms[i],
            "together": True,
            "grasp": [float(v) for v in actions[i].grasp],
            "place": [float(v) for v in actions[i].place],
            "descent_m": actions[i].descent,
            "grasp_success": outcomes[i]["grasp_success"],
            "grasp_reason": outcomes[i]["grasp_reason"],
            "grasped_vertices": outcomes[i]["grasped_vertices"],
            "placed_error_m": None,
            "retries": len(pair.attempts) - 1,
            "attempts": pair.attempts,
            "max_tracking_error_m": outcomes[i]["max_tracking_error"],
            # The pair's time, shared: both entries ran over the same seconds.
            "sim_seconds": pair.sim_seconds / len(planned),
            "wall_seconds": pair.wall_seconds / len(planned),
        }
        entries.append(entry)
    if not pair.carried:
        for plan_i in planned:
            log(f"  {plan_i.label} → place, one arm")
            entry, state = single_arm_action(
                cfg, cell, plan_i, state, log, predicted_corners=predicted_corners
            )
            entry["after_pair_failed"] = True
            entries.append(entry)
        return entries, state
    for i, plan_i in enumerate(planned):
        if not place_is_corner(plan_i.place, predicted_corners):
            continue
        seen = nearest_keypoint(state, actions[i].place, 2 * cfg.regrasp_radius)
        if seen is None:
            continue
        error = float(np.linalg.norm(seen[:2] - actions[i].place[:2]))
        entries[i]["placed_error_m"] = error
        if error <= cfg.place_tolerance or cfg.retries < 1:
            continue
        if not re_place:
            log(f"  {plan_i.label} placed {error * 1000:.0f} mm off; a folded stack: left there")
            entries[i]["re_place_skipped"] = "stack"
            continue
        log(f"  {plan_i.label} placed {error * 1000:.0f} mm off; re-placing it with one arm")
        redo = dataclasses.replace(plan_i, grasp=seen)
        entry, state = single_arm_action(
            cfg, cell, redo, state, log, predicted_corners=predicted_corners, replacing=True
        )
        entry["kind"] = "re_place"
        entries.append(entry)
    return entries, state
