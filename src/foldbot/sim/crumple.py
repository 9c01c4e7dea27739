"""Crumpled starts: a settled flat cloth is pinched, lifted, dragged and dropped by a helper body.

The helper is a small rigid body that collides with nothing, driven along a path by a fixed
constraint; the pinched vertices are soft-body anchors to it (a body with mass: anchors to static
bodies are reported to blow the cloth up). Everything is drawn from the caller's seeded generator,
so a crumple is as reproducible as the physics (the first simulation in its process). The helper
and its anchors are removed before returning; the cloth rests on the table in the workspace.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p

from foldbot.errors import FoldbotError, require
from foldbot.sim.cloth import SoftCloth, settle

CRUMPLE_STYLES = ("fold", "hang")
"""CrumpleConfig.style values."""


def _range(name: str, value: tuple[float, float], lo: float, hi: float) -> None:
    a, b = value
    require(
        math.isfinite(a) and math.isfinite(b) and lo <= a <= b <= hi,
        f"CrumpleConfig.{name} must satisfy {lo} ≤ low ≤ high ≤ {hi}, got {value!r}",
    )


@dataclass(frozen=True)
class CrumpleConfig:
    """How a cloth is crumpled: pinch-lift-drag-drop cycles, each drawn from the seed."""

    style: str = "fold"
    """fold: lift the pinched point where it lies and carry it across the cloth, laying the
    hanging part over the rest; hang: lift it beside the parked arm (the whole cloth hangs) and
    lay it down towards the workspace centre, which heaps the cloth higher."""
    pinches: tuple[int, int] = (1, 1)
    """Number of pinch-lift-drop cycles, uniform integer in [low, high]. One already heaps the
    cloth (coverage ~0.3–0.7); pinching a heap again made Bullet's cloth diverge (measured)."""
    lift_height: tuple[float, float] = (0.20, 0.35)
    """Height the pinched point is lifted to above the table (m)."""
    hold_radius: tuple[float, float] = (0.14, 0.20)
    """hang: horizontal distance of the lift point from the workspace centre (m); the parked
    arm's gripper hangs ~0.24 m over the centre, so the lifted cloth is held beside it."""
    fold_spread: float = math.pi / 4
    """fold: the carry heads towards the cloth's centroid turned by up to ± this (rad)."""
    arm_clear_radius: float = 0.12
    """fold: a pinch this close (m) to the workspace centre, under the parked gripper, …"""
    arm_clear_height: float = 0.16
    """… is lifted no higher than this (m above the table)."""
    drag: tuple[float, float] = (0.2, 0.6)
    """Travel while lowering, before release, as a fraction of the flat cloth's diagonal
    (fold: across the cloth; hang: towards and past the workspace centre): lays the hanging
    cloth down in overlapping folds."""
    drag_height: float = 0.12
    """Before the drag the pinched point comes straight down to this height (m), so the cloth
    passes under the parked arm's gripper (~0.24 m above the table)."""
    release_height: tuple[float, float] = (0.02, 0.08)
    """Height of the pinched point above the table when it is let go (m)."""
    grip_points: tuple[int, int] = (1, 2)
    """Cloth points held together per pinch, uniform integer in [low, high]: two points (one
    helper, their distance kept) hang the cloth as a curtain, which lands less bunched."""
    pinch_radius: float = 1.1
    """Vertices within this many mean edge lengths of the picked vertex are pinched with it."""
    speed: float = 0.4
    """Helper speed along its path (m/s)."""
    hold_time: float = 0.4
    """Pause at the top of the lift, letting the hanging cloth swing out (s)."""
    helper_mass: float = 0.2
    """Mass of the helper body (kg)."""
    max_force: float = 200.0
    """Force limit of the constraint that drives the helper (N)."""
    settle_time: float = 2.0
    """Longest settling after each drop (s)."""
    margin: float = 0.02
    """The cloth must end this far inside the workspace square (m); if it does not, the helper
    carries the whole crumpled cloth (every vertex anchored) back in, a few mm above the table."""

    def __post_init__(self) -> None:
        lo, hi = self.pinches
        require(
            isinstance(lo, int) and isinstance(hi, int) and 1 <= lo <= hi <= 5,
            f"CrumpleConfig.pinches must satisfy 1 ≤ low ≤ high ≤ 5 (integers), got {self.pinches!r}",
        )
        g0, g1 = self.grip_points
        require(
            isinstance(g0, int) and isinstance(g1, int) and 1 <= g0 <= g1 <= 2,
            f"CrumpleConfig.grip_points must satisfy 1 ≤ low ≤ high ≤ 2 (integers), got {self.grip_points!r}",
        )
        require(
            self.style in CRUMPLE_STYLES,
            f"CrumpleConfig.style must be one of {', '.join(CRUMPLE_STYLES)}, got {self.style!r}",
        )
        _range("lift_height", self.lift_height, 0.05, 0.6)
        _range("hold_radius", self.hold_radius, 0.0, 0.3)
        _range("drag", self.drag, 0.0, 2.0)
        _range("release_height", self.release_height, 0.0, 0.3)
        for name, lo_v, hi_v in (
            ("pinch_radius", 0.0, 5.0),
            ("drag_height", 0.0, 0.2),
            ("fold_spread", 0.0, math.pi),
            ("arm_clear_radius", 0.0, 0.3),
            ("arm_clear_height", 0.02, 0.6),
            ("speed", 0.01, 2.0),
            ("hold_time", 0.0, 5.0),
            ("helper_mass", 0.001, 10.0),
            ("max_force", 1.0, 1e4),
            ("settle_time", 0.1, 10.0),
            ("margin", 0.0, 0.2),
        ):
            v = getattr(self, name)
            require(
                math.isfinite(v) and lo_v <= v <= hi_v,
                f"CrumpleConfig.{name} must be in [{lo_v}, {hi_v}], got {v!r}",
            )


