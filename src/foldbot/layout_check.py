"""Can this cell fold? A layout's workspace checked point by point before a cloth is laid in it:
the arm's reach (IK gripper down at the heights a fold's motions pass through, the arm clear of
the table) and the camera's view of the workspace (where it is in the simulated cell, or where a
calibration found it). `foldbot check-layout` runs it; `foldbot fold --layout` checks only the
workspace centre and the arm's home.

Kinematics only, on a planning twin in a world of its own (the arm's URDF, the table): nothing
here steps physics or touches a simulated cell.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np

from foldbot.control.executor import ArmExecutor, check_arm_fits
from foldbot.errors import ConfigError, UnreachableTargetError
from foldbot.planning.motion import MotionConfig
from foldbot.sim.camera import CameraConfig
from foldbot.sim.layout import CellLayout
from foldbot.sim.robots import (
    HOME_HEIGHT_ABOVE_TABLE,
    gripper_down_quaternion,
    make_robot,
)
from foldbot.sim.robots import REACH_CHECK_HEIGHT as GRASP_HEIGHT
from foldbot.sim.world import SimConfig, SimWorld

CHECK_HEIGHTS: tuple[tuple[str, float], ...] = (
    ("grasp", GRASP_HEIGHT),
    ("approach", MotionConfig().approach_height),
    ("carry", HOME_HEIGHT_ABOVE_TABLE),
)
"""The TCP heights over the table (m) each workspace point is checked at, gripper down: where
the jaws close on the cloth, where a grasp is approached from and a place retreated to, and a
fold carry's arc top (a 45 cm towel's half fold peaks 0.23 m up; the home is 0.25 m)."""
REQUIRED_HEIGHTS = 2
"""A point the arm can work at is reached at the first this many CHECK_HEIGHTS (grasp and
approach: every grasp and place). A carry's top lies over the cloth's middle, so a point reached
there but not 0.25 m above it (near the base, at the far edge) is reported, not refused."""
DEFAULT_GRID = 13
"""Points along each side of the workspace (13: every 5 cm over the default 0.6 m)."""
GRID_RANGE = (2, 41)
"""The grid sizes allowed."""


@dataclass(frozen=True)
class CameraPlacement:
    """Where a camera stands and what it sees: 4 × 4 T_world_camera (OpenCV axes), the 3 × 3
    intrinsics, the image size, and where the pose came from (for the report).
    `true_T_world_camera`: where the camera truly stands, where that is known apart from
    T_world_camera (a calibration solved on the simulated cell: T_world_camera is what it
    found, this what it was found against)."""

    T_world_camera: np.ndarray
    K: np.ndarray
    width: int
    height: int
    source: str
    true_T_world_camera: np.ndarray | None = None

    def sim_camera(self, base: CameraConfig) -> CameraConfig:
        """`base` (its noise, lighting, clipping) as this camera: its image size and
        intrinsics, rendered from where the camera truly stands, its Observations carrying
        T_world_camera (the calibration's pose: perception works from it, as on a real cell)."""
        K = np.asarray(self.K, dtype=float)
        if abs(K[0, 1]) > 1e-9:
            raise ConfigError(
                f"{self.source}: the simulated camera has no skew, but K[0][1] is {K[0, 1]!r}"
            )
        rows = tuple(tuple(float(v) for v in row) for row in self.T_world_camera)
        true = self.true_T_world_camera
        return replace(
            base,
            width=int(self.width),
            height=int(self.height),
            fx=float(K[0, 0]),
            fy=float(K[1, 1]),
            cx=float(K[0, 2]),
            cy=float(K[1, 2]),
            pose=rows if true is None else tuple(tuple(float(v) for v in r) for r in true),
            reported_pose=None if true is None else rows,
            reported_pose_source="" if true is None else self.source,
        )

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel (u, v) of world points (N × 3) and their depth along the optical axis (m)."""
        T_cam_world = np.linalg.inv(self.T_world_camera)
        pc = np.asarray(points, dtype=float) @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = (pc @ self.K.T)[:, :2] / z[:, None]
        return uv, z

    def in_view(self, points: np.ndarray) -> np.ndarray:
        """Which world points (N × 3) lie in front of the camera and inside the image."""
        uv, z = self.project(points)
        u, v = uv[:, 0], uv[:, 1]
        ok = (z > 0) & np.isfinite(u) & np.isfinite(v)
        return ok & (u >= 0) & (u <= self.width - 1) & (v >= 0) & (v <= self.height - 1)

    def footprint(self, plane_z: float) -> np.ndarray | None:
        """The image's outline on the horizontal plane z = plane_z (world xy, 4 × 2), or None
        where a corner's ray does not meet it in front of the camera (a camera looking up)."""
        corners = [(0, 0), (self.width - 1, 0), (self.width - 1, self.height - 1)]
        corners.append((0, self.height - 1))
        K_inv = np.linalg.inv(self.K)
        R, eye = self.T_world_camera[:3, :3], self.T_world_camera[:3, 3]
        out = []
        for u, v in corners:
            ray = R @ (K_inv @ np.array([u, v, 1.0]))
            if ray[2] >= -1e-9:
                return None
            s = (plane_z - eye[2]) / ray[2]
            if s <= 0:
                return None
            out.append((eye + s * ray)[:2])
        return np.asarray(out)


@dataclass(frozen=True)
class LayoutCheck:
    """What a layout's check found over its workspace grid (`xs` along x, `ys` along y)."""

    layout: CellLayout
    robot: str
    xs: np.ndarray
    ys: np.ndarray
    failures: tuple[dict[tuple[int, int], tuple[int, str]], ...]
    """Per arm: (ix, iy) → (the index in CHECK_HEIGHTS of the first height the arm does not
    reach there, why: IK's or the table check's reason); points absent are reached at every
    height."""
    camera: CameraPlacement
    in_view: np.ndarray
    """len(ys) × len(xs): the workspace point on the table top is inside the camera's image,
    the camera above the table (from below it sees the table's underside), and no obstacle of
    the layout stands between them."""
    mm_per_px: float | None
    """The image's resolution on the table at the workspace centre (mm per pixel along u); None
    where the camera does not look down at it (below the table top, or facing away)."""
    arm_names: tuple[str, ...] = field(default=("arm",))
    hidden: dict[str, int] = field(default_factory=dict)
    """Per obstacle of the layout, how many workspace points inside the image it hides from
    the camera (only those that hide some)."""
    blocked_postures: tuple[str, ...] = ()
    """Why an arm's home posture meets one of the layout's obstacles (one line per such arm)."""

    @property
    def points(self) -> int:
        return len(self.xs) * len(self.ys)

    def heights_reached(self, arm: int) -> np.ndarray:
        """len(ys) × len(xs): how many of CHECK_HEIGHTS, from the table up, arm `arm` reaches
        at the point."""
        out = np.full((len(self.ys), len(self.xs)), len(CHECK_HEIGHTS), dtype=int)
        for (ix, iy), (level, _) in self.failures[arm].items():
            out[iy, ix] = level
        return out

    def reached(self, arm: int) -> np.ndarray:
        """len(ys) × len(xs): arm `arm` can grasp and place at the point (REQUIRED_HEIGHTS)."""
        return self.heights_reached(arm) >= REQUIRED_HEIGHTS

    @property
    def covered(self) -> np.ndarray:
        """len(ys) × len(xs): some arm can grasp and place at the point."""
        return np.logical_or.reduce([self.reached(a) for a in range(len(self.failures))])

    @property
    def ok(self) -> bool:
        """Every workspace point is reached by an arm and seen by the camera, and no arm rests
        in an obstacle."""
        return bool(self.covered.all() and self.in_view.all() and not self.blocked_postures)

    @property
    def obstacles_in_image(self) -> tuple[str, ...]:
        """The layout's obstacles some part of which lies inside the camera's image (points
        through each box, 5 along each side): perception masks them as the cell's fixtures
        and `ros-check` looks for them there."""
        t = np.linspace(0.0, 1.0, 5)
        unit = np.stack(np.meshgrid(t, t, t, indexing="ij"), axis=-1).reshape(-1, 3)
        out = []
        for ob in self.layout.obstacles:
            c = ob.corners()  # its sides from its first corner (Obstacle.corners' order)
            points = c[0] + unit @ np.stack([c[4] - c[0], c[2] - c[0], c[1] - c[0]])
            if self.camera.in_view(points).any():
                out.append(ob.name)
        return tuple(out)

    def unreached(self, arm: int) -> dict[tuple[int, int], str]:
        """Where arm `arm` cannot grasp or place, and why."""
        return {k: why for k, (lv, why) in self.failures[arm].items() if lv < REQUIRED_HEIGHTS}

    def low_only(self, arm: int) -> dict[tuple[int, int], str]:
        """Where arm `arm` grasps and places but does not reach every height above, and why."""
        return {k: why for k, (lv, why) in self.failures[arm].items() if lv >= REQUIRED_HEIGHTS}

    def lines(self, listed: int = 5) -> list[str]:
        """The report as text: per arm what it reaches (the first few points it does not, with
        why), the camera's view, and the verdict."""
        x0, x1, y0, y1 = self.layout.workspace_bounds
        step = (x1 - x0) / max(len(self.xs) - 1, 1)
        out = [
            f"workspace x {x0:.3f}–{x1:.3f} m, y {y0:.3f}–{y1:.3f} m on the table at "
            f"{self.layout.table_height:g} m: {len(self.xs)} × {len(self.ys)} points, "
            f"{1000 * step:.0f} mm apart; each tried gripper down at "
            + ", ".join(f"{name} {1000 * h:.0f} mm" for name, h in CHECK_HEIGHTS)
            + " over the table, the arm clear of it"
        ]
        carry = CHECK_HEIGHTS[-1]
        for a, name in enumerate(self.arm_names):
            fails, low = self.unreached(a), self.low_only(a)
            out.append(
                f"{name} ({self.robot}): grasps and places at {self.points - len(fails)} of "
                f"{self.points} points, of those {self.points - len(fails) - len(low)} also "
                f"{1000 * carry[1]:.0f} mm up"
            )
            for (ix, iy), why in sorted(fails.items())[:listed]:
                out.append(f"  ({self.xs[ix]:.3f}, {self.ys[iy]:.3f}) m: {why}")
            if len(fails) > listed:
                out.append(f"  … and {len(fails) - listed} more")
        out += self.blocked_postures
        if len(self.failures) > 1:
            out.append(
                f"some arm reaches {int(self.covered.sum())} of {self.points} points, both "
                f"{int(np.logical_and.reduce([self.reached(a) for a in range(2)]).sum())}"
            )
        seen = int(self.in_view.sum())
        out.append(
            f"camera ({self.camera.source}): sees {seen} of {self.points} points on the table, "
            + self.resolution_words("the workspace centre")
        )
        if seen < self.points:
            missed = [
                (self.xs[ix], self.ys[iy])
                for iy, ix in zip(*np.nonzero(~self.in_view), strict=True)
            ]
            out.append(
                "  not seen: "
                + ", ".join(f"({x:.3f}, {y:.3f})" for x, y in missed[:listed])
                + (f" … and {len(missed) - listed} more" if len(missed) > listed else "")
            )
        for name, n in self.hidden.items():
            out.append(f"  obstacle {name!r} stands between the camera and {n} of them")
        for name in self.obstacles_in_image:
            out.append(
                f"  obstacle {name!r} is in the image: perception masks it as a fixture, not "
                "cloth, and `ros-check` looks for it there"
            )
        out.append(
            "the layout can fold: every workspace point reached and seen"
            if self.ok
            else "the layout cannot fold everywhere in its workspace: move the workspace "
            "(workspace_center_xy, workspace_size), the arm (robot_base_xyz), the camera or an "
            "obstacle"
        )
        return out

    def resolution_words(self, centre: str) -> str:
        """The image's resolution at `centre` (the workspace's), or why it has none there."""
        if self.mm_per_px is not None:
            return f"{self.mm_per_px:.2f} mm per pixel at {centre}"
        eye_z = float(self.camera.T_world_camera[2, 3])
        if eye_z <= self.layout.table_height:
            return (
                f"no resolution at {centre}: the camera is below the table top (at z = {eye_z:.3f} m, "
                f"the table at {self.layout.table_height:.3f} m)"
            )
        return (
            f"no resolution at {centre}: it lies behind the camera, which faces away from the table"
        )

    def record(self) -> dict[str, Any]:
        """layout_check.json's content (plain JSON)."""
        return {
            "ok": self.ok,
            "robot": self.robot,
            "arms": list(self.arm_names),
            "layout": self.layout.changes(),
            "workspace_bounds_m": list(self.layout.workspace_bounds),
            "grid_x_m": self.xs.tolist(),
            "grid_y_m": self.ys.tolist(),
            "check_heights_m": {name: h for name, h in CHECK_HEIGHTS},
            "required_heights": [name for name, _ in CHECK_HEIGHTS[:REQUIRED_HEIGHTS]],
            "reached": {
                name: {
                    "points": int(self.reached(a).sum()),
                    "points_every_height": self.points - len(self.failures[a]),
                    "short": [
                        {
                            "x_m": float(self.xs[ix]),
                            "y_m": float(self.ys[iy]),
                            "heights_reached": [n for n, _ in CHECK_HEIGHTS[:level]],
                            "why": why,
                        }
                        for (ix, iy), (level, why) in sorted(self.failures[a].items())
                    ],
                }
                for a, name in enumerate(self.arm_names)
            },
            "covered_points": int(self.covered.sum()),
            "blocked_postures": list(self.blocked_postures),
            "camera": {
                "source": self.camera.source,
                "T_world_camera": self.camera.T_world_camera.tolist(),
                "K": self.camera.K.tolist(),
                "image_size": [self.camera.width, self.camera.height],
                "points_seen": int(self.in_view.sum()),
                "points_hidden_by_obstacles": dict(self.hidden),
                "obstacles_in_image": list(self.obstacles_in_image),
                "mm_per_px": self.mm_per_px,
            },
            "points": self.points,
        }


def _grid(layout: CellLayout, n: int) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = GRID_RANGE
    if isinstance(n, bool) or not isinstance(n, int) or not lo <= n <= hi:
        raise ConfigError(f"the grid must be {lo}–{hi} points a side, got {n!r}")
    x0, x1, y0, y1 = layout.workspace_bounds
    return np.linspace(x0, x1, n), np.linspace(y0, y1, n)


def _reach_failures(
    executor: ArmExecutor, layout: CellLayout, xs: np.ndarray, ys: np.ndarray
) -> dict[tuple[int, int], tuple[int, str]]:
    """Where the executor's twin cannot reach a grid point at every check height: the first
    height it misses (index in CHECK_HEIGHTS) and why; each
    point's IK is seeded from the home posture, each height from the one below (as a fold's
    lift is)."""
    model = executor.model
    down = gripper_down_quaternion(executor.yaw)
    out: dict[tuple[int, int], tuple[int, str]] = {}
    for iy, y in enumerate(ys):
        for ix, x in enumerate(xs):
            q = model.home_q
            for level, (name, h) in enumerate(CHECK_HEIGHTS):
                target = [float(x), float(y), layout.table_height + h]
                try:
                    q = model.solve_ik(target, down, q_seed=q)
                    executor.check_table_clearance(q[None])
                except UnreachableTargetError as exc:
                    why = str(exc).removeprefix("waypoint 0: ")
                    if "best residual" in why:  # IK's own words, without the target repeated
                        why = "no IK solution, best " + why.partition("best ")[2]
                    out[(ix, iy)] = (level, f"at the {name} height ({1000 * h:.0f} mm): {why}")
                    break
    return out


def check_cell_fits(layout: CellLayout, robot: str, arms: int, park: str) -> None:
    """ConfigError where an arm cannot reach the workspace centre or would rest (home, park) in
    one of the layout's obstacles: what the simulated cell and the planner node check as they
    start, run before anything starts (`foldbot ros-fold`, whose nodes would otherwise die with
    it at start-up). Kinematics only, on twins in a world of their own."""
    world = SimWorld(SimConfig(layout=layout))
    try:
        for arm_layout in layout.arm_layouts(arms):
            model = make_robot(robot, world.client, arm_layout)
            executor = ArmExecutor(world, model, None)  # type: ignore[arg-type]  # no cloth
            check_arm_fits(executor, robot, park)
    finally:
        world.close()


def check_layout(
    layout: CellLayout,
    camera: CameraPlacement,
    robot: str = "ur5",
    arms: int = 1,
    grid: int = DEFAULT_GRID,
    progress: Any = None,
) -> LayoutCheck:
    """Check `layout`'s workspace on a `grid` × `grid` of points: each arm's reach gripper down
    at CHECK_HEIGHTS with its links clear of the table, and `camera`'s view of the table top
    there. `progress(done, total)` is called after each arm (for a long check's display)."""
    if arms not in (1, 2):
        raise ConfigError(f"a cell has 1 or 2 arms, got {arms!r}")
    xs, ys = _grid(layout, grid)
    world = SimWorld(SimConfig(layout=layout))
    try:
        failures, blocked = [], []
        names = ("arm",) if arms == 1 else ("left arm", "right arm")
        for a, arm_layout in enumerate(layout.arm_layouts(arms)):
            model = make_robot(robot, world.client, arm_layout)
            executor = ArmExecutor(world, model, None)  # type: ignore[arg-type]  # no cloth
            failures.append(_reach_failures(executor, layout, xs, ys))
            try:
                executor.check_postures({"home": model.home_q})
            except ConfigError as exc:
                blocked.append(f"{names[a]}: {exc}")
            if progress is not None:
                progress(a + 1, arms)
    finally:
        world.close()
    gx, gy = np.meshgrid(xs, ys)
    table = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, layout.table_height)], axis=1)
    above = bool(camera.T_world_camera[2, 3] > layout.table_height)
    in_view = camera.in_view(table).reshape(gx.shape) & above
    eye = camera.T_world_camera[:3, 3]
    hidden: dict[str, int] = {}
    for o in layout.obstacles:
        behind = np.array([o.blocks(eye, pt) for pt in table]).reshape(gx.shape) & in_view
        if behind.any():
            hidden[o.name] = int(behind.sum())
        in_view &= ~behind
    cx, cy = layout.workspace_center_xy
    _, z = camera.project(np.array([[cx, cy, layout.table_height]]))
    mm_per_px = 1000.0 * float(z[0]) / float(camera.K[0, 0]) if above and z[0] > 0 else None
    return LayoutCheck(
        layout=layout,
        robot=robot,
        xs=xs,
        ys=ys,
        failures=tuple(failures),
        camera=camera,
        in_view=in_view,
        mm_per_px=mm_per_px,
        arm_names=names,
        hidden=hidden,
        blocked_postures=tuple(blocked),
    )


