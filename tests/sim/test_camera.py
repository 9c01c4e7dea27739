"""The simulated RGB-D camera: configuration checks, projection from K, depth, noise."""

from __future__ import annotations

import dataclasses

import numpy as np
import pybullet as p
import pytest

from foldbot.errors import ConfigError
from foldbot.perception.geometry import backproject, project_points
from foldbot.sim.camera import CameraConfig, Lighting, RGBDCamera, depth_from_buffer, look_at
from foldbot.sim.world import SimWorld


@pytest.fixture(scope="module")
def plate_world():
    """A table with a thin red plate of known corners on it (20 × 14 cm, 5 cm up, turned)."""
    world = SimWorld()
    half = [0.1, 0.07, 0.0001]
    pos, yaw = [0.43, 0.05, 0.80], 0.3
    rot = p.getQuaternionFromEuler([0, 0, yaw])
    vis = p.createVisualShape(
        p.GEOM_BOX, halfExtents=half, rgbaColor=[1, 0, 0, 1], physicsClientId=world.client
    )
    body = p.createMultiBody(
        0, -1, vis, basePosition=pos, baseOrientation=rot, physicsClientId=world.client
    )
    R = np.array(p.getMatrixFromQuaternion(rot)).reshape(3, 3)
    corners = np.array([[sx * half[0], sy * half[1], half[2]] for sx, sy in
                        [(-1, -1), (1, -1), (1, 1), (-1, 1)]]) @ R.T + pos  # fmt: skip
    yield world, body, corners
    world.close()


def _inside(uv: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    v, u = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    s = []
    for k in range(4):
        a, b = uv[k], uv[(k + 1) % 4]
        s.append((b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0]))
    s = np.array(s)
    return np.all(s > 0, axis=0) | np.all(s < 0, axis=0)


@pytest.mark.parametrize(
    "config",
    [
        CameraConfig(width=320, height=240),
        CameraConfig(width=321, height=239, fx=450.0, fy=470.0, cx=140.3, cy=131.8),
    ],
)
def test_pixels_see_the_rays_K_says(plate_world, config: CameraConfig) -> None:
    world, body, corners = plate_world
    cam = RGBDCamera(world.client, config)
    seg = cam.render_segmentation() == body
    uv, _ = project_points(corners, cam.intrinsics, cam.T_world_camera)
    predicted = _inside(uv, seg.shape)
    boundary = seg.sum() ** 0.5 * 4
    assert (predicted != seg).sum() < 0.05 * boundary  # off by a pixel would flip ~all of them


def test_depth_is_metres_along_the_optical_axis(plate_world) -> None:
    world, body, corners = plate_world
    cam = RGBDCamera(world.client, CameraConfig(width=160, height=120))
    obs = cam.observe()
    seg = cam.render_segmentation()
    assert obs.rgb.dtype == np.uint8 and obs.rgb.shape == (120, 160, 3)
    assert obs.depth.dtype == np.float32 and obs.depth.shape == (120, 160)
    v, u = np.nonzero(seg == world.table_id)
    pts = backproject(np.c_[u, v], obs.depth[v, u], obs.intrinsics, obs.T_world_camera)
    np.testing.assert_allclose(pts[:, 2], world.layout.table_height, atol=2e-4)
    v, u = np.nonzero(seg == body)
    pts = backproject(np.c_[u, v], obs.depth[v, u], obs.intrinsics, obs.T_world_camera)
    np.testing.assert_allclose(pts[:, 2], corners[0, 2], atol=2e-4)


def test_depth_buffer_conversion() -> None:
    near, far = 0.4, 2.0
    z = np.array([0.4, 1.0, 1.9])
    d = (far / (far - near)) * (1 - near / z)  # OpenGL depth of z
    np.testing.assert_allclose(depth_from_buffer(d, near, far), z, rtol=1e-6)
    assert np.isnan(depth_from_buffer(np.array([1.0]), near, far)[0])


