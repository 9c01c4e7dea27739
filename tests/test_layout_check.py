"""The layout check: the arm's reach over a workspace (IK gripper down, the arm clear of the
table) and the camera's view of it, on the default cell, cells that fail, and a moved camera."""

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.layout_check import (
    CHECK_HEIGHTS,
    REQUIRED_HEIGHTS,
    CameraPlacement,
    check_layout,
    check_picture,
)
from foldbot.sim.camera import CameraConfig, camera_for_layout, look_at
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout


def sim_camera(layout: CellLayout = DEFAULT_LAYOUT) -> CameraPlacement:
    cam = camera_for_layout(CameraConfig(), layout)
    return CameraPlacement(cam.T_world_camera, cam.K, cam.width, cam.height, "simulated")


def test_the_default_cell_reaches_and_sees_its_whole_workspace():
    check = check_layout(DEFAULT_LAYOUT, sim_camera(), grid=5)
    assert check.ok and check.points == 25
    assert check.failures == ({},) and check.covered.all() and check.in_view.all()
    assert np.allclose(check.xs, [0.15, 0.3, 0.45, 0.6, 0.75])
    # 880 px focal length, the table ~1.16 m from the camera along its axis.
    assert 1.0 < check.mm_per_px < 1.6
    lines = check.lines()
    assert "grasps and places at 25 of 25 points, of those 25 also 250 mm up" in lines[1]
    assert lines[-1].startswith("the layout can fold")
    record = check.record()
    assert record["ok"] and record["reached"]["arm"]["points"] == 25
    assert record["required_heights"] == ["grasp", "approach"]


def test_a_workspace_beyond_the_arms_reach_is_refused_point_by_point():
    # The cloth's far edge 1.05 m out: past a UR5's 0.85 m reach.
    far = CellLayout(
        table_size=(1.6, 1.2), table_center_xy=(0.7, 0.0), workspace_center_xy=(0.75, 0.0)
    )
    check = check_layout(far, sim_camera(far), grid=5)
    assert not check.ok
    reached = check.reached(0)
    assert reached[:, 0].all() and not reached[:, -1].any()  # near edge yes, far edge no
    whys = check.unreached(0).values()
    assert all("height" in w and "no IK solution, best residual" in w for w in whys)
    assert "cannot fold everywhere" in check.lines()[-1]
    short = check.record()["reached"]["arm"]["short"]
    nowhere = [s["x_m"] for s in short if not s["heights_reached"]]
    assert min(nowhere) >= 0.9 and sum(np.isclose(nowhere, 1.05)) == 5


def test_the_arm_touching_the_table_counts_as_not_reached():
    # The pedestal example: the arm 5 cm below a table starting 12 cm ahead of it. Turned to
    # the right, the UR5's shoulder (a cylinder 14 cm out from its axis) meets the table's edge.
    layout = CellLayout(
        table_height=0.70,
        table_size=(1.0, 1.2),
        table_center_xy=(0.62, 0.0),
        robot_base_xyz=(0.0, 0.0, 0.65),
        workspace_center_xy=(0.50, 0.06),
    )
    check = check_layout(layout, sim_camera(layout), grid=7)
    whys = list(check.unreached(0).values())
    assert any("shoulder_link would touch the table" in w for w in whys)
    # Two arms, each on its own side, between them reach every point.
    two = check_layout(layout, sim_camera(layout), arms=2, grid=7)
    assert two.ok and len(two.failures) == 2
    assert not two.reached(0).all() and two.covered.all()
    assert two.arm_names == ("left arm", "right arm")


def test_a_point_reached_low_but_not_at_a_carrys_top_is_reported_not_refused():
    check = check_layout(DEFAULT_LAYOUT, sim_camera(), robot="panda", grid=7)
    low = check.low_only(0)
    assert low, "the Panda does not reach 250 mm over its near edge 10 cm off the middle"
    assert all(f"carry height ({1000 * CHECK_HEIGHTS[-1][1]:.0f} mm)" in w for w in low.values())
    levels = check.heights_reached(0)
    for ix, iy in low:
        assert levels[iy, ix] >= REQUIRED_HEIGHTS and check.reached(0)[iy, ix]


