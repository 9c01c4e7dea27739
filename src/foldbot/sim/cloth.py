"""The cloth as a PyBullet soft body in the deformable world: physical parameters, loading, settling.

Never a chain of rigid boxes: a mass-spring soft body built from a generated mesh. Its vertex state is
simulator ground truth; outside the simulator it is reachable only through `foldbot.sim.oracle`.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as p

from foldbot.errors import SimulationDivergedError, require
from foldbot.garments.mesh import ClothMesh

MAX_GUARD_EVERY = 100
"""ClothConfig.crossing_guard's upper bound (physics steps between checks)."""


@dataclass(frozen=True)
class ClothConfig:
    """Physical parameters of the soft-body cloth. Defaults fold a 16×16, 30 cm towel cleanly."""

    mass: float = 0.1
    """Total mass (kg). Much lighter cloth was unstable at 1/240 s (and in DEDO's experience)."""
    elastic_stiffness: float = 40.0
    """Spring elastic stiffness (PyBullet `springElasticStiffness`)."""
    damping_stiffness: float = 0.1
    """Spring damping (PyBullet `springDampingStiffness`), along springs only."""
    bending_stiffness: float = 0.2
    """Bending-spring stiffness (PyBullet `springBendingStiffness`), the real bending control."""
    friction: float = 1.0
    """Cloth friction coefficient (the binding's default of 0 is frictionless cloth). Bullet
    multiplies it by a rigid body's friction (the table's 1.0) for cloth–rigid contact, and by
    itself for cloth–cloth contact unless `layer_friction` is set."""
    layer_friction: float | None = None
    """Friction between two layers of the cloth (cloth–cloth contact); None = friction², Bullet's
    product of the two bodies' coefficients. Set, the soft body's coefficient becomes
    √layer_friction and the table's friction is raised by friction / √layer_friction, so the
    cloth still meets the table at friction × the table's friction (`table_friction_gain`). The
    gripper's pads, which hold by anchors, meet the cloth at √layer_friction × theirs."""
    collision_margin: float | None = None
    """Collision margin (m); None = the mesh's mean edge length / `margin_divisor`."""
    margin_divisor: float = 5.0
    """Where `collision_margin` is None, the margin is the mean edge length over this: a fifth
    keeps the cloth on the table; thinner (a larger divisor) makes stacks blow up
    (docs/experiments.md)."""
    self_collision: bool = True
    """Cloth–cloth collision, which keeps folded layers apart."""
    crossing_guard: int = 0
    """Every how many physics steps the crossing guard puts back mesh points that went through
    the cloth (sim.crossing_guard; Bullet's contact leaves them through); 0: no guard."""
    thickness: float | None = None
    """Layer thickness (m) used for fold goals; None = 2 × collision margin, the spacing at which
    cloth–cloth contact holds two simulated layers apart."""
    drop_height: float = 0.005
    """Height above the table the flat cloth is spawned at before settling (m)."""
    rgba: tuple[float, float, float, float] = (0.20, 0.40, 0.85, 1.0)
    """Cloth colour."""

    def __post_init__(self) -> None:
        require(
            math.isfinite(self.mass) and 0.0 < self.mass <= 5.0,
            f"cloth mass must be in (0, 5] kg, got {self.mass!r}",
        )
        require(
            math.isfinite(self.margin_divisor) and 2.0 <= self.margin_divisor <= 20.0,
            f"cloth margin_divisor must be in [2, 20] (margin = edge / it), "
            f"got {self.margin_divisor!r}",
        )
        for name in ("elastic_stiffness", "bending_stiffness"):
            v = getattr(self, name)
            require(math.isfinite(v) and v > 0.0, f"cloth {name} must be > 0, got {v!r}")
        for name in ("damping_stiffness", "friction", "drop_height"):
            v = getattr(self, name)
            require(math.isfinite(v) and v >= 0.0, f"cloth {name} must be ≥ 0, got {v!r}")
        require(
            float(self.crossing_guard).is_integer() and 0 <= self.crossing_guard <= MAX_GUARD_EVERY,
            f"cloth crossing_guard must be an integer in [0, {MAX_GUARD_EVERY}] physics steps "
            f"(0: no guard), got {self.crossing_guard!r}",
        )
        if self.layer_friction is not None:
            require(
                math.isfinite(self.layer_friction) and 0.0 < self.layer_friction <= 4.0,
                f"cloth layer_friction must be in (0, 4] (or unset: friction²), "
                f"got {self.layer_friction!r}",
            )
        if self.thickness is not None:
            require(
                0.0 <= self.thickness <= 0.05,
                f"cloth thickness must be in [0, 0.05] m, got {self.thickness!r}",
            )
        if self.collision_margin is not None:
            require(
                0.0 < self.collision_margin <= 0.02,
                f"cloth collision_margin must be in (0, 0.02] m, got {self.collision_margin!r}",
            )

    @property
    def body_friction(self) -> float:
        """The soft body's own friction coefficient (PyBullet `frictionCoeff`): `friction`, or
        √layer_friction where the layers' friction is set apart."""
        if self.layer_friction is None:
            return self.friction
        return math.sqrt(self.layer_friction)

    @property
    def table_friction_gain(self) -> float:
        """What the table's friction is multiplied by so that cloth–table friction stays
        friction × the table's: 1 unless `layer_friction` is set."""
        if self.layer_friction is None:
            return 1.0
        return self.friction / self.body_friction


