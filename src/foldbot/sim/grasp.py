"""Physical cloth grasping: closing the jaws anchors the cloth vertices caught between the fingers.

A real parallel gripper holds cloth by friction between its pads; PyBullet's cloth–rigid friction
cannot hold a pinched sheet reliably, so the vertices that really lie between the closed finger pads
are attached to a finger link with soft-body anchors. Nothing outside the jaws is ever attached.
With `catch="surface"` the jaws also hold cloth that passes between the pads where no mesh point
does (a corner taken 1–2 cm off a vertex, on a mesh 2.7 cm coarse): the mesh point of each such
triangle nearest the TCP is anchored where it lies.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from foldbot.errors import require
from foldbot.sim.cloth import SoftCloth
from foldbot.sim.robots.base import Robot
from foldbot.types import GraspResult

JAW_CATCHES = ("vertices", "surface")
"""What closed jaws hold: "vertices", the mesh points between the pads only; "surface", also a
cloth triangle that passes between the pads with none of its points there (held at its point
nearest the TCP)."""

SURFACE_SAMPLES = 8
"""Barycentric subdivisions per triangle edge when testing whether a triangle passes between the
pads: samples 1/8 of an edge apart, ≤ 3.4 mm on a 2.7 cm mesh, finer than the 2 cm pads."""


HELD_GAP_MIN = 0.001
"""Least gap (m) the jaws report while they hold cloth (a cloth modelled with no thickness)."""

HOLD_SLACK = 0.03
"""A held point this much (m) further from the TCP than when it was grasped has not risen with
the jaws (an anchored point keeps its distance to the millimetre)."""


def slip_reason(motion: str, held: int) -> str:
    """The gripper's report of a grasp that let go of its cloth in `motion` (its name), having
    held `held` vertices: the failed grasp the loops see (a cell over ROS words it so too)."""
    return (
        f"the cloth slipped from the jaws in the {motion} ({held} vertices were held; the "
        "gripper holds none of them now)"
    )


class ClothGrasp:
    """Close/open the gripper of `robot` on `cloth`, anchoring what lies between the jaws."""

    def __init__(
        self,
        world,
        robot: Robot,
        cloth: SoftCloth,
        tolerance: float = 0.004,
        pinch_reach: float = 0.01,
        catch: str = "vertices",
    ) -> None:
        require(
            catch in JAW_CATCHES,
            f"unknown jaw catch {catch!r}; allowed: {', '.join(JAW_CATCHES)}",
        )
        self.world = world
        self.robot = robot
        self.cloth = cloth
        self.tolerance = tolerance
        """Slack (m) around the pad volume within which a vertex counts as between the jaws."""
        self.pinch_reach = pinch_reach
        """How far (m) either side of the closed pads, across the closing axis, cloth is swept in
        and pinched by closing pads (always within the opening the pads closed from)."""
        self.catch = catch
        """What the closed jaws hold (JAW_CATCHES): the mesh points between the pads, or also
        the cloth surface between them."""
        self._anchors: list[int] = []
        self.held: tuple[int, ...] = ()
        self._grasped_at = np.zeros(0)
        """The held points' distances from the TCP when grasped (m)."""
        self._opening_from: float | None = None
        """The gap (m) the jaws opened from while holding cloth, until they are past it: a real
        gripper's fingers open from where the cloth stopped them (reported_fingers)."""
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

    def _held_distances(self) -> np.ndarray:
        """Each held point's distance (m) from the TCP, in `held` order."""
        tcp = self.robot.tcp_pose()[0]
        return np.linalg.norm(self.cloth.sim_vertices()[list(self.held)] - tcp, axis=1)

    def holds_what_it_grasped(self) -> bool:
        """What the gripper can tell of its hold, as a real one's object detection does: the
        jaws hold cloth, and what they grasped moved with them (no held point more than
        HOLD_SLACK further from the TCP than when grasped). False once a grasp has slipped."""
        if not self._anchors:
            return False
        return bool(np.all(self._held_distances() <= self._grasped_at + HOLD_SLACK))

    def _cloth_stop(self, opening: float) -> float:
        """The gap (m) cloth stops a real gripper's fingers at, the jaws' measured `opening`
        aside: the held cloth's layer thickness (at least HELD_GAP_MIN) while the grasp holds
        what it grasped, the gap they opened from until they are past it; else 0."""
        if self._opening_from is not None and opening >= self._opening_from:
            self._opening_from = None
        stop = self._opening_from or 0.0
        if self.holds_what_it_grasped():
            stop = max(stop, self.cloth.thickness, HELD_GAP_MIN)
        return stop

    def jaw_gap(self) -> float:
        """The jaws' gap (m) as a real gripper's encoder reads it: closed on cloth, they stop on
        it while they hold what they grasped, and close on once it has slipped out; else the
        fingers' measured gap. (The simulated pads pass through the cloth, which the anchors
        hold instead.)"""
        opening = self.robot.gripper_opening()
        return max(opening, self._cloth_stop(opening))

    def reported_fingers(self) -> np.ndarray:
        """The finger joints (left, right; m) as a real gripper's driver publishes them on
        /joint_states: stopped on the held cloth (jaw_gap) while the grasp holds, opening from
        it, else measured. A cell's task node sees a slip there, as the jaws closing on after
        they had stalled."""
        fingers = self.robot.finger_positions()
        opening = self.robot.gripper_opening()
        stop = self._cloth_stop(opening)
        if stop <= opening:
            return fingers
        return np.maximum(fingers, self.robot.finger_target(min(stop, self.robot.max_opening)))

    def lost_hold(self, held_before: tuple[int, ...], motion: str) -> str | None:
        """Why a grasp that held `held_before` as a motion began, and was not opened by it, no
        longer holds what it grasped (holds_what_it_grasped) after `motion`: the gripper's report
        of a slip; None while it holds, or where it held nothing."""
        if not held_before or self.holds_what_it_grasped():
            return None
        return slip_reason(motion, len(held_before))

    def slip(self) -> tuple[int, ...]:
        """Every anchor released with the fingers left closed: as a fault injected, a grasp that
        loses its cloth in a carry (open() lets go so before opening); the vertices it held."""
        lost = self.held
        for anchor in self._anchors:
            self.cloth.release(anchor)
        self._anchors.clear()
        self.held = ()
        return lost

    def vertices_between_jaws(self, gap: float | None = None) -> np.ndarray:
        """Indices of cloth vertices inside the volume between the finger pads (mesh order)."""
        return np.flatnonzero(self._between_jaws(self.cloth.sim_vertices(), gap))

    def surface_between_jaws(self, gap: float | None = None) -> np.ndarray:
        """Mesh points (mesh order) that hold the cloth surface between the pads: for each
        triangle with a sample point (SURFACE_SAMPLES per edge) inside the pad volume, its vertex
        nearest the TCP. Used where no vertex lies between the pads."""
        verts = self.cloth.sim_vertices()
        faces = np.asarray(self.cloth.mesh.faces)
        tcp = self.robot.tcp_pose()[0]
        near = faces[np.linalg.norm(verts[faces] - tcp, axis=2).min(axis=1) < 0.1]
        if near.size == 0:
            return np.zeros(0, dtype=int)
        n = SURFACE_SAMPLES
        ij = np.array([(i, j) for i in range(n + 1) for j in range(n + 1 - i)], dtype=float) / n
        bary = np.column_stack([ij, 1.0 - ij.sum(axis=1)])  # (S, 3)
        points = np.einsum("sk,fkd->fsd", bary, verts[near])  # (F, S, 3)
        inside = self._between_jaws(points.reshape(-1, 3), gap).reshape(len(near), -1).any(axis=1)
        caught = near[inside]
        if caught.size == 0:
            return np.zeros(0, dtype=int)
        nearest = np.argmin(np.linalg.norm(verts[caught] - tcp, axis=2), axis=1)
        return np.unique(caught[np.arange(len(caught)), nearest])

    def _between_jaws(self, points: np.ndarray, gap: float | None) -> np.ndarray:
        """Mask of world `points` (N×3) inside the volume between the finger pads."""
        pos, quat = self.robot.tcp_pose()
        rot = np.asarray(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        local = (points - pos) @ rot  # world → TCP frame
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
        return inside

    def close(self, settle_time: float = 0.4, force: float | None = None) -> GraspResult:
        """Close the fingers under position control (each with at most `force` N; None: the
        robot model's), then anchor the vertices caught between them."""
        if self._anchors:
            return GraspResult(True, self.held, "already holding")
        self.robot.set_gripper_opening(0.0, force)
        steps = max(1, round(settle_time / self.world.time_step))
        self.world.step(steps)
        caught = self.vertices_between_jaws()
        between = "between the jaws"
        if caught.size == 0 and self.catch == "surface":
            caught = self.surface_between_jaws()
            between = "holding the cloth between the jaws"
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
            self._anchors.append(self.cloth.anchor(int(v), self.robot.body_id, link))
        self.held = tuple(int(v) for v in caught)
        self._grasped_at = self._held_distances()
        return GraspResult(True, self.held, f"{len(caught)} vertices {between}")

    def open(
        self, width: float | None = None, settle_time: float = 0.3, force: float | None = None
    ) -> None:
        """Release every anchor and open the fingers (each with at most `force` N; None: the
        robot model's)."""
        if self.holds_what_it_grasped():
            self._opening_from = self.jaw_gap()
        self.slip()  # let go of the cloth, then open
        self.robot.set_gripper_opening(self.robot.max_opening if width is None else width, force)
        self.world.step(max(1, round(settle_time / self.world.time_step)))


class SlipFault:
    """A fault injected to watch the loop recover (EpisodeConfig.fault_slip): the first carry
    that holds cloth lets it go `fraction` of the way from its start toward its end, in the
    table's plane, the jaws left closed (ClothGrasp.slip); once per episode."""

    def __init__(self, fraction: float = 0.0) -> None:
        require(0.0 <= fraction < 1.0, f"slip fraction must be in [0, 1), got {fraction!r}")
        self.fraction = fraction
        self.slipped = False
        """Whether the slip has happened."""

    def hook(self, grasp: ClothGrasp, start_xy: np.ndarray, end_xy: np.ndarray):
        """A step hook for a carry by `grasp`'s arm from `start_xy` to `end_xy` (m): it slips
        once the TCP has come `fraction` of the way; None when no slip is due (none injected,
        already slipped, or the gripper holds nothing)."""
        if self.fraction <= 0.0 or self.slipped or not grasp.holding:
            return None
        start = np.asarray(start_xy, dtype=float)[:2]
        way = np.asarray(end_xy, dtype=float)[:2] - start
        span = max(float(way @ way), 1e-12)

        def slip_once(_world) -> None:
            if not self.slipped and (grasp.robot.tcp_pose()[0][:2] - start) @ way / span >= (
                self.fraction
            ):
                self.slipped = True
                grasp.slip()

        return slip_once