_GREEN, _AMBER, _RED = (60, 180, 75), (240, 170, 30), (220, 50, 47)
_BLUE, _GREY, _DARK, _WHITE = (40, 110, 230), (200, 190, 170), (70, 70, 70), (255, 255, 255)


def check_picture(check: LayoutCheck, width_px: int = 720) -> np.ndarray:
    """The check from above, the arm at the bottom (+x up the picture, +y to the left): the
    table, the workspace's points (green: reached at every height, amber: grasp and place but
    not a carry's top, red: not; by the arm that reaches highest there; hollow: outside the
    camera's image or hidden behind an obstacle), the camera's view on the table (blue), the
    arms' bases, the layout's obstacles (dark, named)."""
    lay = check.layout
    arms = len(check.failures)
    tx, ty = lay.table_center_xy
    sx, sy = lay.table_size
    bases = [a.robot_base_xyz[:2] for a in lay.arm_layouts(arms)]
    corners = [c for o in lay.obstacles for c in o.bounds]
    xs = [tx - sx / 2, tx + sx / 2] + [b[0] for b in bases] + [c[0] for c in corners]
    ys = [ty - sy / 2, ty + sy / 2] + [b[1] for b in bases] + [c[1] for c in corners]
    pad = 0.08
    x_lo, x_hi = min(xs) - pad, max(xs) + pad
    y_lo, y_hi = min(ys) - pad, max(ys) + pad
    scale = width_px / (y_hi - y_lo)
    legend_h = 96
    height_px = round((x_hi - x_lo) * scale)
    img = np.full((height_px + legend_h, width_px, 3), 245, np.uint8)

    def px(x: float, y: float) -> tuple[int, int]:
        return round((y_hi - y) * scale), round((x_hi - x) * scale)

    cv2.rectangle(img, px(tx + sx / 2, ty + sy / 2), px(tx - sx / 2, ty - sy / 2), _GREY, -1)
    font = cv2.FONT_HERSHEY_SIMPLEX
    labels: list[tuple[int, int, int, int]] = []
    for o in lay.obstacles:  # from above: their footprints, named (a name under another's
        (_, oy0, _), (ox1, _, _) = o.bounds  # moves down to a line of its own)
        cv2.fillPoly(img, [np.array([px(x, y) for x, y in o.footprint()], np.int32)], _DARK)
        u, v = px(ox1, oy0)
        (w, h), _ = cv2.getTextSize(o.name, font, 0.4, 1)
        u, v = u + 4, v + 12
        while any(u < a + c and a < u + w and v - h < b and b - d < v for a, b, c, d in labels):
            v += h + 4
        labels.append((u, v, w, h))
        cv2.putText(img, o.name, (u, v), font, 0.4, _DARK, 1, cv2.LINE_AA)
    x0, x1, y0, y1 = lay.workspace_bounds
    cv2.rectangle(img, px(x1, y1), px(x0, y0), _WHITE, 2)
    foot = check.camera.footprint(lay.table_height)
    if foot is not None:
        pts = np.array([px(x, y) for x, y in foot], np.int32)
        cv2.polylines(img, [pts], True, _BLUE, 2, cv2.LINE_AA)
    best = np.max([check.heights_reached(a) for a in range(arms)], axis=0)
    r = max(3, round(0.35 * scale * (x1 - x0) / max(len(check.xs) - 1, 1)))
    for iy, y in enumerate(check.ys):
        for ix, x in enumerate(check.xs):
            level = best[iy, ix]
            colour = (
                _GREEN
                if level == len(CHECK_HEIGHTS)
                else (_AMBER if level >= REQUIRED_HEIGHTS else _RED)
            )
            seen = bool(check.in_view[iy, ix])
            cv2.circle(img, px(x, y), r, colour, -1 if seen else 2, cv2.LINE_AA)
    base_r = max(6, round(0.04 * scale))
    for (bx, by), name in zip(bases, check.arm_names, strict=True):
        u, v = px(bx, by)
        cv2.circle(img, (u, v), base_r, _DARK, -1, cv2.LINE_AA)
        cv2.putText(img, name, (u + base_r + 6, v + 5), font, 0.45, _DARK, 1, cv2.LINE_AA)
    carry_mm = 1000 * CHECK_HEIGHTS[-1][1]
    y_text = height_px + 22
    legend = [
        (_GREEN, -1, "reached"),
        (_AMBER, -1, f"grasp and place only (not {carry_mm:.0f} mm up)"),
        (_RED, -1, "not reached"),
        (_GREEN, 2, "not seen"),
    ]
    u = 12
    for colour, fill, text in legend:
        cv2.circle(img, (u + 6, y_text - 5), 6, colour, fill, cv2.LINE_AA)
        cv2.putText(img, text, (u + 18, y_text), font, 0.42, _DARK, 1, cv2.LINE_AA)
        u += 30 + cv2.getTextSize(text, font, 0.42, 1)[0][0]
    cv2.line(img, (12, y_text + 22), (36, y_text + 22), _BLUE, 2)
    cv2.putText(
        img, "the camera's image on the table", (44, y_text + 27), font, 0.45, _DARK, 1, cv2.LINE_AA
    )
    verdict = "every point reached and seen" if check.ok else "not every point reached and seen"
    who = f"{arms} × {check.robot}" if arms > 1 else check.robot
    cv2.putText(
        img,
        f"{who}: {int(check.covered.sum())}/{check.points} reached, "
        f"{int(check.in_view.sum())}/{check.points} seen: {verdict}",
        (12, y_text + 56),
        font,
        0.5,
        _GREEN if check.ok else _RED,
        1,
        cv2.LINE_AA,
    )
    return img


