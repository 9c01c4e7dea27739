"""Two arms on one clock: segments and joint moves of several arms stepped together, each arm
under its own time-parametrised trajectory; an arm whose trajectory ends first holds its last
sample until the others have arrived, and only then do the gripper events happen."""

from __future__ import annotations

import numpy as np

from foldbot.control.executor import ArmExecutor, PlannedSegment, SegmentLog
from foldbot.errors import ArmsWouldCollideError
from foldbot.sim import import_pybullet

p = import_pybullet()  # pybullet, its start-up banner silenced (foldbot.sim)

ARM_CLEARANCE = 0.02
"""Two arms' links must stay this far apart (m) at every step of a motion planned together: a
margin for the arms not keeping exactly equal progress along their paths."""


def check_arms_clear(
    plans: list[tuple[ArmExecutor, list[PlannedSegment]]], clearance: float = ARM_CLEARANCE
) -> None:
    """Raise ArmsWouldCollideError when two arms' planned motions, segment by segment at equal
    progress along their joint paths, bring any of their links within `clearance` (checked on
    the planning twins, which must share one world)."""
    for i, (ea, pa) in enumerate(plans):
        for eb, pb in plans[i + 1 :]:
            ma, mb = ea.model, eb.model
            if ma.client != mb.client:
                raise ValueError("arms planned together need their planning twins in one world")
            for sa, sb in zip(pa, pb, strict=True):
                na, nb = len(sa.joint_path), len(sb.joint_path)
                for u in np.linspace(0.0, 1.0, max(na, nb)):
                    qa = sa.joint_path[round(u * (na - 1))]
                    qb = sb.joint_path[round(u * (nb - 1))]
                    with ma.posed(qa), mb.posed(qb):
                        hits = p.getClosestPoints(
                            ma.body_id, mb.body_id, clearance, physicsClientId=ma.client
                        )
                    if hits:
                        h = min(hits, key=lambda c: c[8])
                        raise ArmsWouldCollideError(
                            f"segment '{sa.segment.name}': the arms' {ma.link_name(h[3])} and "
                            f"{mb.link_name(h[4])} would come {h[8] * 1000:.0f} mm apart "
                            f"(at least {clearance * 1000:.0f} mm needed)"
                        )


def run_together(steps: list[tuple[ArmExecutor, PlannedSegment]]) -> list[SegmentLog]:
    """Move every arm along its segment at once (one physics world), then apply each segment's
    gripper event; returns one log per arm, in order."""
    if not steps:
        return []
    world = steps[0][0].world
    if any(ex.world is not world for ex, _ in steps):
        raise ValueError("arms stepped together must share one world")
    runs = [ex.start(step) for ex, step in steps]
    for k in range(1, max(r.samples for r in runs)):
        for r in runs:
            r.command(k)
        world.step()
        for r in runs:
            r.monitor(k)
    return [r.finish() for r in runs]


def move_joints_together(
    targets: list[tuple[ArmExecutor, np.ndarray]], name: str = "joint_move"
) -> list[SegmentLog]:
    """Rest-to-rest joint-space moves of every arm at once (e.g. parking both)."""
    if not targets:
        return []
    world = targets[0][0].world
    trajs = []
    for ex, q in targets:
        q = np.asarray(q, dtype=float)
        q0 = ex.robot.joint_positions()
        trajs.append(None if np.abs(q - q0).max() < 1e-4 else ex.joint_move_trajectory(q0, q))
    steps = max((len(t.times) for t in trajs if t is not None), default=0)
    for k in range(1, steps):
        for (ex, _), t in zip(targets, trajs, strict=True):
            if t is not None:
                i = min(k, len(t.times) - 1)
                v = t.velocities[i] if k < len(t.times) else np.zeros(ex.robot.dof)
                ex.robot.command_joint_positions(t.positions[i], v)
        world.step()
    logs = []
    for (ex, q), t in zip(targets, trajs, strict=True):
        err = float(np.linalg.norm(ex.robot.tcp_pose()[0] - ex.robot.fk_tcp(q)[0]))
        logs.append(SegmentLog(name, 0.0 if t is None else t.duration, err if t else 0.0))
    return logs