MAX_DEPTH_UNDER_TABLE_M = 0.05
"""A cloth vertex this far under the table top has gone through it: the simulation diverged."""
MAX_HEIGHT_OVER_TABLE_M = 1.5
"""… and one this far over it has been flung: no carry lifts the cloth so high."""


def yaw_rotation(yaw: float) -> np.ndarray:
    """3×3 rotation about world z."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class SoftCloth:
    """A cloth soft body placed flat on the table at (x, y) with a yaw, vertex order = the mesh's."""

    def __init__(
        self,
        client: int,
        mesh: ClothMesh,
        config: ClothConfig,
        table_height: float,
        position_xy: tuple[float, float],
        yaw: float = 0.0,
    ) -> None:
        self.client = client
        self.mesh = mesh
        self.config = config
        self.table_height = table_height
        self.margin = config.collision_margin or mesh.edge_length / config.margin_divisor
        self.thickness = config.thickness if config.thickness is not None else 2 * self.margin
        base = np.array([position_xy[0], position_xy[1], table_height + config.drop_height])
        self.spawn_vertices = mesh.vertices @ yaw_rotation(yaw).T + base
        with tempfile.TemporaryDirectory(prefix="foldbot-cloth-") as tmp:
            # The mesh is written already in its world placement so vertex order and positions
            # can be checked one-to-one after loading.
            placed = ClothMesh(self.spawn_vertices - base, mesh.faces, mesh.keypoints)
            obj = placed.write_obj(Path(tmp) / "cloth.obj")
            self.body_id = p.loadSoftBody(
                str(obj),
                basePosition=base.tolist(),
                scale=1.0,
                mass=config.mass,
                useNeoHookean=0,
                useBendingSprings=1,
                useMassSpring=1,
                springElasticStiffness=config.elastic_stiffness,
                springDampingStiffness=config.damping_stiffness,
                springDampingAllDirections=0,
                springBendingStiffness=config.bending_stiffness,
                useSelfCollision=int(config.self_collision),
                frictionCoeff=config.body_friction,
                collisionMargin=self.margin,
                useFaceContact=1,
                physicsClientId=client,
            )
        if self.body_id < 0:
            raise RuntimeError("PyBullet failed to load the cloth soft body")
        p.changeVisualShape(
            self.body_id,
            -1,
            rgbaColor=list(config.rgba),
            flags=p.VISUAL_SHAPE_DOUBLE_SIDED,
            physicsClientId=client,
        )
        loaded = self._raw_vertices()
        if loaded.shape != self.spawn_vertices.shape:
            raise RuntimeError(
                f"PyBullet loaded {len(loaded)} cloth vertices, the mesh has "
                f"{len(self.spawn_vertices)}"
            )
        # PyBullet may reorder vertices; map loaded order back to the mesh's.
        order = np.argmin(
            np.linalg.norm(self.spawn_vertices[:, None, :] - loaded[None, :, :], axis=2), axis=1
        )
        if len(set(order.tolist())) != len(order):
            raise RuntimeError("could not match loaded cloth vertices to the mesh one-to-one")
        self._order = order
        self._anchors: set[int] = set()

    def anchor(self, vertex: int, body: int, link: int = -1) -> int:
        """Pin mesh vertex `vertex` to link `link` of rigid body `body` (a PyBullet soft-body
        anchor) and return its constraint id; the cloth counts as held until `release`."""
        anchor = p.createSoftBodyAnchor(
            self.body_id, self.sim_index(int(vertex)), body, link, physicsClientId=self.client
        )
        self._anchors.add(anchor)
        return anchor

    def release(self, anchor: int) -> None:
        """Remove an anchor made by `anchor`."""
        p.removeConstraint(anchor, physicsClientId=self.client)
        self._anchors.discard(anchor)

    @property
    def held(self) -> bool:
        """Whether anything holds the cloth (a gripper's or a helper's anchor)."""
        return bool(self._anchors)

    def _raw_vertices(self) -> np.ndarray:
        _, verts = p.getMeshData(
            self.body_id, -1, flags=p.MESH_DATA_SIMULATION_MESH, physicsClientId=self.client
        )
        return np.asarray(verts, dtype=np.float64)

    def node_positions(self) -> np.ndarray:
        """Vertex positions (V×3, world, m) in PyBullet's node order. Simulator state."""
        return self._raw_vertices()

    def set_node_positions(self, positions: np.ndarray) -> None:
        """Move the nodes (V×3, node order) where given; their velocities are kept."""
        p.resetMeshData(
            self.body_id, vertices=np.asarray(positions).tolist(), physicsClientId=self.client
        )

    def node_faces(self) -> np.ndarray:
        """The mesh's triangles (F×3) as PyBullet node indices."""
        return self._order[np.asarray(self.mesh.faces)]

    def sim_vertices(self) -> np.ndarray:
        """Vertex positions (V×3, world, m) in mesh order. Simulator state: sim-side use only."""
        return self._raw_vertices()[self._order]

    def sim_index(self, vertex: int) -> int:
        """PyBullet node index of mesh vertex `vertex` (for anchors)."""
        return int(self._order[vertex])

    def check_finite_and_bounded(self, center_xy: tuple[float, float], radius: float) -> np.ndarray:
        """Raise SimulationDivergedError on NaN or vertices far outside the workspace; return the
        vertices (mesh order) checked."""
        v = self.sim_vertices()
        if not np.all(np.isfinite(v)):
            raise SimulationDivergedError("cloth simulation diverged: non-finite vertex positions")
        d_xy = np.linalg.norm(v[:, :2] - np.asarray(center_xy), axis=1).max()
        z_lo = v[:, 2].min() - self.table_height
        z_hi = v[:, 2].max() - self.table_height
        broken = []
        if d_xy > radius:
            broken.append(
                f"a vertex lies {d_xy:.2f} m from the workspace centre (limit {radius:.2f} m)"
            )
        if z_lo < -MAX_DEPTH_UNDER_TABLE_M:
            broken.append(
                f"a vertex lies {-z_lo * 1000:.1f} mm under the table top (limit "
                f"{MAX_DEPTH_UNDER_TABLE_M * 1000:g} mm: it went through)"
            )
        if z_hi > MAX_HEIGHT_OVER_TABLE_M:
            broken.append(
                f"a vertex lies {z_hi:.2f} m over the table (limit {MAX_HEIGHT_OVER_TABLE_M:g} m)"
            )
        if broken:
            raise SimulationDivergedError("cloth simulation diverged: " + "; ".join(broken))
        return v