@dataclass(frozen=True)
class CrumpleResult:
    """What a crumple did (world frame, m): per pinch the picked vertex and its path corners."""

    pinches: tuple[dict, ...]
    recentred: bool
    """True when the cloth had to be carried back into the workspace."""
    sim_seconds: float


class _Helper:
    """A collision-free rigid body moved by a fixed constraint; cloth vertices anchor to it."""

    def __init__(self, world, position: np.ndarray, cfg: CrumpleConfig) -> None:
        self.world = world
        self.client = world.client
        self.cfg = cfg
        self.body = p.createMultiBody(
            baseMass=cfg.helper_mass,
            baseCollisionShapeIndex=-1,
            baseVisualShapeIndex=-1,
            basePosition=position.tolist(),
            physicsClientId=self.client,
        )
        self.constraint = p.createConstraint(
            self.body,
            -1,
            -1,
            -1,
            p.JOINT_FIXED,
            [0, 0, 0],
            [0, 0, 0],
            position.tolist(),
            physicsClientId=self.client,
        )
        p.changeConstraint(self.constraint, maxForce=cfg.max_force, physicsClientId=self.client)
        self.position = np.asarray(position, dtype=float)
        self.cloth: SoftCloth | None = None
        self.anchors: list[int] = []

    def attach(self, cloth: SoftCloth, vertices: np.ndarray) -> None:
        self.cloth = cloth
        for v in vertices:
            self.anchors.append(cloth.anchor(int(v), self.body))

    def move(self, path: list[np.ndarray], speed: float) -> None:
        """Drive the helper through the waypoints at `speed` (m/s), one pivot update per step."""
        dt = self.world.time_step
        for target in path:
            target = np.asarray(target, dtype=float)
            dist = float(np.linalg.norm(target - self.position))
            n = max(1, math.ceil(dist / (speed * dt)))
            start = self.position
            for k in range(1, n + 1):
                self.position = start + (target - start) * (k / n)
                p.changeConstraint(
                    self.constraint,
                    jointChildPivot=self.position.tolist(),
                    maxForce=self.cfg.max_force,
                    physicsClientId=self.client,
                )
                self.world.step()

    def hold(self, seconds: float) -> None:
        self.world.step(max(0, round(seconds / self.world.time_step)))

    def remove(self) -> None:
        for a in self.anchors:
            self.cloth.release(a)
        self.anchors.clear()
        p.removeConstraint(self.constraint, physicsClientId=self.client)
        p.removeBody(self.body, physicsClientId=self.client)


def _pinched(cloth: SoftCloth, centre_vertex: int, radius: float) -> np.ndarray:
    """Mesh vertices within `radius` (m, in the flat mesh) of `centre_vertex`."""
    flat = cloth.mesh.vertices
    d = np.linalg.norm(flat - flat[centre_vertex], axis=1)
    return np.flatnonzero(d <= radius)


def _out_of_workspace(cloth: SoftCloth, bounds: tuple[float, float, float, float], margin: float):
    """(dx, dy) that moves the cloth's top-view bounding box inside `bounds` shrunk by margin."""
    v = cloth.sim_vertices()
    lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)
    x0, x1, y0, y1 = bounds
    shift = np.zeros(2)
    for k, (blo, bhi) in enumerate(((x0 + margin, x1 - margin), (y0 + margin, y1 - margin))):
        if hi[k] - lo[k] > bhi - blo:
            shift[k] = 0.5 * (blo + bhi) - 0.5 * (lo[k] + hi[k])
        elif lo[k] < blo:
            shift[k] = blo - lo[k]
        elif hi[k] > bhi:
            shift[k] = bhi - hi[k]
    return shift


