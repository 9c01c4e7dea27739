"""Two arms planned together keep clear of each other: their planned motions checked on the
planning twins. (Moving them on one clock is control.executor's run_together and
move_joints_together.)"""

from __future__ import annotations

import numpy as np

from foldbot.control.executor import ArmExecutor, PlannedSegment
from foldbot.errors import ArmsWouldCollideError

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
                        hit = ma.nearest_within(mb.body_id, clearance)
                    if hit is not None:
                        link_a, link_b, dist = hit
                        raise ArmsWouldCollideError(
                            f"segment '{sa.segment.name}': the arms' {ma.link_name(link_a)} and "
                            f"{mb.link_name(link_b)} would come {dist * 1000:.0f} mm apart "
                            f"(at least {clearance * 1000:.0f} mm needed)"
                        )
