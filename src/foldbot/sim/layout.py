"""Where things stand in the cell: table, robot base and the cloth workspace (world frame, metres).

World: z up, x away from the robot base across the table; the robot is mounted at the table's near
edge, its base's x axis along world +x. A cell laid out otherwise (a lower table, an arm on a
pedestal beside it, the cloth further out) is a layout file: `foldbot fold --layout FILE.toml`,
its keys CellLayout's fields (load_layout). The simulated cell is then built as the file says,
and a real cell (`foldbot ros-fold --cell real`) is planned for it.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from foldbot.errors import ConfigError, require


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
    """Side of the square cloth workspace (m); every point in it should be reachable gripper
    down (`foldbot check-layout` checks it over a grid; a fold checks the centre)."""
    home_xy: tuple[float, float] | None = None
    """Where the arm's home posture holds the TCP (table plane, m); None: over the workspace
    centre."""
    arm_spacing: float = 0.6
    """A two-arm cell: the bases stand this far apart (m) along y on the near edge, centred on
    `robot_base_xyz`; each arm's home (`home_xy`) is at the workspace centre's x and its own
    base's y, beside a towel of up to 45 cm rather than over it."""

    def __post_init__(self) -> None:
        def numbers(name: str, count: int) -> tuple[float, ...]:
            value = getattr(self, name)
            try:
                out = tuple(float(v) for v in value)
            except (TypeError, ValueError):
                out = ()
            if (
                len(out) != count
                or not all(math.isfinite(v) for v in out)
                or any(isinstance(v, bool) for v in value)
            ):
                raise ConfigError(
                    f"layout {name} must be {count} finite numbers (m), got {value!r}"
                )
            object.__setattr__(self, name, out)
            return out

        def number(name: str, lo: float, hi: float) -> float:
            value = getattr(self, name)
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not (ok and math.isfinite(value) and lo < value <= hi):
                raise ConfigError(
                    f"layout {name} must be a number in ({lo:g}, {hi:g}] m, got {value!r}"
                )
            object.__setattr__(self, name, float(value))
            return float(value)

        number("table_height", 0.0, 2.0)
        number("workspace_size", 0.1, 2.0)
        number("arm_spacing", 0.0, 2.0)
        sx, sy = numbers("table_size", 2)
        require(sx > 0.0 and sy > 0.0, f"layout table_size must be > 0 m each, got {(sx, sy)!r}")
        tx, ty = numbers("table_center_xy", 2)
        numbers("robot_base_xyz", 3)
        numbers("workspace_center_xy", 2)
        if self.home_xy is not None:
            numbers("home_xy", 2)
        x0, x1, y0, y1 = self.workspace_bounds
        eps = 1e-9
        require(
            tx - sx / 2 - eps <= x0 and x1 <= tx + sx / 2 + eps
            and ty - sy / 2 - eps <= y0 and y1 <= ty + sy / 2 + eps,
            f"layout workspace (x {x0:.3f}–{x1:.3f}, y {y0:.3f}–{y1:.3f} m: workspace_center_xy "
            f"± workspace_size / 2) must lie on the table top (x {tx - sx / 2:.3f}–"
            f"{tx + sx / 2:.3f}, y {ty - sy / 2:.3f}–{ty + sy / 2:.3f} m: table_center_xy ± "
            "table_size / 2)",
        )  # fmt: skip
        bx, by, bz = self.robot_base_xyz
        on_table = abs(bx - tx) < sx / 2 and abs(by - ty) < sy / 2
        require(
            not on_table or bz >= self.table_height - eps,
            f"layout robot_base_xyz {self.robot_base_xyz!r} stands inside the table (its top at "
            f"{self.table_height:g} m over x {tx - sx / 2:.3f}–{tx + sx / 2:.3f}, y "
            f"{ty - sy / 2:.3f}–{ty + sy / 2:.3f} m): mount the arm on the top (base z = "
            "table_height) or beside the table (table_center_xy and table_size leaving its "
            "xy off the top)",
        )
        require(
            x0 - bx >= MIN_BASE_CLEARANCE - eps,
            f"layout workspace must lie at least {MIN_BASE_CLEARANCE:g} m ahead of the robot base "
            f"along +x (the arm faces +x): its near edge is at x = {x0:.3f} m, the base at "
            f"x = {bx:.3f} m",
        )

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

    def workspace_shift(self) -> tuple[float, float, float]:
        """How far (m) this layout's workspace centre and table top lie from the default
        layout's (dx, dy, dz): what a setting placed for the default cell (the simulated
        camera's pose, the flattening's region) moves by."""
        (cx, cy), (dcx, dcy) = self.workspace_center_xy, DEFAULT_LAYOUT.workspace_center_xy
        return (cx - dcx, cy - dcy, self.table_height - DEFAULT_LAYOUT.table_height)

    def base_shift(self) -> tuple[float, float, float]:
        """How far (m) this layout's robot base lies from the default layout's: what a setting
        placed by the arm's reach (how far out a spread can hold the towel) moves by."""
        return tuple(
            a - b for a, b in zip(self.robot_base_xyz, DEFAULT_LAYOUT.robot_base_xyz, strict=True)
        )

    def changes(self) -> dict[str, object]:
        """The fields that differ from the default layout (plain JSON: tuples as lists), as
        result.json records them."""
        out: dict[str, object] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if value != getattr(DEFAULT_LAYOUT, f.name):
                out[f.name] = list(value) if isinstance(value, tuple) else value
        return out


MIN_BASE_CLEARANCE = 0.1
"""Least distance (m) along +x from the robot base to the workspace's near edge: the arm cannot
fold cloth over its own base (the default cell leaves 0.15 m)."""

DEFAULT_LAYOUT = CellLayout()

LAYOUT_FIELDS = tuple(f.name for f in dataclasses.fields(CellLayout))
"""The keys a layout file may set."""


def layout_from_table(table: Mapping[str, object], where: str) -> CellLayout:
    """A CellLayout from a table of its fields (the rest at their defaults); ConfigError naming
    `where`, the bad key or value and what is allowed."""
    if not isinstance(table, Mapping):
        raise ConfigError(f"{where}: a layout is a table of name = value, got {table!r}")
    unknown = sorted(set(table) - set(LAYOUT_FIELDS))
    if unknown:
        raise ConfigError(
            f"{where}: unknown layout key{'s' if len(unknown) > 1 else ''} "
            f"{', '.join(map(repr, unknown))}; allowed: {', '.join(LAYOUT_FIELDS)}"
        )
    try:
        return CellLayout(**table)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def load_layout(path: str | Path) -> CellLayout:
    """The cell layout a TOML file gives (keys: LAYOUT_FIELDS, metres in the world frame; the
    rest at their defaults); ConfigError naming the file and what is wrong with it."""
    p = Path(path)
    if not p.is_file():
        what = "is a folder, not a file" if p.is_dir() else "does not exist"
        raise ConfigError(f"layout file {str(p)!r} {what} (a .toml of {', '.join(LAYOUT_FIELDS)})")
    try:
        table = tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"layout file {str(p)!r} is not valid TOML: {exc}") from None
    return layout_from_table(table, f"layout file {str(p)!r}")
