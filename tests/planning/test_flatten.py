import math

import numpy as np
import pytest

from foldbot.errors import ConfigError, FoldbotError
from foldbot.perception.state import ClothState
from foldbot.planning.flatten import (
    FlattenConfig,
    fit_expected_outline,
    perceived_coverage,
    plan_pull,
    plan_pulls,
)

TABLE = 0.75
W, H = 0.30, 0.24


def polygon_area(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def state_of(outline_xy) -> ClothState:
    """A perceived cloth whose top-view outline is `outline_xy` (world, m), 2 mm above the table."""
    xy = np.asarray(outline_xy, dtype=float)
    return ClothState(
        detected=True,
        reason="synthetic",
        mask=np.ones((4, 4), bool),
        coverage_m2=polygon_area(xy),
        outline_world=np.c_[xy, np.full(len(xy), TABLE + 0.002)],
        table_plane=np.array([0.0, 0.0, 1.0, -TABLE]),
    )


def rect(cx, cy, w, h, yaw=0.0) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    local = np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])
    return local @ np.array([[c, s], [-s, c]]) + [cx, cy]


def test_fit_recovers_the_pose_of_a_flat_cloth():
    yaw = 0.3
    fit = fit_expected_outline(rect(0.46, 0.02, W, H, yaw), W, H, FlattenConfig())
    assert fit.overlap > 0.95
    assert np.linalg.norm(fit.center - [0.46, 0.02]) < 0.01
    assert abs((fit.yaw - yaw + math.pi / 2) % math.pi - math.pi / 2) < math.radians(6)


def test_the_expected_outline_stays_inside_the_workspace():
    cfg = FlattenConfig()
    # A cloth lying against the far edge of the workspace.
    fit = fit_expected_outline(rect(0.70, 0.0, 0.10, 0.10), W, H, cfg)
    x0, x1, y0, y1 = cfg.workspace
    assert fit.corners[:, 0].max() <= x1 - cfg.margin + 0.006
    assert fit.corners[:, 0].min() >= x0 + cfg.margin - 0.006
    assert fit.corners[:, 1].max() <= y1 - cfg.margin + 0.006
    assert fit.corners[:, 1].min() >= y0 + cfg.margin - 0.006


def test_pull_goes_to_the_biggest_shortfall():
    # The flat towel with its +x/+y corner folded under: a 10 cm triangle is missing there.
    full = rect(0.45, 0.0, W, H)
    notched = np.array([full[0], full[1], [0.60, 0.02], [0.50, 0.12], full[3]])
    state = state_of(notched)
    fit, pulls = plan_pulls(state, W, H, FlattenConfig())
    assert fit.overlap > 0.85
    best = pulls[0]
    corner = full[2]
    assert np.linalg.norm(best.action.place[:2] - corner) < 0.03
    assert best.shortfall == pytest.approx(np.linalg.norm(corner - [0.55, 0.07]), abs=0.02)
    # The grasp is on the cloth, just inside its edge, near the missing corner, at table level.
    g = best.action.grasp
    assert np.linalg.norm(g[:2] - [0.55, 0.07]) < 0.04
    assert g[2] == pytest.approx(TABLE + FlattenConfig().grasp_height)
    # Place beyond grasp along the pull, and the grasp on the fold line's moving (left) side.
    x, y, dx, dy = best.action.fold_line
    assert (-dy) * (g[0] - x) + dx * (g[1] - y) > 0


def test_no_pull_once_the_target_coverage_is_reached():
    state = state_of(rect(0.45, 0.0, W, H * 0.92))
    assert perceived_coverage(state, W * H) == pytest.approx(0.92, abs=1e-6)
    assert plan_pull(state, W, H, FlattenConfig()) is None
    short = state_of(rect(0.45, 0.0, W, H * 0.8))
    assert plan_pull(short, W, H, FlattenConfig()) is not None


