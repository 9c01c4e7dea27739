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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from foldbot.errors import ConfigError, require

OBSTACLE_CLEARANCE = 0.02
"""Least distance (m) every planned arm pose keeps from a layout's obstacles (its links and
fingers; the table keeps control.executor's TABLE_CLEARANCE): a real fixture is measured by hand
and drawn as a box, so the arm keeps a margin from it."""
OBSTACLE_FIELDS = ("name", "center_xyz", "size_xyz", "yaw_deg")
"""The keys of a layout file's `[[obstacles]]` table (yaw_deg may be left out: 0)."""
WORKSPACE_CLEAR_HEIGHT = 0.3
"""Height (m) over the cloth workspace an obstacle may not reach into: the cloth, its folds and
the carries' arcs (a 45 cm towel's peaks 0.23 m up) need it clear."""


def finite_numbers(value: object, count: int) -> tuple[float, ...] | None:
    """`value` as `count` finite floats, or None where it is not that (booleans refused)."""
    try:
        out = tuple(float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        return None
    if len(out) != count or not all(math.isfinite(v) for v in out):
        return None
    if any(isinstance(v, bool) for v in value):  # type: ignore[union-attr]
        return None
    return out


@dataclass(frozen=True)
class Obstacle:
    """A fixed box in the cell that the arm must keep clear of (a camera's post, a wall, a bin,
    a light): its name, its centre and its size along its own x, y and z (world frame, m), turned
    `yaw_deg` about the vertical (0: its sides along the world's axes). The simulated cell builds
    it; every planned motion keeps OBSTACLE_CLEARANCE from it, in process and over ROS, in the
    simulated cell or a real one."""

    name: str
    center_xyz: tuple[float, float, float]
    size_xyz: tuple[float, float, float]
    yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        name = self.name
        ok_name = (
            isinstance(name, str) and name != "" and all(c.isalnum() or c in "_-" for c in name)
        )
        if not ok_name:
            raise ConfigError(
                f"an obstacle's name must be a non-empty word (letters, digits, _ and -), got "
                f"{name!r}"
            )
        for key in ("center_xyz", "size_xyz"):
            value = getattr(self, key)
            out = finite_numbers(value, 3)
            if out is None:
                raise ConfigError(
                    f"obstacle {name!r}: {key} must be 3 finite numbers (m), got {value!r}"
                )
            object.__setattr__(self, key, out)
        if not all(0.0 < v <= 10.0 for v in self.size_xyz):
            raise ConfigError(
                f"obstacle {name!r}: size_xyz must be 3 sizes in (0, 10] m, got "
                f"{list(self.size_xyz)!r}"
            )
        yaw = self.yaw_deg
        if isinstance(yaw, bool) or not isinstance(yaw, int | float) or not -360 <= yaw <= 360:
            raise ConfigError(
                f"obstacle {name!r}: yaw_deg must be degrees in [-360, 360], got {yaw!r}"
            )
        object.__setattr__(self, "yaw_deg", float(yaw))

    def footprint(self) -> tuple[tuple[float, float], ...]:
        """The box's four corners seen from above (world xy, m), counter-clockwise."""
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        hx, hy = self.size_xyz[0] / 2, self.size_xyz[1] / 2
        x, y = self.center_xyz[:2]
        return tuple(
            (x + c * u - s * v, y + s * u + c * v)
            for u, v in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))
        )

    def overlaps_area(self, x0: float, x1: float, y0: float, y1: float) -> bool:
        """Whether its footprint overlaps the rectangle x0–x1, y0–y1 (world m) by more than a
        touch (separating axes: the rectangle's two and the box's two)."""
        box = self.footprint()
        area = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        for ax, ay in ((1.0, 0.0), (0.0, 1.0), (c, s), (-s, c)):
            a = [ax * x + ay * y for x, y in box]
            b = [ax * x + ay * y for x, y in area]
            if max(a) <= min(b) + 1e-12 or max(b) <= min(a) + 1e-12:
                return False
        return True

    @property
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """(lowest corner, highest corner) of the box's extent along the world's axes (m): the
        box itself where it is not turned."""
        xs, ys = zip(*self.footprint(), strict=True)
        z, hz = self.center_xyz[2], self.size_xyz[2] / 2
        return (min(xs), min(ys), z - hz), (max(xs), max(ys), z + hz)

    def to_local(self, points: Sequence[float] | np.ndarray) -> np.ndarray:
        """World points (…×3, m) in the box's own frame (its centre, its sides' axes)."""
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        d = np.asarray(points, dtype=np.float64) - np.asarray(self.center_xyz)
        return np.stack(
            [c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1], d[..., 2]], axis=-1
        )

    def corners(self, margin: float = 0.0) -> np.ndarray:
        """The box's 8 corners (8×3 world m), grown by `margin` on every side."""
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        hx, hy, hz = (v / 2 + margin for v in self.size_xyz)
        local = np.array([(u, v, w) for u in (-hx, hx) for v in (-hy, hy) for w in (-hz, hz)])
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return local @ rot.T + np.asarray(self.center_xyz)

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Bool per world point (…×3, m): whether it lies inside the box grown by `margin` on
        every side (what a depth camera sees of the box, less its noise)."""
        half = np.asarray(self.size_xyz) / 2 + margin
        return (np.abs(self.to_local(points)) <= half).all(axis=-1)

    def blocks(self, start: Sequence[float], end: Sequence[float]) -> bool:
        """Whether the straight segment from `start` to `end` (world m) passes through the box
        (a camera's line of sight to a point on the table)."""
        h = tuple(v / 2 for v in self.size_xyz)
        lo, hi = tuple(-v for v in h), h
        t0, t1 = 0.0, 1.0
        a_local, b_local = self.to_local(start).tolist(), self.to_local(end).tolist()
        for a, b, low, high in zip(a_local, b_local, lo, hi, strict=True):
            d = float(b) - float(a)
            if abs(d) < 1e-12:
                if not low <= a <= high:
                    return False
                continue
            ta, tb = (low - a) / d, (high - a) / d
            t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
            if t0 > t1:
                return False
        return True

    def as_dict(self) -> dict[str, object]:
        """As a layout file's `[[obstacles]]` table (plain JSON; yaw_deg where turned)."""
        turned = {"yaw_deg": self.yaw_deg} if self.yaw_deg else {}
        return {
            "name": self.name,
            "center_xyz": list(self.center_xyz),
            "size_xyz": list(self.size_xyz),
            **turned,
        }


def obstacle_from_table(table: object, where: str) -> Obstacle:
    """An Obstacle from a layout file's `[[obstacles]]` table; ConfigError naming `where`, the
    bad or missing key and what is allowed."""
    if isinstance(table, Obstacle):
        return table
    if not isinstance(table, Mapping):
        raise ConfigError(
            f"{where}: an obstacle is a table of {', '.join(OBSTACLE_FIELDS)}, got {table!r}"
        )
    unknown = sorted(set(table) - set(OBSTACLE_FIELDS))
    missing = [k for k in OBSTACLE_FIELDS if k not in table and k != "yaw_deg"]
    if unknown or missing:
        what = []
        if unknown:
            plural = "s" if len(unknown) > 1 else ""
            what.append(f"unknown key{plural} {', '.join(map(repr, unknown))}")
        if missing:
            what.append(f"missing {', '.join(map(repr, missing))}")
        raise ConfigError(
            f"{where}: {'; '.join(what)}; an obstacle has {', '.join(OBSTACLE_FIELDS[:-1])} "
            "and may have yaw_deg"
        )
    try:
        return Obstacle(**dict(table))
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


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
    obstacles: tuple[Obstacle, ...] = ()
    """Fixed boxes in the cell the arm keeps OBSTACLE_CLEARANCE from (a layout file's
    `[[obstacles]]` tables: name, center_xyz, size_xyz); none may reach into the cloth workspace
    up to WORKSPACE_CLEAR_HEIGHT over the table."""

    def __post_init__(self) -> None:
        def numbers(name: str, count: int) -> tuple[float, ...]:
            value = getattr(self, name)
            out = finite_numbers(value, count)
            if out is None:
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
        self._check_obstacles()
        require(
            x0 - bx >= MIN_BASE_CLEARANCE - eps,
            f"layout workspace must lie at least {MIN_BASE_CLEARANCE:g} m ahead of the robot base "
            f"along +x (the arm faces +x): its near edge is at x = {x0:.3f} m, the base at "
            f"x = {bx:.3f} m",
        )

    def _check_obstacles(self) -> None:
        """Obstacles as Obstacle, named once each, none in the cloth workspace."""
        given = self.obstacles
        if isinstance(given, str | bytes | Mapping) or not isinstance(given, Sequence):
            raise ConfigError(
                f"layout obstacles must be a list of tables ({', '.join(OBSTACLE_FIELDS)}), "
                f"got {given!r}"
            )
        obstacles = tuple(
            obstacle_from_table(o, f"layout obstacles[{i}]") for i, o in enumerate(given)
        )
        names = [o.name for o in obstacles]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ConfigError(
                f"layout obstacles must have names of their own; {', '.join(map(repr, twice))} "
                "named more than once"
            )
        x0, x1, y0, y1 = self.workspace_bounds
        z0, z1 = self.table_height, self.table_height + WORKSPACE_CLEAR_HEIGHT
        for o in obstacles:
            (ox0, oy0, oz0), (ox1, oy1, oz1) = o.bounds
            if oz0 < z1 and z0 < oz1 and o.overlaps_area(x0, x1, y0, y1):
                raise ConfigError(
                    f"layout obstacle {o.name!r} (x {ox0:.3f}–{ox1:.3f}, y {oy0:.3f}–{oy1:.3f}, "
                    f"z {oz0:.3f}–{oz1:.3f} m) reaches into the cloth workspace (x {x0:.3f}–"
                    f"{x1:.3f}, y {y0:.3f}–{y1:.3f} m, up to {WORKSPACE_CLEAR_HEIGHT:g} m over "
                    "the table), which the cloth and the carries need clear: move it or the "
                    "workspace"
                )
        object.__setattr__(self, "obstacles", obstacles)

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
            if f.name == "obstacles":
                if value:
                    out[f.name] = [o.as_dict() for o in value]
            elif value != getattr(DEFAULT_LAYOUT, f.name):
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
