"""The cell's layout: one arm as it always was, or two side by side; a file's fields checked and
named, the camera and the arm placed by it."""

from pathlib import Path

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.sim.camera import DEFAULT_EYE, DEFAULT_TARGET, CameraConfig, camera_for_layout
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout, load_layout
from foldbot.sim.robots import ROBOT_NAMES, check_workspace_reach, make_robot
from foldbot.sim.world import SimConfig, SimWorld

PEDESTAL = Path(__file__).resolve().parents[2] / "layouts" / "pedestal.toml"
OBSTACLE = (
    '[[obstacles]]\nname = "post"\ncenter_xyz = [0.9, 0.5, 1.1]\nsize_xyz = [0.05, 0.05, 0.7]\n'
)


def test_one_arm_layout_is_the_cell_itself():
    assert DEFAULT_LAYOUT.arm_layouts(1) == (DEFAULT_LAYOUT,)


def test_two_arms_stand_apart_on_the_near_edge_left_arm_first():
    left, right = DEFAULT_LAYOUT.arm_layouts(2)
    assert left.robot_base_xyz == pytest.approx((0.0, 0.3, 0.75))
    assert right.robot_base_xyz == pytest.approx((0.0, -0.3, 0.75))
    # Each arm's home is at its own side, not over the workspace centre where both would meet.
    assert left.home_xy == pytest.approx((0.45, 0.3))
    assert right.home_xy == pytest.approx((0.45, -0.3))
    # The table and the cloth's workspace are the cell's.
    assert left.workspace_center_xy == DEFAULT_LAYOUT.workspace_center_xy
    assert left.table_size == DEFAULT_LAYOUT.table_size


@pytest.mark.parametrize("arms", [0, 3])
def test_other_arm_counts_are_refused(arms):
    with pytest.raises(ValueError, match="1 or 2 arms"):
        DEFAULT_LAYOUT.arm_layouts(arms)


def test_the_shipped_example_layout_loads_and_names_what_it_changes():
    layout = load_layout(PEDESTAL)
    assert layout.table_height == 0.70 and layout.robot_base_xyz == (0.0, 0.0, 0.65)
    assert layout.workspace_center_xy == (0.50, 0.06) and layout.workspace_size == 0.6
    assert layout.changes() == {
        "table_height": 0.70,
        "table_size": [0.97, 1.2],
        "table_center_xy": [0.635, 0.0],
        "robot_base_xyz": [0.0, 0.0, 0.65],
        "workspace_center_xy": [0.50, 0.06],
    }
    assert layout.workspace_shift() == pytest.approx((0.05, 0.06, -0.05))
    assert layout.base_shift() == pytest.approx((0.0, 0.0, -0.10))
    assert DEFAULT_LAYOUT.changes() == {} and not any(DEFAULT_LAYOUT.workspace_shift())


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("table_hight = 0.7\n", "unknown layout key 'table_hight'; allowed: table_height,"),
        ("table_height = -0.7\n", "layout table_height must be a number in (0, 2] m, got -0.7"),
        ("table_height = true\n", "layout table_height must be a number in (0, 2] m, got True"),
        ("robot_base_xyz = [0, 0]\n", "layout robot_base_xyz must be 3 finite numbers (m)"),
        ("table_size = [1.2, 0]\n", "layout table_size must be > 0 m each, got (1.2, 0.0)"),
        ("home_xy = [0.4, 'a']\n", "layout home_xy must be 2 finite numbers (m)"),
        (
            "workspace_center_xy = [0.9, 0.0]\n",
            "layout workspace (x 0.600–1.200, y -0.300–0.300 m: workspace_center_xy ± "
            "workspace_size / 2) must lie on the table top (x -0.150–1.050",
        ),
        (
            "robot_base_xyz = [0.0, 0.0, 0.6]\n",
            "layout robot_base_xyz (0.0, 0.0, 0.6) stands inside the table (its top at 0.75 m",
        ),
        (
            "robot_base_xyz = [0.1, 0.0, 0.75]\n",
            "layout workspace must lie at least 0.1 m ahead of the robot base along +x (the arm "
            "faces +x): its near edge is at x = 0.150 m, the base at x = 0.100 m",
        ),
        ("table_height = [\n", "is not valid TOML"),
        (
            OBSTACLE.replace("[0.9, 0.5, 1.1]", "[0.45, 0.0, 0.9]"),
            "layout obstacle 'post' (x 0.425–0.475, y -0.025–0.025, z 0.550–1.250 m) reaches "
            "into the cloth workspace (x 0.150–0.750, y -0.300–0.300 m, up to 0.3 m over the "
            "table)",
        ),
        (OBSTACLE.replace('"post"', '"a post"'), "an obstacle's name must be a non-empty word"),
        (
            OBSTACLE.replace("[0.05, 0.05, 0.7]", "[0.05, 0.0, 0.7]"),
            "obstacle 'post': size_xyz must be 3 sizes in (0, 10] m, got [0.05, 0.0, 0.7]",
        ),
        (
            OBSTACLE.replace("[0.9, 0.5, 1.1]", "[0.9, 0.5]"),
            "layout obstacles[0]: obstacle 'post': center_xyz must be 3 finite numbers (m)",
        ),
        (
            OBSTACLE.replace("center_xyz", "centre"),
            "layout obstacles[0]: unknown key 'centre'; missing 'center_xyz'; an obstacle has "
            "name, center_xyz, size_xyz and may have yaw_deg",
        ),
        (
            OBSTACLE + "yaw_deg = 400\n",
            "obstacle 'post': yaw_deg must be degrees in [-360, 360], got 400",
        ),
        (OBSTACLE + OBSTACLE, "layout obstacles must have names of their own; 'post' named"),
        ('obstacles = "post"\n', "layout obstacles must be a list of tables"),
    ],
)
def test_a_bad_layout_file_is_named_with_what_is_allowed(tmp_path, text, needle):
    path = tmp_path / "cell.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_layout(path)
    assert needle in str(exc.value)
    assert str(path) in str(exc.value)


