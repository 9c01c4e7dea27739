"""A dry run: what a fold would do, seen and planned from one camera frame, with nothing
moved. Every stage is planned from that frame (a towel's later stages on the outline the one
before predicts, one layer up; a garment's all at once from its keypoints, as its fold plans
them) and carried as the fold carries it (two arms together, a towel's folded stack by its
edge's middle), every pick-and-place's motion planned from where the arm stands,
each waypoint's IK and table clearance checked (a pair's arms also kept clear of each other),
each step timed at the cell's speed scale: the plan, its pictures and its motion time, to look
at before a first run on a real arm (`foldbot fold --dry-run`, `foldbot ros-fold --dry-run`).

A crumpled start's dry run (one arm) plans the first flattening pull from the heap as seen, as
the flattening would make it (the first pull whose motion is feasible, those out of reach
before it named); every later pull and the fold are planned from what the one before leaves,
so they are not (dry_run_flatten)."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import imageio.v3 as iio
import numpy as np

from foldbot.carry import assign_arms
from foldbot.cell import FoldCell
from foldbot.errors import (
    ArmsWouldCollideError,
    ConfigError,
    FoldbotError,
    OutputError,
    UnreachableTargetError,
    failed_segment,
)
from foldbot.flatten import pulls_from_view, stops_at
from foldbot.garment_loop import aimed_actions, garment_keypoints, together
from foldbot.grasp_points import stack_grasp_point
from foldbot.io.staging import prepare_output
from foldbot.loop import (
    LoopConfig,
    StageCarries,
    actions_overlay,
    first_aim,
    plan_from_first_view,
    require_in_view,
    stage_carries,
)
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.planning.flatten import FlattenConfig, perceived_coverage
from foldbot.planning.garment_recipes import PLANNED_FROM, fold_outline
from foldbot.planning.recipes import CORNER_NAMES
from foldbot.types import Observation

PLAN_FILE = "plan.json"
"""What a dry run writes instead of result.json (DryRun.record)."""


@dataclass
class DryRun:
    """A dry run's plan (`record`, plan.json's content) and its pictures, one per stage."""

    record: dict[str, Any]
    overlays: list[np.ndarray] = field(default_factory=list)

    def summary(self) -> str:
        """One line on it."""
        r = self.record
        if "flatten" in r:
            return flatten_summary(r)
        actions = r["actions"]
        bad = [f"stage {a['stage']} {a['label']}" for a in actions if not a["feasible"]]
        pairs = sum(1 for a in actions if a.get("together")) // 2
        together = f" ({pairs} pair(s) by two arms together)" if pairs else ""
        head = (
            f"dry run: {len(r['stages'])} stage(s), {len(actions)} pick-and-place(s){together} "
            "planned from one frame, nothing moved; "
        )
        if bad:
            return head + f"NOT feasible: {', '.join(bad)} ({PLAN_FILE} says why)"
        return head + (
            f"every motion feasible, {r['motion_seconds']:.1f} s of arm motion at speed scale "
            f"{r['speed_scale']:g}"
        )


def step_name(step: Any) -> str:
    """A planned step's name: a PlannedSegment's segment's, or a ROS step's ("name")."""
    return str(step["name"]) if isinstance(step, dict) else str(step.segment.name)


def action_entry(stage: int, action: FoldAction) -> dict[str, Any]:
    """plan.json's start of an action's entry: its stage, label, grasp, place, layers and
    descent (m: how far the jaws come down onto the grasp; None: the motion's default)."""
    return {
        "stage": stage,
        "label": action.label,
        "grasp": np.asarray(action.grasp, dtype=float).tolist(),
        "place": np.asarray(action.place, dtype=float).tolist(),
        "layers": action.layers,
        "descent_m": action.descent,
    }


def timed_steps(cell: FoldCell, arm: int, steps: list[Any]) -> list[dict[str, Any]]:
    """Each planned step of `arm`'s motion, named and timed (s) at the cell's speed scale."""
    previous = cell.active_arm
    cell.use_arm(arm)
    try:
        return [{"name": step_name(s), "seconds": cell.step_seconds(s)} for s in steps]
    finally:
        cell.use_arm(previous)


def infeasible(entry: dict[str, Any], exc: FoldbotError) -> dict[str, Any]:
    """`entry` marked infeasible, with the reason and the segment the motion failed in."""
    return entry | {"feasible": False, "reason": str(exc), "segment": failed_segment(exc)}


def plan_single(
    cell: FoldCell, stage: int, action: FoldAction, log: Callable[[str], None]
) -> dict[str, Any]:
    """One arm's pick-and-place (the arm on its grasp's side) planned from where it stands."""
    cell.use_arm(cell.arm_for(action.grasp))
    entry = action_entry(stage, action)
    try:
        steps = cell.plan_action(action)
    except UnreachableTargetError as exc:
        log(f"dry run: stage {stage}, {action.label}: NOT feasible: {exc}")
        return infeasible(entry, exc)
    timed = timed_steps(cell, cell.active_arm, steps)
    seconds = float(sum(t["seconds"] for t in timed))
    log(f"dry run: stage {stage}, {action.label}: {seconds:.1f} s of motion")
    entry |= {"feasible": True, "arm": cell.active_arm, "steps": timed, "motion_seconds": seconds}
    return entry


def plan_pair(
    cell: FoldCell,
    stage: int,
    actions: tuple[FoldAction, ...],
    singles: tuple[FoldAction, ...],
    log: Callable[[str], None],
) -> list[dict[str, Any]]:
    """Two pick-and-places planned as a two-arm cell carries them together (carry_pair): one
    arm each on its grasp's side, the other way round where their motions would meet, and one
    arm at a time (`singles`, as the loop falls back to them) where they would meet either way.
    Each entry holds its own arm's steps; `pair_seconds`, the pair's time on one clock (each
    step as long as the longer arm's), is written on the first entry only."""
    entries = [action_entry(stage, a) | {"together": True} for a in actions]
    arms = assign_arms(cell.arm_for, actions)
    met: ArmsWouldCollideError | None = None
    for order in (arms, arms[::-1]):
        try:
            steps = cell.plan_together(list(zip(order, actions, strict=True)))
        except ArmsWouldCollideError as exc:
            met = exc
            continue
        except UnreachableTargetError as exc:
            log(f"dry run: stage {stage}, {' and '.join(a.label for a in actions)}: NOT "
                f"feasible together: {exc}")  # fmt: skip
            return [infeasible(e, exc) for e in entries]
        timed = [timed_steps(cell, arm, s) for arm, s in zip(order, steps, strict=True)]
        pair_seconds = float(sum(max(t[k]["seconds"] for t in timed) for k in range(len(timed[0]))))
        for entry, arm, t in zip(entries, order, timed, strict=True):
            entry |= {
                "feasible": True,
                "arm": arm,
                "steps": t,
                "motion_seconds": float(sum(x["seconds"] for x in t)),
            }
        entries[0]["pair_seconds"] = pair_seconds
        labels = " and ".join(a.label for a in actions)
        log(f"dry run: stage {stage}, {labels} together: {pair_seconds:.1f} s of motion")
        return entries
    log(f"dry run: stage {stage}: the arms would meet ({met}); one arm at a time")
    return [plan_single(cell, stage, a, log) | {"arms_would_meet": str(met)} for a in singles]


def carried_seconds(actions: list[dict[str, Any]]) -> float:
    """The arms' motion time over a dry run's entries: a pair's once (its pair_seconds)."""
    total = 0.0
    for a in actions:
        if a.get("together"):
            total += a.get("pair_seconds", 0.0)
        else:
            total += a.get("motion_seconds", 0.0)
    return float(total)


@dataclass(frozen=True)
class DryStage:
    """One stage as a dry run plans it: its fold line, the actions carried as the fold's first
    try aims them, whether two arms carry them together (with `pair_descent`, m, where a pair
    comes down so: the towel's), whether by a stack's edge middle, and its picture."""

    fold_line: tuple[float, float, float, float]
    actions: tuple[FoldAction, ...]
    together: bool
    by_edge_middle: bool
    overlay: np.ndarray
    pair_descent: float | None = None


def towel_stages(
    cfg: LoopConfig, cell: FoldCell, state: ClothState, obs: Observation
) -> list[DryStage]:
    """A towel's stages from one frame, as the open loop plans them (a later stage on the
    outline the one before predicts), each carried as the fold carries it (loop.stage_carries;
    the open loop corner after corner) and aimed as the loop's first try aims it where no newer
    frame is seen (loop.first_aim)."""
    stages = []
    for k, (plan, corners) in enumerate(plan_from_first_view(cfg, cell, state)):
        if cfg.closed_loop:
            carries = stage_carries(cfg, cell, k, plan)
        else:
            carries = StageCarries(tuple(plan.actions), False, None)
        centre = np.mean([np.asarray(c, dtype=float) for c in corners.values()], axis=0)
        aimed = tuple(first_aim(cfg, state, a, centre) for a in carries.actions)
        # A later stage is drawn over the first frame with the outline it was planned on, the
        # one the stage before predicts (orange).
        outline = [] if k == 0 else [np.array([corners[n] for n in CORNER_NAMES], dtype=float)]
        stages.append(
            DryStage(
                fold_line=plan.fold_lines[0],
                actions=aimed,
                together=carries.together,
                by_edge_middle=carries.edge_of is not None,
                overlay=actions_overlay(
                    obs, state, aimed, plan.fold_lines[0], cell.table_height, outline
                ),
                pair_descent=cfg.pair_descent,
            )
        )
    return stages


def garment_stages(
    cfg: LoopConfig, cell: FoldCell, state: ClothState, obs: Observation
) -> list[DryStage]:
    """A garment's stages, planned from the flat garment's keypoints as its fold plans them
    (all at once: garment_loop.run_garment_fold), each carried as that loop carries it (a
    two-arm cell's two grasps together where they fit, garment_loop.together). The first
    stage's grasps are aimed onto the cloth this frame shows (garment_loop.aimed_actions); a
    later stage's, which the fold aims from the frame it starts from, as planned (a stack's at
    the table, under every layer)."""
    if not state.detected:
        raise FoldbotError(f"no garment found before folding: {state.reason}")
    if cfg.require_full_view:
        require_in_view(state)
    keypoints = garment_keypoints(state, cfg.recipe)
    plan = cell.plan_garment(cfg.recipe, keypoints, cfg.place_lift, cfg.layer_thickness)
    height = float(np.median(state.keypoint_array()[:, 2]))
    parts = [np.asarray(state.outline_world, dtype=float)[:, :2]]  # as the garment loop predicts
    stages = []
    for i, stage in enumerate(plan.stages):
        # A later stage is drawn over the first frame with the pieces it was planned on, the
        # ones the stages before predict (orange).
        shown = [] if i == 0 else [np.c_[part, np.full(len(part), height)] for part in parts]
        parts = fold_outline(parts, stage.fold_line)
        pair = cfg.closed_loop and together(cell, stage)
        if cfg.closed_loop and i == 0:
            aimed = tuple(aimed_actions(cfg, state, obs, stage, None, pair))
        elif cfg.closed_loop:
            aimed = tuple(
                a
                if a.layers <= 1
                else dataclasses.replace(
                    a, grasp=stack_grasp_point(state, a.grasp, cfg.stack_grasp_height)
                )
                for a in stage.actions
            )
        else:
            aimed = tuple(stage.actions)
        stages.append(
            DryStage(
                fold_line=stage.fold_line,
                actions=aimed,
                together=pair,
                by_edge_middle=False,
                overlay=actions_overlay(
                    obs, state, aimed, stage.fold_line, cell.table_height, shown
                ),
            )
        )
    return stages


def dry_run(
    cfg: LoopConfig, cell: FoldCell, speed_scale: float, log: Callable[[str], None] = print
) -> DryRun:
    """Observe once (the arm where it stands: it is not parked), plan every stage (a towel's:
    towel_stages; a garment's: garment_stages) and every carry's motion, move nothing. An
    action no arm can do is recorded as infeasible, with the reason and the segment it failed
    in, and the others are planned still."""
    state, obs = cell.observe()
    garment = cfg.recipe in PLANNED_FROM  # a garment's recipe (the towel's: planning.recipes)
    planned = (garment_stages if garment else towel_stages)(cfg, cell, state, obs)
    stages, actions, overlays = [], [], []
    for k, stage in enumerate(planned, start=1):
        stages.append(
            {
                "stage": k,
                "fold_line": list(map(float, stage.fold_line)),
                "together": stage.together,
                "by_edge_middle": stage.by_edge_middle,
            }
        )
        overlays.append(stage.overlay)
        if stage.together:
            paired = stage.actions
            if stage.pair_descent is not None:
                paired = tuple(
                    dataclasses.replace(a, descent=stage.pair_descent) for a in stage.actions
                )
            actions.extend(plan_pair(cell, k, paired, stage.actions, log))
        else:
            actions.extend(plan_single(cell, k, a, log) for a in stage.actions)
    record = {
        "dry_run": True,
        "planned_recipe": cfg.recipe,
        "arms": cell.arms,
        "closed_loop": cfg.closed_loop,
        "speed_scale": speed_scale,
        "stages": stages,
        "actions": actions,
        "feasible": all(a["feasible"] for a in actions),
        "motion_seconds": carried_seconds(actions),
        "perceived_keypoints": perceived_keypoints(state),
    }
    return DryRun(record, overlays)


def dry_run_flatten(
    cfg: FlattenConfig,
    cell: FoldCell,
    expected_size: tuple[float, float],
    speed_scale: float,
    log: Callable[[str], None] = print,
) -> DryRun:
    """A crumpled towel's dry run with one arm: the heap observed once (the arm where it stands),
    its perceived coverage of the towel's `expected_size` (m), and the first pull the flattening
    (flatten.run_flatten) would make, planned: the pulls in its order, each planned from where
    the arm stands until one is feasible (an unreachable one is skipped there too, and named
    here). Nothing moves. No pull where the flattening would make none (the coverage already
    stops it, or no point of the outline is short enough to pull)."""
    width, height = (float(v) for v in expected_size)
    state, obs = cell.observe()
    if not state.detected:
        raise FoldbotError(f"no cloth found to flatten: {state.reason}")
    coverage = perceived_coverage(state, width * height)
    done = stops_at(cfg, coverage)
    log(
        f"dry run: the crumpled towel's perceived coverage {coverage:.2f} "
        f"(target {cfg.target_coverage:.2f})" + (": no pull needed" if done else "")
    )
    actions: list[dict[str, Any]] = []
    expected = None
    if not done:
        _fit, pulls, expected = pulls_from_view(cfg, state, obs, (width, height))
        if not pulls:
            done = True
            log("dry run: no point of the expected outline is short enough to pull")
        for pull in pulls:
            entry = plan_single(cell, 0, pull.action, log)
            actions.append(
                entry
                | {"kind": "flatten_pull", "shortfall_m": pull.shortfall, "target": pull.target}
            )
            if entry["feasible"]:
                break
    first = next((a for a in actions if a["feasible"]), None)
    overlay = draw_overlay(
        obs,
        state,
        grasp_points=[np.asarray(a["grasp"]) for a in actions[-1:]],
        place_points=[np.asarray(a["place"]) for a in actions[-1:]],
        expected_outline=expected,
    )
    record = {
        "dry_run": True,
        "start": "crumpled",
        "arms": cell.arms,
        "speed_scale": speed_scale,
        "flatten": {
            "perceived_coverage": coverage,
            "target_coverage": cfg.target_coverage,
            "pull_needed": not done,
            "pulls_planned": len(actions),
        },
        "stages": [],
        "actions": actions,
        "feasible": done or first is not None,
        "motion_seconds": 0.0 if first is None else first["motion_seconds"],
        "perceived_keypoints": perceived_keypoints(state),
    }
    return DryRun(record, [overlay])


def flatten_summary(r: dict[str, Any]) -> str:
    """dry_run_flatten's one line."""
    f = r["flatten"]
    head = (
        f"dry run: the crumpled towel seen at coverage {f['perceived_coverage']:.2f} (target "
        f"{f['target_coverage']:.2f}), nothing moved; "
    )
    tail = "; each later pull and the fold are planned from what the one before leaves"
    if not f["pull_needed"]:
        return head + "no pull needed: the fold is planned from what the camera then sees"
    first = next((a for a in r["actions"] if a["feasible"]), None)
    if first is None:
        return head + (
            f"NOT feasible: every flattening pull ({f['pulls_planned']}) is out of the arm's "
            f"reach ({PLAN_FILE} says why)"
        )
    skipped = f["pulls_planned"] - 1
    return (
        head
        + f"the first pull, {first['label']}, feasible: {first['motion_seconds']:.1f} s of arm "
        f"motion at speed scale {r['speed_scale']:g}"
        + (f" ({skipped} out of reach before it, skipped)" if skipped else "")
        + tail
    )


def perceived_keypoints(state: ClothState) -> dict[str, list[float]]:
    """plan.json's `perceived_keypoints`: each keypoint's world position (m) as seen."""
    return {
        label: np.asarray(xyz, dtype=float).tolist()
        for label, (xyz, _conf) in state.keypoints.items()
    }


def check_dry_run_output(out: Path, overwrite: bool) -> None:
    """Refuse an --out a dry run must not write into: a file, a folder holding anything but
    an earlier dry run, or an earlier dry run without --overwrite (a plan beside an episode's
    result.json would read as that episode's)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} exists and is not a folder")
    if not out.is_dir() or not any(out.iterdir()):
        return
    if not (out / PLAN_FILE).is_file():
        raise OutputError(
            f"--out {out} is a non-empty folder that holds no dry run ({PLAN_FILE}); allowed: "
            "a new path, an empty folder, or an earlier dry run's folder with --overwrite"
        )
    if not overwrite:
        raise OutputError(f"--out {out} already holds a dry run; pass --overwrite to replace it")


def write_dry_run(run: DryRun, out: Path, overwrite: bool) -> Path:
    """plan.json and overlay_planK.png (stage K's grasps, places and fold line over the frame
    it was planned from), written whole into `out` or not at all (an earlier dry run there
    replaced with `overwrite`)."""
    out = Path(out)
    check_dry_run_output(out, overwrite)
    stage = prepare_output(out)
    try:
        (stage / PLAN_FILE).write_text(json.dumps(run.record, indent=2) + "\n")
        for k, image in enumerate(run.overlays, start=1):
            iio.imwrite(stage / f"overlay_plan{k}.png", image)
        check_dry_run_output(out, overwrite)  # the folder may have changed meanwhile
        if out.exists():
            shutil.rmtree(out)  # empty, or an earlier dry run (checked)
        os.replace(stage, out)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    return out


def check_dry_run_config(garment: str, start: str, faults: list[str], arms: int = 1) -> None:
    """ConfigError where a dry run cannot show the fold: a crumpled start with two arms (each
    spread is tried at hang margins and tool tilts as it goes; one arm's first pull is planned,
    dry_run_flatten), or an injected fault (it acts on a motion, and nothing moves). `garment`:
    the cloth's, named in the refusal."""
    if start != "flat" and arms != 1:
        raise ConfigError(
            f"--dry-run plans a crumpled {garment}'s first flattening pull with one arm; two arms "
            "spread it, each spread tried at its hang margins and tool tilts as it goes: got "
            "--start crumpled --arms 2"
        )
    if faults:
        raise ConfigError(
            f"{' and '.join(faults)} act on a motion, and a dry run moves nothing: drop "
            + ("it" if len(faults) == 1 else "them")
        )
