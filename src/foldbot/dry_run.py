"""A dry run: what a towel fold would do, seen and planned from one camera frame, with nothing
moved. Every stage is planned as the open loop plans it (a later stage on the outline the one
before predicts, one layer up) and every pick-and-place's motion from where the arm stands,
each waypoint's IK and table clearance checked, each step timed at the cell's speed scale: the
plan, its pictures and its motion time, to look at before a first run on a real arm
(`foldbot fold --dry-run`, `foldbot ros-fold --dry-run`)."""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import imageio.v3 as iio
import numpy as np

from foldbot.cell import FoldCell
from foldbot.errors import ConfigError, OutputError, UnreachableTargetError, failed_segment
from foldbot.io.staging import prepare_output
from foldbot.loop import LoopConfig, plan_from_first_view, plan_overlay

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
        actions = r["actions"]
        bad = [f"stage {a['stage']} {a['label']}" for a in actions if not a["feasible"]]
        head = (
            f"dry run: {len(r['stages'])} stage(s), {len(actions)} pick-and-place(s) planned "
            "from one frame, nothing moved; "
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


def dry_run(
    cfg: LoopConfig, cell: FoldCell, speed_scale: float, log: Callable[[str], None] = print
) -> DryRun:
    """Observe once (the arm where it stands: it is not parked), plan every stage and every
    action's motion, move nothing. An action no arm can do is recorded as infeasible, with the
    reason and the segment it failed in, and the others are planned still."""
    state, obs = cell.observe()
    plans = plan_from_first_view(cfg, cell, state)
    stages, actions, overlays = [], [], []
    for k, plan in enumerate(plans, start=1):
        stages.append({"stage": k, "fold_line": list(map(float, plan.fold_lines[0]))})
        overlays.append(plan_overlay(obs, state, plan, cell.table_height))
        for action in plan.actions:
            cell.use_arm(cell.arm_for(action.grasp))
            entry: dict[str, Any] = {
                "stage": k,
                "label": action.label,
                "grasp": np.asarray(action.grasp, dtype=float).tolist(),
                "place": np.asarray(action.place, dtype=float).tolist(),
                "layers": action.layers,
            }
            try:
                steps = cell.plan_action(action)
            except UnreachableTargetError as exc:
                entry |= {"feasible": False, "reason": str(exc), "segment": failed_segment(exc)}
                log(f"dry run: stage {k}, {action.label}: NOT feasible: {exc}")
            else:
                seconds = [cell.step_seconds(s) for s in steps]
                entry |= {
                    "feasible": True,
                    "arm": cell.active_arm,
                    "steps": [
                        {"name": step_name(s), "seconds": t}
                        for s, t in zip(steps, seconds, strict=True)
                    ],
                    "motion_seconds": float(sum(seconds)),
                }
                log(f"dry run: stage {k}, {action.label}: {sum(seconds):.1f} s of motion")
            actions.append(entry)
    record = {
        "dry_run": True,
        "planned_recipe": cfg.recipe,
        "arms": cell.arms,
        "speed_scale": speed_scale,
        "stages": stages,
        "actions": actions,
        "feasible": all(a["feasible"] for a in actions),
        "motion_seconds": float(sum(a.get("motion_seconds", 0.0) for a in actions)),
        "perceived_keypoints": {
            label: np.asarray(xyz, dtype=float).tolist()
            for label, (xyz, _conf) in state.keypoints.items()
        },
    }
    return DryRun(record, overlays)


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


def check_dry_run_config(garment: str, start: str, faults: list[str]) -> None:
    """ConfigError where a dry run cannot show the fold: a garment (planned from keypoints on
    the flat garment, not by the towel loop), a crumpled start (each pull is planned from what
    the last one left), or an injected fault (it acts on a motion, and nothing moves)."""
    if garment != "towel":
        raise ConfigError(f"--dry-run plans a towel's fold; got --garment {garment}")
    if start != "flat":
        raise ConfigError(
            "--dry-run plans the fold of a towel lying flat; a crumpled start is flattened "
            "first, each pull planned from what the one before left: got --start crumpled"
        )
    if faults:
        raise ConfigError(
            f"{' and '.join(faults)} act on a motion, and a dry run moves nothing: drop "
            + ("it" if len(faults) == 1 else "them")
        )