OBSTACLE_SEEN_MARGIN = 0.02
"""How far (m) from a layout's obstacle a depth point may lie and still be the obstacle's: the
depth's noise and a calibration's centimetre at the table."""
OBSTACLE_SEEN_FRACTION = 0.5
"""Share of the pixels whose line of sight meets an obstacle that must see it there (the rest
see past it) for it to count as where the layout puts it: half, so that a box drawn a little
larger than its fixture passes (layouts/cloth_tray.toml's 60 × 8 × 4 cm tray drawn 64 × 12 × 5:
67 %) and one where nothing stands, or moved off by its width, does not (7 %, 17 %)."""
OBSTACLE_MIN_PIXELS = 50
"""Fewer pixels than this on an obstacle: too little of it in view to say."""


@dataclass(frozen=True)
class ObstacleSighting:
    """What a depth image shows where a layout puts one obstacle: `pixels` whose line of sight
    meets the box and have a depth, of them `seen` whose depth is where the ray enters the box
    (within OBSTACLE_SEEN_MARGIN) and `past` whose depth lies beyond it (the camera sees through
    where the box should be: the table under a tray that is not there); the rest see something
    in front of it (the arm, the cloth). An obstacle less than the margin tall on the table
    cannot be told from the table."""

    name: str
    pixels: int
    seen: int
    past: int

    @property
    def in_view(self) -> bool:
        """Enough of it in view to say where it is."""
        return self.seen + self.past >= OBSTACLE_MIN_PIXELS

    @property
    def seen_fraction(self) -> float:
        """Share of the decided pixels that see the box (NaN where none is decided)."""
        n = self.seen + self.past
        return self.seen / n if n else float("nan")

    @property
    def where_the_layout_says(self) -> bool:
        """Out of view (nothing to say), or seen where the layout puts it."""
        return not self.in_view or self.seen_fraction >= OBSTACLE_SEEN_FRACTION