def test_nothing_in_view_reads_nan(plate_world) -> None:
    world, _, _ = plate_world
    up = CameraConfig(
        width=64, height=48, eye=(0.5, 0.0, 2.0), target=(0.5, 0.0, 3.0), up=(1, 0, 0)
    )
    obs = RGBDCamera(world.client, up).observe()
    assert np.all(np.isnan(obs.depth))


def test_noise_is_seeded_and_grows_with_depth(plate_world) -> None:
    world, _, _ = plate_world
    clean = RGBDCamera(world.client, CameraConfig(width=160, height=120)).observe()
    cfg = CameraConfig(width=160, height=120, depth_noise=0.002, rgb_noise=3.0, depth_dropout=0.05)
    a = RGBDCamera(world.client, cfg).observe()
    b = RGBDCamera(world.client, cfg).observe()
    c = RGBDCamera(world.client, cfg).observe(rng=np.random.default_rng(7))
    np.testing.assert_array_equal(a.rgb, b.rgb)
    np.testing.assert_array_equal(np.nan_to_num(a.depth), np.nan_to_num(b.depth))
    assert not np.array_equal(a.rgb, c.rgb)
    holes = np.isnan(a.depth) & ~np.isnan(clean.depth)
    assert 0.03 < holes.mean() < 0.07
    ok = ~np.isnan(a.depth)
    ratio = (a.depth - clean.depth)[ok] / (0.002 * clean.depth[ok] ** 2)
    assert np.std(ratio) == pytest.approx(1.0, abs=0.05)
    assert np.abs(a.rgb.astype(int) - clean.rgb).mean() > 1.0


def test_default_pose_and_intrinsics() -> None:
    cfg = CameraConfig()
    K = cfg.K
    assert (K[0, 2], K[1, 2]) == ((640 - 1) / 2, (480 - 1) / 2)
    T = cfg.T_world_camera
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], cfg.eye)
    axis = np.subtract(cfg.target, cfg.eye)
    np.testing.assert_allclose(T[:3, 2], axis / np.linalg.norm(axis), atol=1e-12)
    # The workspace (0.6 m square on the table) is in view.
    ws = np.array([[x, y, 0.75] for x in (0.15, 0.75) for y in (-0.3, 0.3)])
    uv, z = project_points(ws, cfg.intrinsics, T)
    assert np.all(z > 0)
    assert np.all((uv >= 0) & (uv <= [639, 479]))
    pose_cfg = CameraConfig(pose=tuple(map(tuple, look_at((1, 0, 2), (0.4, 0, 0.75)))))
    np.testing.assert_allclose(pose_cfg.T_world_camera, look_at((1, 0, 2), (0.4, 0, 0.75)))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"width": 0}, "width"),
        ({"height": 10.5}, "height"),
        ({"fx": -3.0}, "fx"),
        ({"cy": 1000.0}, "cy"),
        ({"near": 0.0}, "near"),
        ({"near": 1.0, "far": 0.9}, "far"),
        ({"eye": (0.5, 0.0, 0.75), "target": (0.5, 0.0, 0.75)}, "eye"),
        ({"eye": (0.5, 0.0, 2.0), "target": (0.5, 0.0, 0.75), "up": (0, 0, 1)}, "up"),
        ({"pose": np.diag([2.0, 1.0, 1.0, 1.0])}, "pose"),
        ({"depth_noise": -0.1}, "depth_noise"),
        ({"rgb_noise": float("nan")}, "rgb_noise"),
        ({"depth_dropout": 1.0}, "depth_dropout"),
        ({"eye": (1.0, float("inf"), 2.0)}, "eye"),
    ],
)
def test_config_errors_name_the_value(kwargs: dict, name: str) -> None:
    with pytest.raises(ConfigError, match=name):
        CameraConfig(**kwargs)