def test_a_missing_layout_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match=r"layout file .*nothere\.toml' does not exist"):
        load_layout(tmp_path / "nothere.toml")


def test_the_default_camera_moves_with_the_workspace_and_the_table():
    layout = load_layout(PEDESTAL)
    moved = camera_for_layout(CameraConfig(), layout)
    shift = layout.workspace_shift()
    assert moved.eye == pytest.approx([a + d for a, d in zip(DEFAULT_EYE, shift, strict=True)])
    assert moved.target == pytest.approx(
        [a + d for a, d in zip(DEFAULT_TARGET, shift, strict=True)]
    )
    # Same framing: the camera looks along the same ray, shifted; the intrinsics are its own.
    assert moved.fx == CameraConfig().fx and moved.up == CameraConfig().up
    # The default cell's camera, and a camera placed by its user, stay where they are.
    assert camera_for_layout(CameraConfig(), DEFAULT_LAYOUT) == CameraConfig()
    own = CameraConfig(eye=(1.0, 0.1, 1.8))
    assert camera_for_layout(own, layout) is own


@pytest.mark.parametrize("robot", ROBOT_NAMES)
def test_every_arm_reaches_the_default_workspace_centre(robot):
    with SimWorld(SimConfig()) as world:
        arm = make_robot(robot, world.client, DEFAULT_LAYOUT)  # its home: raises where it cannot
        check_workspace_reach(arm, robot)  # the centre at the table: raises where it cannot


