"""Carrying on a cell: one arm's pick-and-place, and two arms' pair carried at once with its
retries, each planned whole (IK on every waypoint, the arms kept apart) before anything moves.

The loops (`loop`, `garment_loop`, `flatten`) decide what to carry and where; this module moves
it and reports what the grippers held.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from foldbot.cell import FoldCell
from foldbot.errors import ArmsWouldCollideError, FoldbotError, UnreachableTargetError
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.planning.spread import SpreadAction
from foldbot.types import GraspResult, Observation

MIN_ARM_SEPARATION = 0.12
"""A two-arm cell carries a stage's two corners together only when both their grasp points and
both their place points lie at least this far apart (m); closer, the grippers would meet, and the
corners are carried one after the other."""


def line_points(line: tuple[float, float, float, float], z: float) -> np.ndarray:
    """The fold line's segment across the cloth as two world points, for drawing."""
    x, y, dx, dy = line
    return np.array([[x, y, z], [x + dx, y + dy, z]])


def show_action(cell: FoldCell, state: ClothState, action: FoldAction) -> None:
    """The video's overlay while an action runs: its grasp and place points and fold line."""
    cell.show(
        state,
        grasp_points=[action.grasp],
        place_points=[action.place],
        fold_line=line_points(action.fold_line, cell.table_height),
    )


def execute_action(cell: FoldCell, action: FoldAction) -> dict:
    """Plan the whole pick-and-place (IK on every waypoint), then run it; after a failed grasp,
    open, lift and stop."""
    try:
        steps = cell.plan_action(action)
    except UnreachableTargetError as exc:
        raise UnreachableTargetError(
            f"action '{action.label}' is infeasible (nothing moved): {exc}"
        ) from exc
    cell.confirm_motion([(cell.active_arm, action, steps)])
    grasp_result, max_err, slipped = None, 0.0, False
    for step in steps:
        step_log = cell.run_step(step)
        max_err = max(max_err, step_log.max_tracking_error)
        if step_log.grasp is not None:
            # A failed grasp after one that held: the cloth slipped from the jaws (the cell's
            # gripper reports it lost its hold).
            slipped = bool(grasp_result and grasp_result.success and not step_log.grasp.success)
            grasp_result = step_log.grasp
            if not grasp_result.success:
                cell.release_and_lift()
                break
    ok = bool(grasp_result and grasp_result.success)
    return {
        "grasp_success": ok,
        "grasp_reason": grasp_result.reason if grasp_result else "no grasp attempted",
        "grasped_vertices": list(grasp_result.vertex_ids) if grasp_result else [],
        "max_tracking_error": max_err,
        "slipped": slipped,
    }


def execute_as_planned(cell: FoldCell, state: ClothState, action: FoldAction) -> dict:
    """Show and run one action as planned (no re-observation or retry); its result.json entry."""
    t_sim, t_wall = cell.sim_time, time.perf_counter()
    show_action(cell, state, action)
    outcome = execute_action(cell, action)
    return open_loop_entry(action, outcome, cell.sim_time - t_sim, time.perf_counter() - t_wall)


def open_loop_entry(action: FoldAction, outcome: dict, sim_s: float, wall_s: float) -> dict:
    """result.json's entry for an action executed as planned (no re-observation or retry)."""
    return {
        **action.as_dict(),
        "kind": "pick_and_place",
        "grasp_success": outcome["grasp_success"],
        "grasp_reason": outcome["grasp_reason"],
        "grasped_vertices": outcome["grasped_vertices"],
        "placed_error_m": None,
        "retries": 0,
        "attempts": [],
        "max_tracking_error_m": outcome["max_tracking_error"],
        "sim_seconds": sim_s,
        "wall_seconds": wall_s,
    }


# --- two arms ------------------------------------------------------------------------------------


