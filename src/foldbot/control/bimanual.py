"""Two arms planned together keep clear of each other: their planned motions checked on the
planning twins at the instants they will really pass through. (Moving them on one clock is
control.executor's run_together and move_joints_together.)"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from foldbot.control.executor import ArmExecutor, PlannedSegment
from foldbot.errors import ArmsWouldCollideError, UnreachableTargetError

ARM_CLEARANCE = 0.02
"""Two arms' links must stay this far apart (m) at every instant of a motion planned together: a
margin for tracking error (under 2 mm at the TCP in every run measured) and for what the
simulated links' collision shapes leave out."""


def step_timelines(executor: ArmExecutor, steps: list[PlannedSegment]) -> list[np.ndarray]:
    """Joint positions (T × dof) an arm passes through in each of its steps, one per physics step,
    time-parametrised as the executor will run them, then still for the segment's dwell; a step
    whose joint path is one configuration is an arm standing still there."""
    out = []
    for s in steps:
        line = (
            np.asarray(s.joint_path, dtype=float)
            if len(s.joint_path) == 1
            else executor.trajectory_for(s.joint_path, s.points, s.segment.speed).positions
        )
        dwell = round(s.segment.dwell / executor.world.time_step)
        out.append(np.vstack([line, np.repeat(line[-1:], dwell, axis=0)]) if dwell else line)
    return out


def check_arms_clear(
    plans: list[tuple[ArmExecutor, list[PlannedSegment]]], clearance: float = ARM_CLEARANCE
) -> None:
    """Raise ArmsWouldCollideError when two arms' planned motions bring any of their links within
    `clearance` at the same instant. The arms start each step together and an arm whose step ends
    first holds its last sample until the other's ends, as control.executor's run_together moves
    them; every physics step is checked, on the planning twins (which must share one world). The
    error names the step, the links and their closest approach in it."""
    lines = [step_timelines(ex, steps) for ex, steps in plans]
    for i, (ea, pa) in enumerate(plans):
        for j in range(i + 1, len(plans)):
            eb, pb = plans[j]
            ma, mb = ea.model, eb.model
            if ma.client != mb.client:
                raise ValueError("arms planned together need their planning twins in one world")
            if len(pa) != len(pb):
                raise ValueError(f"arms planned together need as many steps ({len(pa)}, {len(pb)})")
            for k, seg in enumerate(pa):
                a, b = lines[i][k], lines[j][k]
                closest: tuple[int, int, float] | None = None
                for t in range(max(len(a), len(b))):
                    with ma.posed(a[min(t, len(a) - 1)]), mb.posed(b[min(t, len(b) - 1)]):
                        hit = ma.nearest_within(mb.body_id, clearance)
                    if hit is not None and (closest is None or hit[2] < closest[2]):
                        closest = hit
                if closest is not None:
                    link_a, link_b, dist = closest
                    how = (
                        f"come {dist * 1000:.0f} mm apart"
                        if dist >= 0.0
                        else f"overlap by {-dist * 1000:.0f} mm"
                    )
                    error = ArmsWouldCollideError(
                        f"segment '{seg.segment.name}': the arms' {ma.link_name(link_a)} and "
                        f"{mb.link_name(link_b)} would {how} "
                        f"(at least {clearance * 1000:.0f} mm apart needed)"
                    )
                    error.segment = seg.segment.name
                    raise error


def check_clear_of_still_arms(
    arm: int,
    moving: tuple[ArmExecutor, list[PlannedSegment]],
    still: list[tuple[ArmExecutor, np.ndarray]],
    clearance: float = ARM_CLEARANCE,
) -> None:
    """One arm's planned motion (`moving`, arm number `arm`) against the other arms standing at
    their joints (`still`): UnreachableTargetError naming the arm when they would meet, so a
    cell can give the action to another arm."""
    executor, plan = moving
    plans = [(executor, plan)]
    for other, q in still:
        at = np.asarray(q, dtype=float)[None, :]
        plans.append((other, [replace(s, joint_path=at) for s in plan]))
    try:
        check_arms_clear(plans, clearance)
    except ArmsWouldCollideError as exc:
        raise UnreachableTargetError(f"arm {arm}: {exc}") from exc