def test_a_camera_turned_away_misses_part_of_the_workspace():
    cam = CameraConfig(eye=(0.45, 0.0, 1.6), target=(0.45, 0.5, 0.75))
    placement = CameraPlacement(
        look_at(cam.eye, cam.target, cam.up), cam.K, cam.width, cam.height, "moved"
    )
    check = check_layout(DEFAULT_LAYOUT, placement, grid=5)
    assert not check.ok and check.covered.all()
    assert check.in_view[-1].any() and not check.in_view[:3].any()  # far +y seen, −y not
    assert "not seen: (0.150, -0.300)" in "\n".join(check.lines())


@pytest.mark.parametrize(
    ("eye", "target", "why"),
    [
        # Under the table looking up: it would see the table's underside, not the cloth.
        ((0.45, 0.0, 0.3), (0.45, 0.0, 0.9), "the camera is below the table top (at z = 0.300 m"),
        ((0.45, 0.0, 1.6), (0.45, 0.0, 2.5), "it lies behind the camera, which faces away"),
    ],
)
def test_a_camera_that_cannot_look_down_at_the_table_sees_nothing_and_says_why(eye, target, why):
    cam = CameraConfig(eye=eye, target=target)
    placement = CameraPlacement(
        look_at(cam.eye, cam.target, cam.up), cam.K, cam.width, cam.height, "moved"
    )
    check = check_layout(DEFAULT_LAYOUT, placement, grid=3)
    assert not check.in_view.any() and check.mm_per_px is None
    assert f"sees 0 of 9 points on the table, no resolution at the workspace centre: {why}" in (
        "\n".join(check.lines())
    )
    assert check.record()["camera"]["mm_per_px"] is None  # JSON has no infinity


def test_the_cameras_footprint_projects_back_onto_the_image_corners():
    cam = sim_camera()
    foot = cam.footprint(DEFAULT_LAYOUT.table_height)
    pts = np.column_stack([foot, np.full(4, DEFAULT_LAYOUT.table_height)])
    uv, z = cam.project(pts)
    assert np.allclose(uv, [[0, 0], [639, 0], [639, 479], [0, 479]], atol=1e-6)
    assert (z > 0).all()
    up = CameraPlacement(np.eye(4), cam.K, cam.width, cam.height, "looking up")
    up.T_world_camera[:3, :3] = np.diag([1.0, -1.0, -1.0])  # optical axis +z world
    assert up.footprint(0.75) is None


def test_a_placement_becomes_the_simulated_camera_it_describes():
    """CameraPlacement.sim_camera: the placement's size and intrinsics over a camera's noise and
    light; rendered from the true pose where one is known, Observations carrying the found one."""
    cam = sim_camera()
    base = CameraConfig(depth_noise=0.001, rgb_noise=2.0)
    plain = cam.sim_camera(base)
    np.testing.assert_allclose(plain.T_world_camera, cam.T_world_camera)
    assert plain.reported_pose is None and plain.depth_noise == 0.001 and plain.rgb_noise == 2.0
    found = cam.T_world_camera.copy()
    found[:3, 3] += (0.002, 0.0, 0.0)
    K = CameraConfig(width=320, height=240).K
    calibrated = CameraPlacement(found, K, 320, 240, "cal.json", cam.T_world_camera)
    placed = calibrated.sim_camera(base)
    np.testing.assert_allclose(placed.T_world_camera, cam.T_world_camera)
    np.testing.assert_allclose(placed.reported_T_world_camera, found)
    assert placed.reported_pose_source == "cal.json"
    np.testing.assert_allclose(placed.K, K)
    assert (placed.width, placed.height) == (320, 240)
    skewed = K.copy()
    skewed[0, 1] = 0.5
    with pytest.raises(ConfigError, match=r"cal.json: the simulated camera has no skew.*0.5"):
        CameraPlacement(found, skewed, 320, 240, "cal.json").sim_camera(base)