def obstacles_in_depth(
    depth: np.ndarray, K: np.ndarray, T_world_camera: np.ndarray, obstacles: tuple
) -> list[ObstacleSighting]:
    """For each of a layout's obstacles, what a depth image (m along the optical axis, 0 or NaN
    unknown) seen from T_world_camera through K shows where the layout puts it: each pixel's line
    of sight cast against the box (slabs in its own frame) and the depth there compared with
    where the ray enters it. Only the box's image (its corners projected) is cast."""
    h, w = depth.shape
    R, t = T_world_camera[:3, :3], T_world_camera[:3, 3]
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    z = np.nan_to_num(np.asarray(depth, dtype=float), nan=0.0)
    out = []
    for ob in obstacles:
        corners = (ob.corners() - t) @ R  # camera frame
        rows, cols = slice(0, h), slice(0, w)
        if np.all(corners[:, 2] <= 1e-3):
            out.append(ObstacleSighting(ob.name, 0, 0, 0))
            continue
        if np.all(corners[:, 2] > 1e-3):
            u = fx * corners[:, 0] / corners[:, 2] + cx
            v = fy * corners[:, 1] / corners[:, 2] + cy
            c0, c1 = max(int(np.floor(u.min())), 0), min(int(np.ceil(u.max())) + 1, w)
            r0, r1 = max(int(np.floor(v.min())), 0), min(int(np.ceil(v.max())) + 1, h)
            rows, cols = slice(r0, max(r0, r1)), slice(c0, max(c0, c1))
        zs = z[rows, cols]
        if zs.size == 0:
            out.append(ObstacleSighting(ob.name, 0, 0, 0))
            continue
        us = (np.arange(cols.start, cols.stop) - cx) / fx
        vs = (np.arange(rows.start, rows.stop) - cy) / fy
        ray_cam = np.stack(
            [
                np.broadcast_to(us, zs.shape),
                np.broadcast_to(vs[:, None], zs.shape),
                np.ones_like(zs),
            ],
            axis=-1,
        )  # direction per pixel with unit depth: a ray's parameter is its depth
        o = ob.to_local(t)  # the camera, and each ray's direction, in the box's frame
        d = ob.to_local(t + ray_cam @ R.T) - o
        half = np.asarray(ob.size_xyz) / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-half - o) / d, (half - o) / d
        t_near = np.nanmax(np.minimum(ta, tb), axis=-1)
        t_far = np.nanmin(np.maximum(ta, tb), axis=-1)
        hits = (t_near <= t_far) & (t_far > 0) & (zs > 0)
        gap = zs[hits] - np.maximum(t_near, 0.0)[hits]  # the depth past where the ray enters
        seen = np.abs(gap) <= OBSTACLE_SEEN_MARGIN
        past = gap > OBSTACLE_SEEN_MARGIN
        out.append(ObstacleSighting(ob.name, int(hits.sum()), int(seen.sum()), int(past.sum())))
    return out
