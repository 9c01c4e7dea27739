"""Where things stand in the cell: table, robot base and the cloth workspace (world frame, metres).

World: z up, x away from the robot base across the table; the robot is mounted at the table's near edge.
"""

from __future__ import annotations

from dataclasses import dataclass


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

    @property
    def workspace_bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the cloth workspace."""
        cx, cy = self.workspace_center_xy
        h = self.workspace_size / 2
        return (cx - h, cx + h, cy - h, cy + h)


DEFAULT_LAYOUT = CellLayout()