def keep_table_grip(world, config: ClothConfig) -> None:
    """Raise the table's friction by `config.table_friction_gain` (nothing to do unless
    `layer_friction` is set): the soft body's own coefficient scales cloth–table friction as
    well as cloth–cloth, and this keeps cloth–table at friction × the world's table friction."""
    if config.table_friction_gain != 1.0:
        world.set_table_friction(world.config.table_friction * config.table_friction_gain)


MAX_SLIDE_SPEED = 0.6
"""Fastest the cloth's centroid may move across the table (m/s) while nothing holds it. A cloth let
go of comes to rest; a heap blowing up slowly drifts as a whole, with nothing holding it (0.9 m/s
seen, `towel_crumpled_two_arms` seed 6 at 1/480 s): its vertices stay inside the bounds, so the
bounds alone let it run on as a cloth lost from view. While held (SoftCloth.held) the rule does
not apply: a towel hung from two points swings, its centroid faster than the hand (0.62–0.68 m/s
behind ideal grippers moving at 0.25 m/s, `scripts/measure_spread.py`)."""


class DivergenceMonitor:
    """A world step hook that checks the cloth every `every` steps and raises when it blows up:
    non-finite or out-of-bounds vertices, or, while nothing holds it, the whole cloth sliding
    across the table faster than `max_slide_speed` (m/s, its centroid's horizontal speed between
    two checks)."""

    def __init__(
        self,
        cloth: SoftCloth,
        center_xy: tuple[float, float],
        radius: float,
        every: int = 24,
        max_slide_speed: float = MAX_SLIDE_SPEED,
    ) -> None:
        self.cloth = cloth
        self.center_xy = center_xy
        self.radius = radius
        self.every = every
        self.max_slide_speed = max_slide_speed
        self.fastest_slide = 0.0
        """The fastest centroid speed across the table seen so far while nothing held the cloth
        (m/s)."""
        self._last: tuple[float, np.ndarray] | None = None

    def __call__(self, world) -> None:
        if world.steps % self.every:
            return
        centroid = self.cloth.check_finite_and_bounded(self.center_xy, self.radius)[:, :2].mean(0)
        if self.cloth.held:
            self._last = None  # an interval that spans a hold is not a slide
            return
        last, self._last = self._last, (world.sim_time, centroid)
        if last is None or world.sim_time <= last[0]:
            return
        speed = float(np.linalg.norm(centroid - last[1])) / (world.sim_time - last[0])
        self.fastest_slide = max(self.fastest_slide, speed)
        if speed > self.max_slide_speed:
            raise SimulationDivergedError(
                f"cloth simulation diverged: the whole cloth slid across the table at "
                f"{speed:.2f} m/s with nothing holding it (limit {self.max_slide_speed:.2f} m/s)"
            )


def settle(world, cloth: SoftCloth, max_time: float = 2.0, tol_speed: float = 0.002) -> float:
    """Step until every cloth vertex moves slower than `tol_speed` m/s; return the time taken (s)."""
    check_dt = 0.1
    n = max(1, round(check_dt / world.time_step))
    prev = cloth.sim_vertices()
    t = 0.0
    while t < max_time:
        world.step(n)
        t += n * world.time_step
        cur = cloth.sim_vertices()
        speed = np.linalg.norm(cur - prev, axis=1).max() / (n * world.time_step)
        prev = cur
        if speed < tol_speed and t >= 0.3:
            return t
    return t