def test_a_layout_out_of_reach_is_refused_before_the_episode_writes_anything(tmp_path, capsys):
    from foldbot.cli import main

    path = tmp_path / "far.toml"
    path.write_text("table_size = [2.4, 1.2]\ntable_center_xy = [0.8, 0.0]\n")
    path.write_text(path.read_text() + "workspace_center_xy = [0.9, 0.0]\ntable_height = 0.4\n")
    path.write_text(path.read_text() + "robot_base_xyz = [0.0, 0.0, 0.75]\n")
    out = tmp_path / "ep"
    assert main(["fold", "--layout", str(path), "--resolution", "5", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "the ur5 mounted at (0, 0, 0.75) m cannot reach the workspace centre (0.9, 0) m" in err
    assert not out.exists() and not list(tmp_path.glob("ep*"))


def test_a_workspace_out_of_the_arms_reach_is_refused_naming_the_layout():
    far = CellLayout(
        table_size=(2.0, 1.2), table_center_xy=(0.8, 0.0), workspace_center_xy=(1.3, 0)
    )
    with SimWorld(SimConfig(layout=far)) as world, pytest.raises(ConfigError) as exc:
        make_robot("ur5", world.client, far)
    text = str(exc.value)
    assert "the ur5 mounted at (0, 0, 0.75) m cannot reach the workspace centre (1.3, 0) m" in text
    assert "move the layout's workspace_center_xy, robot_base_xyz or table_height" in text


CAMERA_MOUNT = Path(__file__).resolve().parents[2] / "layouts" / "camera_mount.toml"


def test_a_layout_files_obstacles_load_named_and_are_recorded():
    layout = load_layout(CAMERA_MOUNT)
    assert [o.name for o in layout.obstacles] == ["camera_post", "camera_bar"]
    post = layout.obstacles[0]
    assert post.center_xyz == (1.20, 0.0, 0.90) and post.size_xyz == (0.08, 0.08, 1.80)
    lo, hi = post.bounds
    assert lo == pytest.approx((1.16, -0.04, 0.0)) and hi == pytest.approx((1.24, 0.04, 1.8))
    assert layout.changes() == {
        "obstacles": [
            {"name": "camera_post", "center_xyz": [1.2, 0.0, 0.9], "size_xyz": [0.08, 0.08, 1.8]},
            {"name": "camera_bar", "center_xyz": [1.17, 0.0, 1.8], "size_xyz": [0.14, 0.06, 0.06]},
        ]
    }
    assert not any(layout.workspace_shift())  # the cell itself is the default one


def test_an_obstacle_blocks_the_lines_through_it_only():
    from foldbot.sim.layout import Obstacle

    box = Obstacle("lamp", (0.0, 0.0, 1.0), (0.2, 0.2, 0.2))
    assert box.blocks((0.0, 0.0, 2.0), (0.0, 0.0, 0.0))  # straight down through it
    assert box.blocks((-1.0, 0.05, 1.05), (1.0, 0.05, 1.05))  # across it
    assert not box.blocks((0.0, 0.0, 2.0), (0.0, 0.0, 1.2))  # stops short of its top
    assert not box.blocks((0.5, 0.0, 2.0), (0.5, 0.0, 0.0))  # beside it
    assert not box.blocks((1.0, 0.0, 2.0), (0.3, 0.0, 0.0))  # passes by its corner


def test_a_turned_obstacle_blocks_reaches_and_is_built_as_turned():
    import pybullet as p

    from foldbot.sim.layout import Obstacle

    # A 40 × 4 cm wall turned 45°: its corners, its extent along the world's axes, the lines
    # through it and past its ends, and the cell's box.
    wall = Obstacle("wall", (1.0, 0.5, 1.0), (0.4, 0.04, 0.5), yaw_deg=45.0)
    corners = np.array(wall.footprint())
    assert np.linalg.norm(corners[1] - corners[0]) == pytest.approx(0.4)
    lo, hi = wall.bounds
    assert hi[0] - lo[0] == pytest.approx((0.4 + 0.04) / np.sqrt(2))
    assert wall.blocks((1.0, 0.3, 1.0), (1.0, 0.7, 1.0))  # across its middle
    assert not wall.blocks((1.1, 0.3, 1.0), (1.1, 0.42, 1.0))  # inside its extent, not it
    assert (
        wall.as_dict()["yaw_deg"] == 45.0
        and "yaw_deg" not in Obstacle("post", (1.0, 0.5, 1.0), (0.1, 0.1, 0.1)).as_dict()
    )
    # Turned, a box whose extent along the axes meets the workspace's corner is allowed where
    # it does not: its side passes 1.8 cm beside the corner (0.75, 0.3).
    near = Obstacle("near", (0.77, 0.32, 0.9), (0.02, 0.30, 0.3), yaw_deg=45.0)
    assert near.bounds[0][0] < 0.75 and near.bounds[0][1] < 0.3
    CellLayout(obstacles=(near,))
    with pytest.raises(ConfigError, match="reaches into the cloth workspace"):
        CellLayout(obstacles=(Obstacle("in", (0.755, 0.305, 0.9), (0.02, 0.30, 0.3), 45.0),))
    with SimWorld(SimConfig(layout=CellLayout(obstacles=(wall,)))) as world:
        pos, quat = p.getBasePositionAndOrientation(
            world.obstacle_ids["wall"], physicsClientId=world.client
        )
        assert pos == pytest.approx((1.0, 0.5, 1.0))
        assert p.getEulerFromQuaternion(quat)[2] == pytest.approx(np.pi / 4)


def test_the_simulated_cell_builds_each_obstacle_where_the_layout_puts_it():
    import pybullet as p

    with SimWorld(SimConfig(layout=load_layout(CAMERA_MOUNT))) as world:
        assert list(world.obstacle_ids) == ["camera_post", "camera_bar"]
        lo, hi = p.getAABB(world.obstacle_ids["camera_post"], physicsClientId=world.client)
        assert lo == pytest.approx((1.16, -0.04, 0.0), abs=0.002)
        assert hi == pytest.approx((1.24, 0.04, 1.8), abs=0.002)
    with SimWorld() as world:
        assert world.obstacle_ids == {}


def test_an_obstacle_contains_the_points_inside_it_grown_by_a_margin():
    from foldbot.sim.layout import Obstacle

    # A 20 × 4 × 10 cm box turned 90°: its long side along the world's y.
    box = Obstacle("bin", (1.0, 0.5, 0.8), (0.2, 0.04, 0.1), yaw_deg=90.0)
    points = np.array(
        [
            [1.0, 0.5, 0.8],  # its centre
            [1.0, 0.59, 0.8],  # 9 cm along its long side: inside
            [1.05, 0.5, 0.8],  # 5 cm across it, 3 cm past its side
            [1.025, 0.5, 0.8],  # 0.5 cm past its side
            [1.0, 0.5, 0.86],  # 1 cm over its top
        ]
    )
    np.testing.assert_array_equal(box.contains(points), [True, True, False, False, False])
    np.testing.assert_array_equal(box.contains(points, 0.015), [True, True, False, True, True])
    assert box.contains(points.reshape(5, 1, 3)).shape == (5, 1)
    corners = box.corners(0.01)
    assert corners.shape == (8, 3)
    np.testing.assert_allclose(corners.min(axis=0), [0.97, 0.39, 0.74], atol=1e-12)
    np.testing.assert_allclose(corners.max(axis=0), [1.03, 0.61, 0.86], atol=1e-12)
    assert box.contains(corners, 0.01 + 1e-9).all()