def test_the_picture_shows_the_cell_from_above():
    check = check_layout(DEFAULT_LAYOUT, sim_camera(), grid=3, arms=2)
    img = check_picture(check)
    assert img.dtype == np.uint8 and img.shape[1] == 720 and img.shape[0] > 500
    green = np.all(img == (60, 180, 75), axis=-1).sum()
    blue = np.all(img == (40, 110, 230), axis=-1).sum()
    assert green > 9 * 50 and blue > 500


@pytest.mark.parametrize("grid", [1, 42, 5.0, True])
def test_a_grid_outside_its_range_is_refused(grid):
    with pytest.raises(ConfigError, match=r"the grid must be 2–41 points a side"):
        check_layout(DEFAULT_LAYOUT, sim_camera(), grid=grid)


def test_three_arms_are_refused():
    with pytest.raises(ConfigError, match="a cell has 1 or 2 arms, got 3"):
        check_layout(DEFAULT_LAYOUT, sim_camera(), arms=3)


@pytest.mark.parametrize("arms", [1, 2])
def test_the_example_layouts_can_fold_everywhere(arms):
    """Every layout file this repository ships is reached and seen over its whole workspace (every
    10 cm here; `foldbot check-layout layouts/pedestal.toml` checks every 5)."""
    from pathlib import Path

    from foldbot.sim.layout import load_layout

    files = sorted((Path(__file__).resolve().parents[1] / "layouts").glob("*.toml"))
    assert files
    for path in files:
        layout = load_layout(path)
        check = check_layout(layout, sim_camera(layout), arms=arms, grid=7)
        assert check.ok, f"{path.name}: " + "\n".join(check.lines())


def test_an_obstacle_in_the_arms_way_or_the_cameras_view_is_found_and_named():
    from foldbot.sim.layout import Obstacle

    # A lamp 47–53 cm over the table between the camera (1.05, 0, 1.75) and the workspace: it
    # hides part of the table from the camera, and the arm's wrist meets it over some points.
    lamp = Obstacle("lamp", (0.75, 0.0, 1.25), (0.12, 0.12, 0.05))
    layout = CellLayout(obstacles=(lamp,))
    check = check_layout(layout, sim_camera(layout), grid=7)
    assert not check.ok
    assert check.hidden == {"lamp": int((~check.in_view).sum())} and check.hidden["lamp"] > 0
    assert check.blocked_postures == ()
    lines = check.lines()
    assert (
        f"  obstacle 'lamp' stands between the camera and {check.hidden['lamp']} of them" in lines
    )
    assert lines[-1].endswith("the camera or an obstacle")
    record = check.record()
    assert record["camera"]["points_hidden_by_obstacles"] == check.hidden
    assert record["layout"]["obstacles"][0]["name"] == "lamp"
    picture = check_picture(check)
    assert picture.ndim == 3 and picture.shape[2] == 3


def test_an_obstacle_where_the_arm_rests_or_reaches_fails_the_check():
    from foldbot.sim.layout import Obstacle

    lamp = Obstacle("lamp", (0.55, 0.10, 1.10), (0.30, 0.30, 0.08))  # 32 cm over the table
    layout = CellLayout(obstacles=(lamp,))
    check = check_layout(layout, sim_camera(layout), grid=5)
    assert not check.ok
    assert len(check.blocked_postures) == 1
    assert check.blocked_postures[0].startswith("arm: the arm's home posture meets an obstacle")
    assert check.blocked_postures[0] in check.lines()
    whys = check.unreached(0).values()
    assert whys and all("obstacle 'lamp'" in w for w in whys)


