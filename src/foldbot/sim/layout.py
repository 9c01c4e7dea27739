"""Where things stand in the cell: table, robot base and the cloth workspace (world frame, metres).

World: z up, x away from the robot base across the table; the robot is mounted at the table's near edge.
"""

from __future__ import annotations

from dataclasses import dataclass, replace


@dataclass(frozen=True)
class CellLayout:
    """Geometry of the folding cell."""

    table_height: float = 0.75
    """Height of the table top above the floor (m)."""
    table_size: tuple[float, float] = (1.2, 1.2)
    """Table top extent along x and y (m)."""
    table_center_xy: tuple[float, float] = (0.45, 0.0)
    """Table top centre in the world (m)."""
    robot_base_xyz: tuple[float, float, float] = (0.0, 0.0, 0.75)
    """Robot base origin in the world (m); on the table top by default."""
    workspace_center_xy: tuple[float, float] = (0.45, 0.0)
    """Centre of the square cloth workspace on the table (m)."""
    workspace_size: float = 0.6
    """Side of the square cloth workspace (m); every point in it is reachable gripper-down."""
    home_xy: tuple[float, float] | None = None
    """Where the arm's home posture holds the TCP (table plane, m); None: over the workspace
    centre."""
    arm_spacing: float = 0.6
    """A two-arm cell: the bases stand this far apart (m) along y on the near edge, centred on
    `robot_base_xyz`; each arm's home (`home_xy`) is at the workspace centre's x and its own
    base's y, beside a towel of up to 45 cm rather than over it."""

    @property
    def workspace_bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the cloth workspace."""
        cx, cy = self.workspace_center_xy
        h = self.workspace_size / 2
        return (cx - h, cx + h, cy - h, cy + h)

    def arm_layouts(self, arms: int) -> tuple[CellLayout, ...]:
        """One layout per arm: the one-arm cell as it is, or two arms side by side (arm 0 on the
        left, +y; arm 1 on the right), each with its base and home moved to its own side."""
        if arms == 1:
            return (self,)
        if arms != 2:
            raise ValueError(f"a cell has 1 or 2 arms, got {arms!r}")
        bx, by, bz = self.robot_base_xyz
        cx, _ = self.workspace_center_xy
        return tuple(
            replace(
                self,
                robot_base_xyz=(bx, by + side * self.arm_spacing / 2, bz),
                home_xy=(cx, by + side * self.arm_spacing / 2),
            )
            for side in (1.0, -1.0)
        )


DEFAULT_LAYOUT = CellLayout()
