"""The PyBullet world of the cell: deformable-world client, gravity, time step, floor and table."""

from __future__ import annotations

import contextlib
import math
import os
from dataclasses import dataclass, field

import pybullet as p

from foldbot.errors import ConfigError, require
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout, Obstacle

MIN_TIME_STEP = 1e-4
"""Shortest physics step (s) accepted: 10 kHz; shorter settles a cloth for hours."""
MAX_TIME_STEP = 0.02
"""Longest physics step (s) accepted: 50 Hz; the cloth blows up well before."""
OBSTACLE_RGBA = (0.45, 0.47, 0.5, 1.0)
"""Colour of a layout's obstacles (grey)."""


@dataclass(frozen=True)
class SimConfig:
    """Physics settings of the world."""

    time_step: float = 1.0 / 360.0
    """Physics step (s). At 1/240 s folded layers of a 16×16 towel sometimes pass through each
    other or the table, and pressing a carried corner onto the lower layer can blow up; 1/360 s
    keeps the layers apart."""
    gravity: float = 9.81
    """Gravitational acceleration (m/s²), pointing down −z."""
    table_friction: float = 1.0
    """Lateral friction coefficient of the table top."""
    table_rgba: tuple[float, float, float, float] = (0.55, 0.45, 0.35, 1.0)
    """Table colour (RGBA 0..1)."""
    gui: bool = False
    """Open the PyBullet GUI instead of running headless (DIRECT)."""
    layout: CellLayout = field(default_factory=lambda: DEFAULT_LAYOUT)
    """Geometry of the cell."""

    def __post_init__(self) -> None:
        require(
            MIN_TIME_STEP <= self.time_step <= MAX_TIME_STEP,
            f"time_step must be in [{MIN_TIME_STEP:g}, {MAX_TIME_STEP:g}] s, got "
            f"{self.time_step!r}",
        )
        require(self.gravity >= 0.0, f"gravity must be ≥ 0 m/s², got {self.gravity!r}")
        require(
            self.table_friction >= 0.0,
            f"table_friction must be ≥ 0, got {self.table_friction!r}",
        )


class SimWorld:
    """A PyBullet client set up as PyBullet's deformable world, with floor and table; owns sim time."""

    def __init__(self, config: SimConfig | None = None) -> None:
        self.config = config or SimConfig()
        self.layout = self.config.layout
        if self.config.gui and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise ConfigError(
                "--gui needs a display, but DISPLAY is not set; run headless without --gui"
            )
        mode = p.GUI if self.config.gui else p.DIRECT
        self.client = p.connect(mode)
        if self.client < 0:
            raise RuntimeError("could not connect to PyBullet (is another GUI already open?)")
        # The deformable world is required: the legacy soft-body world ignores spring parameters
        # and anchors to moving bodies do not move the cloth.
        p.resetSimulation(p.RESET_USE_DEFORMABLE_WORLD, physicsClientId=self.client)
        p.setGravity(0, 0, -self.config.gravity, physicsClientId=self.client)
        p.setTimeStep(self.config.time_step, physicsClientId=self.client)
        if self.config.gui:
            p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, physicsClientId=self.client)
            cx, cy = self.layout.workspace_center_xy
            p.resetDebugVisualizerCamera(
                1.3, 60, -40, [cx, cy, self.layout.table_height], physicsClientId=self.client
            )
        self.table_id = self._make_table()
        self.obstacle_ids: dict[str, int] = {
            o.name: self._make_obstacle(o) for o in self.layout.obstacles
        }
        """The layout's obstacles' body ids by name (static boxes the arm plans clear of)."""
        self.sim_time = 0.0
        self.steps = 0
        self._step_hooks: list = []
        self._idle_hooks: list = []

    def _make_table(self) -> int:
        lay = self.layout
        half = [lay.table_size[0] / 2, lay.table_size[1] / 2, lay.table_height / 2]
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=self.client)
        vis = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=half,
            rgbaColor=list(self.config.table_rgba),
            physicsClientId=self.client,
        )
        body = p.createMultiBody(
            0,
            col,
            vis,
            basePosition=[lay.table_center_xy[0], lay.table_center_xy[1], lay.table_height / 2],
            physicsClientId=self.client,
        )
        p.changeDynamics(
            body, -1, lateralFriction=self.config.table_friction, physicsClientId=self.client
        )
        return body

    def _make_obstacle(self, obstacle: Obstacle) -> int:
        """A static grey box where the layout puts `obstacle`."""
        half = [v / 2 for v in obstacle.size_xyz]
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=self.client)
        vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=half, rgbaColor=list(OBSTACLE_RGBA), physicsClientId=self.client
        )
        turn = p.getQuaternionFromEuler([0.0, 0.0, math.radians(obstacle.yaw_deg)])
        return p.createMultiBody(
            0,
            col,
            vis,
            basePosition=list(obstacle.center_xyz),
            baseOrientation=turn,
            physicsClientId=self.client,
        )

    @property
    def time_step(self) -> float:
        return self.config.time_step

    def set_table_friction(self, friction: float) -> None:
        """Set the table top's lateral friction coefficient (the cloth's `layer_friction` raises it
        to keep cloth–table friction)."""
        require(friction >= 0.0, f"table friction must be ≥ 0, got {friction!r}")
        p.changeDynamics(self.table_id, -1, lateralFriction=friction, physicsClientId=self.client)

    def set_table_color(self, rgba: tuple[float, float, float, float]) -> None:
        """Recolour the table top (used by scene randomisation)."""
        p.changeVisualShape(self.table_id, -1, rgbaColor=list(rgba), physicsClientId=self.client)

    def add_step_hook(self, hook, on_idle: bool = False) -> None:
        """Call `hook(world)` after every physics step (divergence monitors, the crossing guard);
        with `on_idle`, after every tick of `idle` too (what follows the clock: publishing)."""
        self._step_hooks.append(hook)
        if on_idle:
            self._idle_hooks.append(hook)

    def remove_step_hook(self, hook) -> None:
        """Stop calling `hook` (added by add_step_hook)."""
        self._step_hooks.remove(hook)
        if hook in self._idle_hooks:
            self._idle_hooks.remove(hook)

    def step(self, n: int = 1) -> None:
        """Advance the physics by n steps and run the hooks."""
        for _ in range(n):
            p.stepSimulation(physicsClientId=self.client)
            self._tick(self._step_hooks)

    def idle(self, n: int = 1) -> None:
        """Advance the clock by n steps without stepping the physics, running only the hooks
        added `on_idle` (nothing moved for the others to watch): a cell at rest
        (sim.rest.RestWatch) stays as it is, as a real one does, instead of a resting soft body
        creeping until it blows up."""
        for _ in range(n):
            self._tick(self._idle_hooks)

    def _tick(self, hooks: list) -> None:
        self.steps += 1
        self.sim_time += self.config.time_step
        for hook in hooks:
            hook(self)

    def close(self) -> None:
        """Disconnect the client (idempotent)."""
        if self.client >= 0:
            with contextlib.suppress(p.error):
                p.disconnect(physicsClientId=self.client)
            self.client = -1

    def __enter__(self) -> SimWorld:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
