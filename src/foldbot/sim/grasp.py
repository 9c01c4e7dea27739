"""Physical cloth grasping: closing the jaws anchors the cloth vertices caught between the fingers.

A real parallel gripper holds cloth by friction between its pads; PyBullet's cloth–rigid friction
cannot hold a pinched sheet reliably, so the vertices that really lie between the closed finger pads
are attached to a finger link with soft-body anchors. Nothing outside the jaws is ever attached.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from foldbot.sim.cloth import SoftCloth
from foldbot.sim.robots.base import Robot
from foldbot.types import GraspResult


class ClothGrasp:
    """Close/open the gripper of `robot` on `cloth`, anchoring what lies between the jaws."""

    def __init__(
        self,
        world,
        robot: Robot,
        cloth: SoftCloth,
        tolerance: float = 0.004,
        pinch_reach: float = 0.01,
    ) -> None:
        self.world = world
        self.robot = robot
        self.cloth = cloth
        self.tolerance = tolerance
        """Slack (m) around the pad volume within which a vertex counts as between the jaws."""
        self.pinch_reach = pinch_reach
        """How far (m) either side of the closed pads, across the closing axis, cloth is swept in
        and pinched by closing pads (always within the opening the pads closed from)."""
        self._anchors: list[int] = []
        self.held: tuple[int, ...] = ()
        # Finger pads squeezing cloth nodes through rigid–soft contact blows the cloth up; the pads'
        # hold is modelled by the anchors instead, so pad–cloth contact is filtered out. The palm
        # and the arm still collide with the cloth.
        for link in robot.finger_link_indices:
            p.setCollisionFilterPair(
                robot.body_id, cloth.body_id, link, -1, 0, physicsClientId=world.client
            )

    @property
    def holding(self) -> bool:
        return bool(self._anchors)

    def vertices_between_jaws(self, gap: float | None = None) -> np.ndarray:
        """Indices of cloth vertices inside the volume between the finger pads (mesh order)."""
        pos, quat = self.robot.tcp_pose()
        rot = np.asarray(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        local = (self.cloth.sim_vertices() - pos) @ rot  # world → TCP frame
        r = self.robot
        g = r.gripper_opening() if gap is None else gap
        tol = self.tolerance
        reach = min(g / 2 + self.pinch_reach, r.max_opening / 2)
        inside = (
            (np.abs(local[:, 0]) <= r.JAW_WIDTH / 2 + tol)
            & (np.abs(local[:, 1]) <= reach)
            & (local[:, 2] <= r.TIP_BELOW_TCP + tol)
            & (local[:, 2] >= r.TIP_BELOW_TCP - r.JAW_DEPTH)
        )
        return np.flatnonzero(inside)

    def close(self, settle_time: float = 0.4) -> GraspResult:
        """Close the fingers under position control, then anchor the vertices caught between them."""
        if self._anchors:
            return GraspResult(True, self.held, "already holding")
        self.robot.set_gripper_opening(0.0)
        steps = max(1, round(settle_time / self.world.time_step))
        self.world.step(steps)
        caught = self.vertices_between_jaws()
        pos, quat = self.robot.tcp_pose()
        if caught.size == 0:
            nearest = np.linalg.norm(self.cloth.sim_vertices() - pos, axis=1).min()
            return GraspResult(
                False,
                (),
                f"no cloth between the jaws (TCP at {np.round(pos, 3).tolist()} m, nearest "
                f"cloth vertex {nearest * 1000:.0f} mm away)",
            )
        rot = np.asarray(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        verts = self.cloth.sim_vertices()
        left, right = self.robot.finger_link_indices
        for v in caught:
            # Attach each vertex to the finger on its side of the TCP.
            side_y = float((verts[v] - pos) @ rot[:, 1])
            link = left if side_y >= 0 else right
            anchor = p.createSoftBodyAnchor(
                self.cloth.body_id,
                self.cloth.sim_index(int(v)),
                self.robot.body_id,
                link,
                physicsClientId=self.world.client,
            )
            self._anchors.append(anchor)
        self.held = tuple(int(v) for v in caught)
        return GraspResult(True, self.held, f"{len(caught)} vertices between the jaws")

    def open(self, width: float | None = None, settle_time: float = 0.3) -> None:
        """Release every anchor and open the fingers."""
        for anchor in self._anchors:
            p.removeConstraint(anchor, physicsClientId=self.world.client)
        self._anchors.clear()
        self.held = ()
        self.robot.set_gripper_opening(self.robot.max_opening if width is None else width)
        self.world.step(max(1, round(settle_time / self.world.time_step)))