def empty_surface(cfg: FlattenConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A planning raster of the workspace with no surface seen (NaN), and its x, y grids."""
    ny = math.ceil((cfg.workspace[3] - cfg.workspace[2]) / cfg.raster) + 1
    nx = math.ceil((cfg.workspace[1] - cfg.workspace[0]) / cfg.raster) + 1
    xs = cfg.workspace[0] + np.arange(nx) * cfg.raster
    ys = cfg.workspace[2] + np.arange(ny) * cfg.raster
    gx, gy = np.meshgrid(xs, ys)
    return np.full((ny, nx), np.nan, np.float32), gx, gy


def test_a_heap_raises_the_grasp_so_the_palm_clears_it():
    cfg = FlattenConfig()
    # A crumpled 15 cm blob whose middle is heaped 8 cm high.
    blob = rect(0.45, 0.0, 0.15, 0.15)
    surface, gx, gy = empty_surface(cfg)
    inside = (np.abs(gx - 0.45) <= 0.075) & (np.abs(gy) <= 0.075)
    r = np.hypot(gx - 0.45, gy)
    surface[inside] = np.clip(0.08 - 0.8 * r[inside], 0.004, None)
    _fit, pulls = plan_pulls(state_of(blob), W, H, cfg, surface)
    assert pulls
    clear = [p for p in pulls if p.palm_ok]
    assert clear
    for pull in clear:
        g = pull.action.grasp
        level = g[2] - TABLE
        heap = surface[np.hypot(gx - g[0], gy - g[1]) <= cfg.palm_radius]
        # Within one raster cell's worth of the heap's slope.
        assert level >= np.nanmax(heap) - cfg.palm_clearance - 0.005
        assert level > cfg.grasp_height  # raised off the table


def test_top_layer_grasp_closes_just_under_the_perceived_surface():
    cfg = FlattenConfig(grasp_layer="top")
    # The towel folded in half along x = 0.50: two layers, the crease at the +x edge.
    outline = rect(0.425, 0.0, W / 2, H)
    surface, gx, gy = empty_surface(cfg)
    surface[(np.abs(gx - 0.425) <= W / 4) & (np.abs(gy) <= H / 2)] = 0.016
    _fit, pulls = plan_pulls(state_of(outline), W, H, cfg, surface, yaw=0.0)
    assert pulls
    for pull in pulls:
        assert pull.action.grasp[2] == pytest.approx(TABLE + 0.016 - cfg.top_depth, abs=1e-6)
    # Every layer at the table, by default.
    _fit, pulls = plan_pulls(state_of(outline), W, H, FlattenConfig(), surface, yaw=0.0)
    assert pulls
    assert all(p.action.grasp[2] == pytest.approx(TABLE + 0.004) for p in pulls)


def test_cloth_beyond_the_flattening_workspace_is_planned_without_surface_data():
    cfg = FlattenConfig()
    # Part of the crumpled cloth lies nearer the robot than the workspace's near edge (x 0.22).
    blob = rect(0.26, -0.02, 0.16, 0.12)
    surface = np.full(
        (
            math.ceil((cfg.workspace[3] - cfg.workspace[2]) / cfg.raster) + 1,
            math.ceil((cfg.workspace[1] - cfg.workspace[0]) / cfg.raster) + 1,
        ),
        0.004,
        np.float32,
    )
    _fit, pulls = plan_pulls(state_of(blob), W, H, cfg, surface)
    assert pulls
    assert all(cfg.workspace[0] + cfg.margin - 1e-9 <= p.action.place[0] for p in pulls)


def test_no_cloth_is_a_clear_error():
    with pytest.raises(FoldbotError, match="no cloth to flatten"):
        plan_pulls(ClothState.not_detected(), W, H, FlattenConfig())


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"target_coverage": 0.0}, r"target_coverage must be in \(0, 1.5\], got 0.0"),
        ({"target_coverage": float("nan")}, r"target_coverage must be in \(0, 1.5\]"),
        ({"finish_coverage": 0.0}, r"finish_coverage must be None or in \(0, 1.5\], got 0.0"),
        ({"finish_coverage": "high"}, r"finish_coverage must be None or in \(0, 1.5\]"),
        ({"max_actions": -1}, r"max_actions must be an integer in \[0, 50\], got -1"),
        ({"max_actions": 2.5}, r"max_actions must be an integer in \[0, 50\], got 2.5"),
        ({"grasp_inset": 0.5}, r"grasp_inset must be in \[0, 0.1\], got 0.5"),
        ({"overshoot": -0.01}, r"overshoot must be in \[0, 0.1\], got -0.01"),
        ({"raster": 0.0}, r"raster must be in \[0.001, 0.02\], got 0.0"),
        ({"retries": 9}, r"retries must be an integer in \[0, 5\], got 9"),
        ({"grasp_layer": "middle"}, r"grasp_layer must be one of all, top, got 'middle'"),
        ({"workspace": (0.5, 0.5, -0.3, 0.3)}, r"workspace .* must span > 0.1 m"),
    ],
)
def test_bad_config_values_name_the_value_and_the_allowed_range(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        FlattenConfig(**kwargs)


def test_flattening_stops_at_the_finishing_coverage_where_it_is_higher():
    assert FlattenConfig(finish_coverage=None).stop_coverage == FlattenConfig().target_coverage
    assert FlattenConfig().stop_coverage == 0.97  # finishing pulls by default
    assert FlattenConfig(target_coverage=0.9, finish_coverage=0.95).stop_coverage == 0.95
    assert FlattenConfig(target_coverage=0.9, finish_coverage=0.8).stop_coverage == 0.9


def test_bad_expected_size_is_a_clear_error():
    state = state_of(rect(0.45, 0.0, W, H))
    with pytest.raises(ConfigError, match="expected_area must be a finite area > 0"):
        perceived_coverage(state, 0.0)
    with pytest.raises(ConfigError, match="expected width × height must be > 0 m"):
        plan_pulls(state, -0.3, H, FlattenConfig())
