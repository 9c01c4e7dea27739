"""Physical cloth grasping: closing the jaws anchors the cloth caught between the fingers.

A real parallel gripper holds cloth by friction between its pads; PyBullet's cloth–rigid friction
cannot hold a pinched sheet reliably, so the cloth that really lies between the closed finger pads
is attached to a finger link with soft-body anchors: the mesh vertices between the pads. The cloth
is a continuous sheet whose mesh points lie up to ~3 cm apart, wider than the 2 cm pads: where the
pads close on triangles' interiors with no vertex between them, each pinched triangle is held by
its vertex nearest the jaws (anchored where it is, relative to its finger). Cloth none of whose
triangles reaches between the pads is never attached.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from foldbot.errors import require
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
        face_samples: int = 8,
    ) -> None:
        self.world = world
        self.robot = robot
        self.cloth = cloth
        self.tolerance = tolerance
        """Slack (m) around the pad volume within which a vertex counts as between the jaws."""
        self.pinch_reach = pinch_reach
        """How far (m) either side of the closed pads, across the closing axis, cloth is swept in
        and pinched by closing pads (always within the opening the pads closed from)."""
        require(
            isinstance(face_samples, int) and 1 <= face_samples <= 32,
            f"face_samples must be an integer in [1, 32], got {face_samples!r}",
        )
        self.face_samples = face_samples
        """Subdivisions per triangle edge of the points that test a triangle against the jaws
        (8: every ~4 mm on a 3 cm mesh, well under the pads' 2 cm)."""
        self._bary = _barycentric_grid(face_samples)
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

    def _in_jaws(self, points: np.ndarray, gap: float | None) -> np.ndarray:
        """Mask of world `points` (N×3) inside the volume between the finger pads."""
        pos, quat = self.robot.tcp_pose()
        rot = np.asarray(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        local = (np.asarray(points, dtype=float) - pos) @ rot  # world → TCP frame
        r = self.robot
        g = r.gripper_opening() if gap is None else gap
        tol = self.tolerance
        reach = min(g / 2 + self.pinch_reach, r.max_opening / 2)
        return (
            (np.abs(local[..., 0]) <= r.JAW_WIDTH / 2 + tol)
            & (np.abs(local[..., 1]) <= reach)
            & (local[..., 2] <= r.TIP_BELOW_TCP + tol)
            & (local[..., 2] >= r.TIP_BELOW_TCP - r.JAW_DEPTH)
        )

    def vertices_between_jaws(self, gap: float | None = None) -> np.ndarray:
        """Indices of cloth vertices inside the volume between the finger pads (mesh order)."""
        return np.flatnonzero(self._in_jaws(self.cloth.sim_vertices(), gap))

    def faces_between_jaws(self, gap: float | None = None) -> np.ndarray:
        """Indices of mesh triangles with some point inside the volume between the finger pads
        (each tested at a barycentric grid of `face_samples` subdivisions)."""
        tri = self.cloth.sim_vertices()[self.cloth.mesh.faces]  # F × 3 × 3
        points = np.einsum("sk,fkd->fsd", self._bary, tri)  # F × S × 3
        return np.flatnonzero(self._in_jaws(points, gap).any(axis=1))

    def caught_vertices(self, gap: float | None = None) -> np.ndarray:
        """Mesh vertices the closed jaws hold (sorted): those between the pads; with none there,
        the vertex nearest the TCP of every triangle passing between the pads (one per pinched
        triangle, so a held layer still turns about the grip as a pinched sheet does)."""
        inside = self.vertices_between_jaws(gap)
        if inside.size:
            return inside
        faces = self.cloth.mesh.faces[self.faces_between_jaws(gap)]
        if faces.size == 0:
            return inside
        d = np.linalg.norm(self.cloth.sim_vertices()[faces] - self.robot.tcp_pose()[0], axis=2)
        return np.unique(faces[np.arange(len(faces)), d.argmin(axis=1)]).astype(np.int64)

    def close(self, settle_time: float = 0.4) -> GraspResult:
        """Close the fingers under position control, then anchor the vertices caught between them."""
        if self._anchors:
            return GraspResult(True, self.held, "already holding")
        self.robot.set_gripper_opening(0.0)
        steps = max(1, round(settle_time / self.world.time_step))
        self.world.step(steps)
        caught = self.caught_vertices()
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
        return GraspResult(
            True, self.held, f"{len(caught)} vertices held (the cloth between the jaws)"
        )

    def open(self, width: float | None = None, settle_time: float = 0.3) -> None:
        """Release every anchor and open the fingers."""
        for anchor in self._anchors:
            p.removeConstraint(anchor, physicsClientId=self.world.client)
        self._anchors.clear()
        self.held = ()
        self.robot.set_gripper_opening(self.robot.max_opening if width is None else width)
        self.world.step(max(1, round(settle_time / self.world.time_step)))


def _barycentric_grid(n: int) -> np.ndarray:
    """Barycentric weights (S×3) of the points of a triangle subdivided n times per edge."""
    return np.array(
        [(i / n, j / n, (n - i - j) / n) for i in range(n + 1) for j in range(n + 1 - i)]
    )