def arms_apart(actions: tuple[FoldAction, ...]) -> bool:
    """Whether two actions' grasp points and place points are far enough apart for two grippers
    to work them at once (MIN_ARM_SEPARATION)."""
    a, b = actions
    return bool(
        np.linalg.norm(a.grasp[:2] - b.grasp[:2]) >= MIN_ARM_SEPARATION
        and np.linalg.norm(a.place[:2] - b.place[:2]) >= MIN_ARM_SEPARATION
    )


def nearest_arm(point: np.ndarray, bases_y: tuple[float, ...]) -> int:
    """The arm whose base is nearest `point` along y: the one on its side of the cell."""
    return int(np.argmin([abs(float(point[1]) - by) for by in bases_y]))


def assign_arms(arm_for: Callable[[np.ndarray], int], actions: tuple[FoldAction, ...]) -> list[int]:
    """One arm per action, each on its grasp's side (`arm_for`); if both grasps fall on one arm's
    side, the grasp further along +y goes to arm 0 (the left arm)."""
    arms = [arm_for(a.grasp) for a in actions]
    if len(set(arms)) == len(arms):
        return arms
    left_first = sorted(range(len(actions)), key=lambda i: -float(actions[i].grasp[1]))
    out = [0] * len(actions)
    for arm, i in enumerate(left_first):
        out[i] = arm
    return out


def execute_together(cell: FoldCell, pairs: list[tuple[int, FoldAction]]) -> list[dict]:
    """Plan every arm's pick-and-place (IK on every waypoint of both) before anything moves, then
    run them step by step on one clock. When a grasp fails, every arm opens and lifts and the
    pair stops there (nothing is carried by one arm alone)."""
    try:
        steps = cell.plan_together(pairs)
    except UnreachableTargetError as exc:
        labels = " and ".join(f"'{a.label}'" for _, a in pairs)
        raise UnreachableTargetError(
            f"actions {labels} are infeasible (nothing moved): {exc}"
        ) from exc
    if len({len(s) for s in steps}) != 1:
        raise FoldbotError("arms moved together need the same number of motion steps")
    cell.confirm_motion([(arm, a, s) for (arm, a), s in zip(pairs, steps, strict=True)])
    grasps: list[GraspResult | None] = [None] * len(pairs)
    max_err = [0.0] * len(pairs)
    for k in range(len(steps[0])):
        logs = cell.run_together([(arm, s[k]) for (arm, _), s in zip(pairs, steps, strict=True)])
        for i, step_log in enumerate(logs):
            max_err[i] = max(max_err[i], step_log.max_tracking_error)
            if step_log.grasp is not None:
                grasps[i] = step_log.grasp
        if any(g is not None and not g.success for g in grasps):
            for arm, _ in pairs:
                cell.release_and_lift_arm(arm)
            break
    carried = all(g is not None and g.success for g in grasps)
    return [
        {
            "grasp_success": bool(g and g.success),
            "grasp_reason": g.reason if g else "no grasp attempted",
            "grasped_vertices": list(g.vertex_ids) if g else [],
            "max_tracking_error": err,
            "carried": carried,
        }
        for g, err in zip(grasps, max_err, strict=True)
    ]


def show_and_carry_pair(
    cell: FoldCell,
    state: ClothState,
    arms: list[int],
    actions: list[FoldAction],
    log: Callable[[str], None] = print,
) -> tuple[list[dict], list[int]]:
    """Show a pair's grasps, places and fold line, then carry it (execute_together) with the arms
    as assigned, or the other way round when they would meet; returns the outcomes and the arms
    used. ArmsWouldCollideError when they would meet either way (nothing moved)."""
    cell.show(
        state,
        grasp_points=[a.grasp for a in actions],
        place_points=[a.place for a in actions],
        fold_line=line_points(actions[0].fold_line, cell.table_height),
    )
    try:
        return execute_together(cell, list(zip(arms, actions, strict=True))), arms
    except ArmsWouldCollideError as exc:
        log(f"  the arms would meet ({exc}); trying them the other way round")
        arms = arms[::-1]
        return execute_together(cell, list(zip(arms, actions, strict=True))), arms