def crumple(
    world,
    cloth: SoftCloth,
    rng: np.random.Generator,
    config: CrumpleConfig | None = None,
) -> CrumpleResult:
    """Crumple the settled cloth physically: per pinch, anchor a random vertex (and its
    neighbours) to a helper body, lift it beside the parked arm, drag it down towards the
    workspace centre, let go and settle; then make sure the cloth lies in the workspace."""
    cfg = config or CrumpleConfig()
    layout = world.layout
    table = layout.table_height
    centre = np.asarray(layout.workspace_center_xy, dtype=float)
    t0 = world.sim_time
    flat = cloth.mesh.vertices[:, :2]
    diagonal = float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
    n_pinch = int(rng.integers(cfg.pinches[0], cfg.pinches[1] + 1))
    log = []
    for _ in range(n_pinch):
        verts = cloth.sim_vertices()
        vid = int(rng.integers(len(verts)))
        grip = [vid]
        if int(rng.integers(cfg.grip_points[0], cfg.grip_points[1] + 1)) == 2:
            # The second point lies 0.3–0.6 of the diagonal away in the flat cloth.
            d = np.linalg.norm(cloth.mesh.vertices - cloth.mesh.vertices[vid], axis=1)
            far = np.flatnonzero((d >= 0.3 * diagonal) & (d <= 0.6 * diagonal))
            if far.size:
                grip.append(int(far[rng.integers(far.size)]))
        lift = float(rng.uniform(*cfg.lift_height))
        angle = float(rng.uniform(-math.pi, math.pi))
        radius = float(rng.uniform(*cfg.hold_radius))
        drag = float(rng.uniform(*cfg.drag)) * diagonal
        release = float(rng.uniform(*cfg.release_height))
        jitter = rng.uniform(-0.03, 0.03, size=2)
        turn = float(rng.uniform(-cfg.fold_spread, cfg.fold_spread))
        start = verts[grip].mean(axis=0)
        if cfg.style == "hang":
            # Lift beside the parked arm, down, then towards (and past) the centre: the hanging
            # cloth is laid down along the drag.
            direction = np.array([math.cos(angle), math.sin(angle)])
            top = np.r_[centre + radius * direction, table + lift]
            direction = -direction
        else:
            # Lift in place (lower under the parked gripper), then carry across the cloth:
            # the hanging part is laid over the rest.
            to_mid = verts[:, :2].mean(axis=0) - start[:2]
            base = math.atan2(to_mid[1], to_mid[0]) if np.linalg.norm(to_mid) > 0.02 else angle
            direction = np.array([math.cos(base + turn), math.sin(base + turn)])
            under_arm = np.linalg.norm(start[:2] - centre) < cfg.arm_clear_radius
            top = np.r_[start[:2], table + (min(lift, cfg.arm_clear_height) if under_arm else lift)]
        low = np.r_[top[:2], table + max(cfg.drag_height, release)]
        bottom = np.r_[top[:2] + drag * direction + jitter, table + release]
        helper = _Helper(world, start, cfg)
        try:
            r = cfg.pinch_radius * cloth.mesh.edge_length
            helper.attach(cloth, np.unique(np.concatenate([_pinched(cloth, g, r) for g in grip])))
            up = np.r_[start[:2], min(top[2], table + 0.08)]
            helper.move([up, top], cfg.speed)
            helper.hold(cfg.hold_time)
            helper.move([low, bottom], cfg.speed)
        finally:
            helper.remove()
        settle(world, cloth, max_time=cfg.settle_time)
        log.append(
            {
                "vertices": grip,
                "lift_point": top.tolist(),
                "release_point": bottom.tolist(),
            }
        )
    shift = _out_of_workspace(cloth, layout.workspace_bounds, cfg.margin)
    recentred = bool(np.any(shift != 0.0))
    if recentred:
        _carry_all(world, cloth, shift, cfg)
    v = cloth.sim_vertices()
    if np.any(np.abs(_out_of_workspace(cloth, layout.workspace_bounds, 0.0)) > 1e-3):
        raise FoldbotError(
            "crumple left the cloth outside the workspace: top-view bounds "
            f"{np.round(v[:, :2].min(axis=0), 3).tolist()}..{np.round(v[:, :2].max(axis=0), 3).tolist()} m"
        )
    return CrumpleResult(tuple(log), recentred, world.sim_time - t0)


def _carry_all(world, cloth: SoftCloth, shift: np.ndarray, cfg: CrumpleConfig) -> None:
    """Carry the whole cloth rigidly by `shift` (m, in the table plane), 5 mm above the table."""
    verts = cloth.sim_vertices()
    start = verts.mean(axis=0)
    helper = _Helper(world, start, cfg)
    try:
        helper.attach(cloth, np.arange(len(verts)))
        lifted = start + [0.0, 0.0, 0.005]
        helper.move([lifted, lifted + [shift[0], shift[1], 0.0]], cfg.speed / 2)
    finally:
        helper.remove()
    settle(world, cloth, max_time=cfg.settle_time)