def test_a_cell_resting_in_an_obstacle_or_out_of_reach_is_refused_before_anything_starts():
    from foldbot.layout_check import check_cell_fits
    from foldbot.sim.layout import Obstacle

    check_cell_fits(DEFAULT_LAYOUT, "ur5", 2, "out_of_view")
    lamp = Obstacle("lamp", (0.55, 0.10, 1.10), (0.30, 0.30, 0.08))
    with pytest.raises(ConfigError, match=r"^the arm's home posture meets an obstacle"):
        check_cell_fits(CellLayout(obstacles=(lamp,)), "ur5", 1, "home")
    far = CellLayout(
        table_size=(2.0, 1.2), table_center_xy=(0.9, 0.0), workspace_center_xy=(0.95, 0.0)
    )
    with pytest.raises(ConfigError, match=r"cannot reach the workspace centre \(0\.95, 0\) m"):
        check_cell_fits(far, "ur5", 1, "home")


def test_the_depth_shows_an_obstacle_where_the_layout_puts_it_or_sees_past_it():
    """ros-check's look at the layout's obstacles (obstacles_in_depth): layouts/cloth_tray.toml's
    tray, 4 cm tall, seen where the file puts it; told of it in a cell without it, or 8 cm off
    across its width, the camera sees the table past it; drawn a little larger than it is, it
    still passes; the camera's post, behind the camera, is out of view."""
    import dataclasses
    from pathlib import Path

    from foldbot.layout_check import obstacles_in_depth
    from foldbot.sim.layout import load_layout
    from foldbot.sim.perception_scenes import render_scene, sample_scene

    root = Path(__file__).resolve().parents[1] / "layouts"
    tray = load_layout(root / "cloth_tray.toml")
    mount = load_layout(root / "camera_mount.toml")

    def depth_of(layout):
        scene = sample_scene(np.random.default_rng([0, 19]), 19, 0.3, 0.4, layout=layout)
        obs = render_scene(scene, 320, 240, 8, 19, layout=layout).obs
        return obs.depth, obs.intrinsics.K, obs.T_world_camera

    def told(obstacle, **change):
        return (dataclasses.replace(obstacle, **change),)

    built = depth_of(tray)
    box = tray.obstacles[0]
    (there,) = obstacles_in_depth(*built, tray.obstacles)
    assert there.in_view and there.seen_fraction > 0.95 and there.where_the_layout_says
    (larger,) = obstacles_in_depth(
        *built, told(box, size_xyz=(0.64, 0.12, 0.05), center_xyz=(0.45, 0.37, 0.775))
    )
    assert 0.5 < larger.seen_fraction < 0.9 and larger.where_the_layout_says
    (off,) = obstacles_in_depth(*built, told(box, center_xyz=(0.45, 0.45, 0.77)))
    assert off.in_view and off.seen_fraction < 0.3 and not off.where_the_layout_says
    (absent,) = obstacles_in_depth(*depth_of(DEFAULT_LAYOUT), tray.obstacles)
    assert absent.in_view and absent.seen_fraction < 0.2 and not absent.where_the_layout_says
    assert absent.past > 0.8 * absent.pixels  # the table under where the tray should be
    for out in obstacles_in_depth(*depth_of(mount), mount.obstacles):
        assert out.pixels == 0 and not out.in_view and out.where_the_layout_says


def test_the_obstacles_inside_the_image_are_named():
    """check-layout names the obstacles the camera sees (perception masks them, ros-check looks
    for them): the cloth tray beside the workspace, not the camera mount's post and bar."""
    from pathlib import Path

    from foldbot.sim.layout import load_layout

    root = Path(__file__).resolve().parents[1] / "layouts"
    tray = load_layout(root / "cloth_tray.toml")
    check = check_layout(tray, sim_camera(tray), grid=3)
    assert check.obstacles_in_image == ("cloth_tray",)
    assert (
        "  obstacle 'cloth_tray' is in the image: perception masks it as a fixture, not cloth, "
        "and `ros-check` looks for it there"
    ) in check.lines()
    assert check.record()["camera"]["obstacles_in_image"] == ["cloth_tray"]
    mount = load_layout(root / "camera_mount.toml")
    assert check_layout(mount, sim_camera(mount), grid=3).obstacles_in_image == ()