def pair_attempt(actions: Sequence[FoldAction | SpreadAction], outcomes: list[dict]) -> dict:
    """One try of a pair (pick-and-places or a spread's two arms), as the entries' `attempts`
    record it: grasps aimed, and what they held."""
    return {
        "grasps": [[float(v) for v in a.grasp] for a in actions],
        "grasp_success": [o["grasp_success"] for o in outcomes],
        "grasp_reasons": [o["grasp_reason"] for o in outcomes],
    }


def missed_grasps(planned: Sequence[FoldAction | SpreadAction], outcomes: list[dict]) -> str:
    """The log's words for a pair's failed grasps: each missed action's label and reason."""
    return "; ".join(
        f"{a.label}: {o['grasp_reason']}"
        for a, o in zip(planned, outcomes, strict=True)
        if not o["grasp_success"]
    )


PairAim = Callable[[int, int, bool, ClothState, "Observation | None", FoldAction], FoldAction]
"""How a pair's try aims its action `i`: (i, try, whether its grasp missed in the last try, the
state and frame seen now, the action as last aimed) → the action to carry."""


@dataclass
class PairCarry:
    """What carry_pair did: the actions as last aimed and their outcomes, the arms that ran
    them, each try's record (pair_attempt), the state and frame it ended on, and its seconds."""

    actions: list[FoldAction]
    outcomes: list[dict]
    arms: list[int]
    attempts: list[dict]
    state: ClothState
    obs: Observation | None
    sim_seconds: float
    wall_seconds: float
    arms_would_meet: str | None = None
    """Why the pair was not carried at its last try: the arms would meet either way round
    (nothing moved in that try). None otherwise."""

    @property
    def carried(self) -> bool:
        """Whether the last try held every grasp and carried the pair."""
        return bool(self.outcomes) and bool(self.outcomes[0]["carried"])


def carry_pair(
    cell: FoldCell,
    planned: tuple[FoldAction, ...],
    state: ClothState,
    obs: Observation | None,
    aim: PairAim,
    retries: int,
    log: Callable[[str], None] = print,
    what: str = "the corners",
) -> PairCarry:
    """Carry two planned actions at once, one arm each (assign_arms; show_and_carry_pair turns
    them round when their motions would meet). Each try aims every action at the frame seen now
    (`aim`), carries the pair, parks and re-observes; a missed grasp makes both arms let go and
    the pair is tried again, at most `retries` times. Stops at a try whose arms would meet
    either way (`arms_would_meet`). `what` names the pair in the log ("carrying `what` one arm at
    a time"), where the callers go on with one arm."""
    t_sim, t_wall = cell.sim_time, time.perf_counter()
    arms = assign_arms(cell.arm_for, planned)
    actions, outcomes, attempts = list(planned), [], []
    failed = [False] * len(planned)
    for attempt in range(retries + 1):
        actions = [aim(i, attempt, failed[i], state, obs, actions[i]) for i in range(len(planned))]
        try:
            outcomes, arms = show_and_carry_pair(cell, state, arms, actions, log)
        except ArmsWouldCollideError as exc:
            log(f"  the arms would meet ({exc}); carrying {what} one arm at a time")
            return PairCarry(
                actions, [], arms, attempts, state, obs,
                cell.sim_time - t_sim, time.perf_counter() - t_wall, arms_would_meet=str(exc),
            )  # fmt: skip
        cell.park()
        state, obs = cell.observe()
        failed = [not o["grasp_success"] for o in outcomes]
        attempts.append(pair_attempt(actions, outcomes))
        if outcomes[0]["carried"]:
            break
        reasons = missed_grasps(planned, outcomes)
        if attempt < retries:
            log(f"  grasp failed ({reasons}); both arms let go, re-observed, retry {attempt + 1}")
        else:
            log(f"  grasp failed ({reasons}); carrying {what} one arm at a time")
    return PairCarry(
        actions, outcomes, arms, attempts, state, obs,
        cell.sim_time - t_sim, time.perf_counter() - t_wall,
    )  # fmt: skip
