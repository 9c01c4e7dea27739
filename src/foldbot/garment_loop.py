"""The garment fold loop (T-shirt, pants): plan every fold from the flat garment's perceived
keypoints, then per action grasp where the cloth is now, carry, place and re-observe; verify each
stage against the outline the plan predicts.

A folded garment hides its keypoints, so unlike the towel loop (foldbot.loop), later stages are not
re-planned from new keypoints: their grasp points come from the first observation, and each grasp is
corrected onto the cloth the camera sees now (a point the earlier carries left on bare table moves
to the nearest perceived cloth). A failed grasp is retried (bounded). In a two-arm cell a stage's two
grasps are carried at once, one arm each (garment_pair); a stack carried from its tip, one arm.
Each later stage's grasps, as aimed from the frame it starts from, are pictured (plan_overlays).
Written against `FoldCell`, so the same code drives any cell; it never reads ground truth.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import cv2
import numpy as np

from foldbot.carry import (
    arms_apart,
    carry_pair,
    execute_action,
    execute_as_planned,
    open_loop_entry,
    show_action,
)
from foldbot.cell import FoldCell
from foldbot.errors import FoldbotError, PerceptionError
from foldbot.grasp_points import (
    GRASP_INSET,
    stack_grasp_point,
    surface_height,
    tip_action,
    top_layer_action,
)
from foldbot.loop import (
    FoldRecord,
    LoopConfig,
    actions_overlay,
    corners_of,
    finish_fold,
    require_in_view,
)
from foldbot.perception.layers import laid_layer_mask, mask_points
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState, fold_check_iou, polygon_mask
from foldbot.planning.actions import FoldAction
from foldbot.planning.garment_recipes import (
    GarmentPlan,
    GarmentStage,
    fold_outline,
    recipe_keypoints,
)
from foldbot.types import Observation

RETRY_INSET = 0.015
"""A tip grasp retried after a miss closes this much farther inside the cloth (m) per retry: a
folded tip's outline runs a crease's bulge past its mesh vertices, so the same point misses
again (pants seed 4 in two arms: twice 15 mm from the nearest vertex)."""
_SKIPPED = {
    "grasp_success": True,
    "grasp_reason": "skipped: an earlier carry already moved this part",
    "grasped_vertices": [],
    "max_tracking_error": 0.0,
}


def outline_distance(state: ClothState, point: np.ndarray) -> float:
    """Signed distance (m) in the table plane from `point` to the perceived outline: > 0 inside the
    cloth, < 0 outside (−inf when no cloth is seen)."""
    outline = np.asarray(state.outline_world, dtype=float).reshape(-1, 3)
    if not state.detected or len(outline) < 3:
        return float("-inf")
    contour = outline[:, :2].astype(np.float32).reshape(-1, 1, 2)
    return float(cv2.pointPolygonTest(contour, (float(point[0]), float(point[1])), True))


def snap_to_cloth(
    state: ClothState, point: np.ndarray, radius: float, inset: float = GRASP_INSET
) -> np.ndarray | None:
    """`point` if the perceived cloth covers it; else the nearest outline point within `radius`,
    moved `inset` inside the cloth (same height); None when no cloth lies that near."""
    d = outline_distance(state, point)
    if d >= 0.0:
        return np.asarray(point, dtype=float)
    if -d > radius:
        return None
    outline = np.asarray(state.outline_world, dtype=float).reshape(-1, 3)[:, :2]
    q = outline[int(np.argmin(np.linalg.norm(outline - point[:2], axis=1)))]
    inward = (q - point[:2]) / max(float(np.linalg.norm(q - point[:2])), 1e-9)
    xy = q + inward * inset
    return np.array([xy[0], xy[1], float(point[2])])


def garment_keypoints(state: ClothState, recipe: str) -> dict[str, np.ndarray]:
    """The perceived keypoints `recipe` plans from; PerceptionError naming the missing ones (and
    what was seen instead) when the camera did not recognise the garment."""
    seen = corners_of(state)
    missing = [n for n in recipe_keypoints(recipe) if n not in seen]
    if missing:
        raise PerceptionError(
            f"the garment was not recognised for recipe {recipe!r}: keypoints {missing} were not "
            f"perceived (seen: {sorted(seen) or 'none'})"
        )
    return seen


def predicted_mask(parts: list[np.ndarray], height: float, obs: Observation) -> np.ndarray:
    """The image mask of predicted outline pieces (N×2, table plane) at cloth `height`."""
    mask = np.zeros((obs.intrinsics.height, obs.intrinsics.width), bool)
    for part in parts:
        poly = np.c_[part, np.full(len(part), height)]
        mask |= polygon_mask(poly, obs.intrinsics, obs.T_world_camera)
    return mask


def corrected_grasp(
    cfg: LoopConfig,
    state: ClothState,
    obs: Observation,
    planned: FoldAction,
    action: FoldAction,
    from_tip: bool = False,
    retry: int = 0,
    top: np.ndarray | None = None,
) -> FoldAction:
    """`action` with its grasp moved onto the cloth seen now: onto the perceived cloth in x, y
    (or, `from_tip`, where the cloth left past the line reaches farthest, or with `top`, the
    points of the layer the previous stage laid, where that layer reaches farthest; on the
    `retry`-th retry after a miss RETRY_INSET farther in each time) and onto the perceived surface
    height there (a stack: at the table, under every layer). A planned part with no cloth seen
    near it (an earlier carry dragged it along: a T-shirt's hem corner after its cuff) is carried
    from the tip instead, as what is left of it past the line (tip_action). A retried grasp
    snapped onto the cloth moves RETRY_INSET per retry toward the cloth's centre (inward), as a
    pair's does, rather than closing on the point that just missed."""
    inset = GRASP_INSET + retry * RETRY_INSET
    if from_tip:
        lead = None if top is None else top_layer_action(top, planned, inset)
        action = lead or tip_action(state, planned, inset) or action
    else:
        seen = snap_to_cloth(state, planned.grasp, cfg.regrasp_radius)
        if seen is not None:
            action = inward(state, dataclasses.replace(action, grasp=seen), retry * RETRY_INSET)
        else:
            action = tip_action(state, planned, inset) or action
    top = surface_height(obs, action.grasp, table_plane=state.table_plane)
    if planned.layers == 1 and top is not None:
        action = dataclasses.replace(action, grasp=np.r_[action.grasp[:2], top])
    if planned.layers > 1:
        action = dataclasses.replace(
            action, grasp=stack_grasp_point(state, action.grasp, cfg.stack_grasp_height)
        )
    return action


def inward(state: ClothState, action: FoldAction, distance: float) -> FoldAction:
    """`action` with its grasp moved `distance` (m) in the table plane toward the perceived
    cloth's centre: where a retry aims after the jaws closed on no cloth (a coarse mesh's
    vertices can lie farther in than the perceived edge). A negative `distance` moves it away,
    onto bare table: an injected grasp failure (`cfg.fault_grasp_offset`, tests)."""
    outline = np.asarray(state.outline_world, dtype=float).reshape(-1, 3)
    if not state.detected or len(outline) < 3 or distance == 0.0:
        return action
    to_centre = outline[:, :2].mean(axis=0) - action.grasp[:2]
    step = to_centre / max(float(np.linalg.norm(to_centre)), 1e-9) * distance
    return dataclasses.replace(action, grasp=np.r_[action.grasp[:2] + step, action.grasp[2]])


def already_carried(
    cfg: LoopConfig, state: ClothState, planned: FoldAction, from_tip: bool = False
) -> bool:
    """Whether earlier carries took `planned`'s part along, as the cloth seen now shows: no cloth
    is left past its line, or (a planned grasp, not a from-tip one) none is seen near its grasp
    point while the cloth already covers its place point. Such a part is skipped, and a missed
    grasp on it is not retried."""
    gone = from_tip or snap_to_cloth(state, planned.grasp, cfg.regrasp_radius) is None
    return gone and (
        tip_action(state, planned) is None
        or (not from_tip and outline_distance(state, planned.place) >= 0.0)
    )


def garment_action(
    cfg: LoopConfig,
    cell: FoldCell,
    planned: FoldAction,
    latest: ClothState,
    latest_obs: Observation,
    log: Callable[[str], None] = print,
    from_tip: bool = False,
    top: np.ndarray | None = None,
    inject_fault: bool = False,
) -> tuple[dict, ClothState, Observation]:
    """One pick-and-place with the grasp corrected onto the cloth seen now (x, y onto the
    perceived cloth, height onto the perceived surface there; `top`: see corrected_grasp); a
    failed grasp is re-observed and retried (at most `cfg.retries` times). `inject_fault` aims
    the first attempt `cfg.fault_grasp_offset` off the cloth (inward, outward). Returns the log entry
    and the observation taken after it (state and frame)."""
    t_sim, t_wall = cell.sim_time, time.perf_counter()
    action, retries, attempts, state, obs = planned, 0, [], latest, latest_obs
    gone = from_tip or snap_to_cloth(state, planned.grasp, cfg.regrasp_radius) is None
    if already_carried(cfg, state, planned, from_tip):
        # Earlier carries took this part along: no cloth is left past the line, or none near the
        # grasp point with the cloth already covering the place point.
        log(f"  {planned.label}: already carried; skipped")
        entry = open_loop_entry(planned, _SKIPPED, 0.0, time.perf_counter() - t_wall)
        entry.update(skipped=True)
        return entry, state, obs
    lead = from_tip and top is not None and top_layer_action(top, planned) is not None
    if lead:
        log(f"  {planned.label}: the top layer first, from where it reaches farthest")
    dragged = gone and not from_tip
    if dragged:
        log(f"  {planned.label}: no cloth seen near it; what is left past the line, from its tip")
    given_up = False
    while True:
        # A missed top-layer grasp is retried as the whole stack's tip carry: the miss has moved
        # the layers, so the frame that showed the laid layer no longer shows it.
        lead_now = lead and retries == 0
        action = corrected_grasp(
            cfg, state, obs, planned, action, from_tip, retries, top if lead_now else None
        )
        if inject_fault and not attempts:
            action = inward(state, action, -cfg.fault_grasp_offset)
        cell.use_arm(cell.arm_for(action.grasp))
        show_action(cell, state, action)
        outcome = execute_action(cell, action)
        cell.park()
        state, obs = cell.observe()
        off = None
        if outcome["grasp_success"]:
            off = max(0.0, -outline_distance(state, action.place))
        attempts.append(
            {
                "grasp": [float(v) for v in action.grasp],
                "grasp_success": outcome["grasp_success"],
                "grasp_reason": outcome["grasp_reason"],
                "placed_error_m": off,
            }
        )
        if outcome["grasp_success"] or retries >= cfg.retries:
            break
        if already_carried(cfg, state, planned, from_tip):
            # Nothing seen near the grasp and nothing past the line: a retry would close the jaws
            # where they just closed on nothing.
            log(f"  grasp failed ({outcome['grasp_reason']}); no cloth left to grasp, not retried")
            given_up = True
            break
        retries += 1
        log(f"  grasp failed ({outcome['grasp_reason']}); re-observed, retry {retries}")
    entry = open_loop_entry(action, outcome, cell.sim_time - t_sim, time.perf_counter() - t_wall)
    entry.update(label=planned.label, placed_error_m=attempts[-1]["placed_error_m"])
    entry.update(retries=retries, attempts=attempts, top_layer=bool(lead), dragged=dragged)
    entry.update(nothing_left=given_up)
    if cell.arms > 1:
        entry["arm"] = cell.active_arm
    return entry, state, obs


def garment_pair(
    cfg: LoopConfig,
    cell: FoldCell,
    planned: tuple[FoldAction, ...],
    latest: ClothState,
    latest_obs: Observation,
    log: Callable[[str], None] = print,
    inject_fault: bool = False,
) -> tuple[list[dict], ClothState, Observation]:
    """A stage's two grasps (a side's hem corner and cuff, a leg's waist corner and hem) carried
    at once, one arm each, so the edge between them is folded rather than dragged by one end.

    Each grasp is corrected onto the cloth seen now (corrected_grasp); each arm takes the grasp on
    its side (assign_arms), the other way round when their motions would meet. A failed grasp
    makes both arms let go; the cell re-observes and redoes the pair (at most `cfg.retries`
    times, a missed grasp RETRY_INSET farther toward the cloth's centre each time); a pair
    that still fails, or whose arms would meet either way, is done one arm at a time
    (garment_action). `inject_fault` aims the first grasp's first attempt off the cloth
    (inward, outward)."""

    def aim(
        i: int,
        attempt: int,
        missed: bool,
        state: ClothState,
        obs: Observation | None,
        _previous: FoldAction,
    ) -> FoldAction:
        grasp = corrected_grasp(cfg, state, obs, planned[i], planned[i])
        if inject_fault and attempt == 0 and i == 0:
            return inward(state, grasp, -cfg.fault_grasp_offset)
        return inward(state, grasp, attempt * RETRY_INSET) if missed else grasp

    pair = carry_pair(cell, planned, latest, latest_obs, aim, cfg.retries, log, "them")
    state, obs = pair.state, pair.obs
    entries = []
    if pair.arms_would_meet is not None:
        for k, p in enumerate(planned):
            entry, state, obs = garment_action(
                cfg, cell, p, state, obs, log, inject_fault=inject_fault and k == 0
            )
            entry["arms_would_meet"] = pair.arms_would_meet
            entries.append(entry)
        return entries, state, obs
    for i, p in enumerate(planned):
        action, outcome = pair.actions[i], pair.outcomes[i]
        entry = open_loop_entry(action, outcome, pair.sim_seconds / 2, pair.wall_seconds / 2)
        off = max(0.0, -outline_distance(state, action.place)) if state.detected else None
        entry.update(label=p.label, arm=pair.arms[i], together=True, attempts=pair.attempts)
        entry.update(retries=len(pair.attempts) - 1, placed_error_m=off)
        entries.append(entry)
    if not pair.carried:
        for p in planned:
            log(f"  {p.label} → place, one arm")
            entry, state, obs = garment_action(cfg, cell, p, state, obs, log)
            entry["after_pair_failed"] = True
            entries.append(entry)
    return entries, state, obs


def together(cell: FoldCell, stage: GarmentStage) -> bool:
    """Whether `cell` carries `stage`'s grasps at once: two arms, two grasps far enough apart
    (arms_apart), and not a stack carried from its tip (one layer at a time)."""
    return (
        cell.arms > 1
        and not stage.from_tip
        and len(stage.actions) == 2
        and arms_apart(stage.actions)
    )


def laid_layer(
    cfg: LoopConfig,
    before_state: ClothState,
    before_obs: Observation,
    state: ClothState,
    obs: Observation,
) -> np.ndarray | None:
    """The top surface (N×3 world points) of the layer a stage laid, seen as the surface that rose
    by at least `cfg.relay_min_rise` between the frames before and after it; None when
    `cfg.top_layer_first` is off, a frame shows no cloth, or nothing rose."""
    if not (cfg.top_layer_first and before_state.detected and state.detected):
        return None
    laid = laid_layer_mask(
        before_obs, before_state.table_plane, obs, state.table_plane, cfg.relay_min_rise
    )
    return mask_points(laid, obs) if laid.any() else None


def plan_overlay_all(
    obs: Observation, state: ClothState, plan: GarmentPlan, z: float
) -> np.ndarray:
    """The first observation's overlay: keypoints and the first stage's grasps, places and line."""
    first = plan.stages[0]
    return actions_overlay(obs, state, first.actions, first.fold_line, z)


def aimed_actions(
    cfg: LoopConfig,
    state: ClothState,
    obs: Observation,
    stage: GarmentStage,
    top: np.ndarray | None,
    pair: bool,
) -> list[FoldAction]:
    """`stage`'s actions as the loop first aims them from this frame (corrected_grasp: onto the
    cloth seen now, from the tip, the laid layer first); a stage's later one-arm actions are aimed
    again after each carry, from the frame that carry leaves."""
    if pair:
        return [corrected_grasp(cfg, state, obs, a, a) for a in stage.actions]
    return [
        corrected_grasp(
            cfg, state, obs, a, a, stage.from_tip, 0, top if j == 0 and stage.top_first else None
        )
        for j, a in enumerate(stage.actions)
    ]


def stage_plan_overlay(
    cfg: LoopConfig,
    state: ClothState,
    obs: Observation,
    stage: GarmentStage,
    top: np.ndarray | None,
    pair: bool,
    z: float,
) -> np.ndarray:
    """A later stage's plan over the frame it starts from: its grasps as aimed from that frame
    (aimed_actions; as planned where the frame shows no cloth), their places and the fold line."""
    shown = aimed_actions(cfg, state, obs, stage, top, pair) if state.detected else stage.actions
    return actions_overlay(obs, state, shown, stage.fold_line, z)


def run_garment_fold(
    cfg: LoopConfig,
    cell: FoldCell,
    log: Callable[[str], None] = print,
    settle_s: float = 0.3,
    record: FoldRecord | None = None,
) -> FoldRecord:
    """Fold a garment on `cell` with the recipe `cfg.recipe` (closed loop, or with
    `cfg.closed_loop` False the open-loop baseline: planned grasps, no re-observation); fills
    and returns `record` (a new one if None), as run_fold."""
    rec = FoldRecord() if record is None else record
    cell.park()
    state, obs = cell.observe()
    if not state.detected:
        raise FoldbotError(f"no garment found before folding: {state.reason}")
    if cfg.require_full_view:
        require_in_view(state)
    plan = cell.plan_garment(
        cfg.recipe, garment_keypoints(state, cfg.recipe), cfg.place_lift, cfg.layer_thickness
    )
    height = float(np.median(state.keypoint_array()[:, 2]))
    rec.initial_overlay = plan_overlay_all(obs, state, plan, cell.table_height)
    rec.initial_state = state
    parts = [np.asarray(state.outline_world, dtype=float)[:, :2]]
    top = None  # the layer the previous stage laid (N×3), for a stage whose top layer goes first
    fault = cfg.fault_grasp_offset > 0  # the episode's first grasp is aimed off the cloth
    for i, stage in enumerate(plan.stages):
        rec.fold_lines.append(stage.fold_line)
        before_state, before_obs = state, obs
        if cfg.closed_loop and i > 0:
            rec.plan_overlays.append(
                stage_plan_overlay(
                    cfg, state, obs, stage, top, together(cell, stage), cell.table_height
                )
            )
        if cfg.closed_loop and together(cell, stage):
            log(f"stage {i + 1}: {' and '.join(a.label for a in stage.actions)} together")
            entries, state, obs = garment_pair(
                cfg, cell, stage.actions, state, obs, log, fault and not rec.actions
            )
            rec.actions.extend(entries)
        else:
            for j, planned in enumerate(stage.actions):
                log(f"stage {i + 1}, action {j + 1}/{len(stage.actions)}: {planned.label} → place")
                if cfg.closed_loop:
                    entry, state, obs = garment_action(
                        cfg,
                        cell,
                        planned,
                        state,
                        obs,
                        log,
                        from_tip=stage.from_tip,
                        top=top if j == 0 and stage.top_first else None,
                        inject_fault=fault and not rec.actions,
                    )
                else:
                    cell.use_arm(cell.arm_for(planned.grasp))
                    entry = execute_as_planned(cell, state, planned)
                rec.actions.append(entry)
        parts = fold_outline(parts, stage.fold_line)
        if not cfg.closed_loop:
            rec.stages.append({"stage": i, "fold_line": list(stage.fold_line), "verified": None})
            continue
        cell.park()
        cell.wait(settle_s)
        state, obs = cell.observe()
        iou = (
            fold_check_iou(state.mask, predicted_mask(parts, height, obs))
            if state.detected
            else 0.0
        )
        rec.stages.append(
            {
                "stage": i,
                "fold_line": list(stage.fold_line),
                "mask_iou_vs_predicted": iou,
                "verified": iou >= cfg.verify_iou,
            }
        )
        rec.stage_overlays.append(draw_overlay(obs, state))
        log(f"stage {i + 1} done: mask IoU with the predicted shape {iou:.2f}")
        if i + 1 < len(plan.stages) and plan.stages[i + 1].top_first:
            top = laid_layer(cfg, before_state, before_obs, state, obs)
    return finish_fold(cell, rec)