def test_lighting_validation_and_change(plate_world) -> None:
    with pytest.raises(ConfigError, match="color"):
        Lighting(color=(2.0, 1.0, 1.0))
    with pytest.raises(ConfigError, match="ambient"):
        Lighting(ambient=-0.1)
    with pytest.raises(ConfigError, match="direction"):
        Lighting(direction=(0.0, 0.0, 0.0))
    world, _, _ = plate_world
    cam = RGBDCamera(world.client, CameraConfig(width=64, height=48))
    bright = cam.observe().rgb.astype(int).mean()
    cam.lighting = dataclasses.replace(cam.lighting, ambient=0.2, diffuse=0.1)
    assert cam.observe().rgb.astype(int).mean() < bright - 10


@pytest.mark.parametrize("name", ["ur5", "ur5e", "panda"])
def test_the_out_of_view_park_hides_nothing_from_the_default_camera(name):
    """At home the gripper hangs over the workspace and hides a large cloth's near edge; parked,
    no pixel of the arm is in the default camera's image, and the TCP is where the park says."""
    from foldbot.sim.robots import make_robot
    from foldbot.sim.robots.base import OUT_OF_VIEW_TCP_FROM_BASE

    with SimWorld() as world:
        robot = make_robot(name, world.client, world.layout)
        camera = RGBDCamera(world.client, CameraConfig())
        robot.reset_joints(robot.home_q)
        assert (camera.render_segmentation() == robot.body_id).any()
        robot.reset_joints(robot.out_of_view_q)
        assert not (camera.render_segmentation() == robot.body_id).any()
        bx, by, _ = world.layout.robot_base_xyz
        dx, dy, dz = OUT_OF_VIEW_TCP_FROM_BASE
        expected = [bx + dx, by + dy, world.layout.table_height + dz]
        assert robot.tcp_pose()[0] == pytest.approx(expected, abs=2e-3)


def test_a_reported_pose_is_what_observations_carry_the_image_is_the_true_pose(
    plate_world,
) -> None:
    """A calibration's pose (`reported_pose`) goes to perception with each frame; the picture is
    still rendered from where the camera stands, so a plate's corners back-projected through
    the reported pose land off by the calibration's error."""
    world, _body, corners = plate_world
    true = CameraConfig(width=320, height=240)
    off = true.T_world_camera.copy()
    off[:3, 3] += (0.004, -0.003, 0.0)  # a calibration 5 mm off
    cam = RGBDCamera(world.client, dataclasses.replace(true, reported_pose=off))
    exact = RGBDCamera(world.client, true)
    seen, truth = cam.observe(), exact.observe()
    np.testing.assert_array_equal(seen.rgb, truth.rgb)
    np.testing.assert_array_equal(seen.depth, truth.depth)
    np.testing.assert_allclose(seen.T_world_camera, off)
    np.testing.assert_allclose(cam.T_world_camera, true.T_world_camera)
    np.testing.assert_allclose(cam.reported_T_world_camera, off)
    inner = corners + 0.7 * (corners.mean(axis=0) - corners)  # on the plate, off its edges
    uv, _ = project_points(inner, truth.intrinsics, truth.T_world_camera)
    px = np.rint(uv).astype(int)
    back = backproject(px, seen.depth[px[:, 1], px[:, 0]], seen.intrinsics, seen.T_world_camera)
    exact_back = backproject(
        px, truth.depth[px[:, 1], px[:, 0]], truth.intrinsics, exact.T_world_camera
    )
    assert np.linalg.norm(exact_back - inner, axis=1).max() < 0.003  # half a pixel, rounded
    shift = np.linalg.norm(back - exact_back, axis=1)
    np.testing.assert_allclose(shift, 0.005, atol=1e-6)  # a rigid shift: the calibration's
    with pytest.raises(ConfigError, match="camera reported_pose must be a rigid 4×4"):
        CameraConfig(reported_pose=np.diag([1.0, 2.0, 1.0, 1.0]))
