"""GarmentEstimator: T-shirt and pants keypoints from RGB-D only, on rendered and synthetic frames.

Tolerances: `foldbot eval-perception --garment {tshirt,pants} --scenes 20` (640×480, randomised
colours, lighting, noise, camera jitter, yaw 90° ± 15°) measured a largest keypoint error of 1.6 mm
(T-shirt) and 2.7 mm (pants, the crotch: the legs nearly touch there); the rendered tests allow
3 mm for T-shirt keypoints and pants corners and 5 mm for the crotch (about twice the largest
measured), the synthetic frames (exact polygons) 2 mm.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from foldbot.errors import ConfigError, PerceptionError
from foldbot.garments.outline import points_inside
from foldbot.garments.pants import PANTS_KEYPOINTS, PantsSpec, pants_outline
from foldbot.garments.tshirt import TSHIRT_KEYPOINTS, TShirtSpec, tshirt_outline
from foldbot.perception.garment_keypoints import (
    GarmentEstimator,
    GarmentKeypointConfig,
    symmetry_axis,
)
from foldbot.perception.state import NO_CLOTH
from foldbot.sim.camera import look_at
from foldbot.sim.perception_scenes import default_garment_scene, render_garment_scene
from foldbot.types import CameraIntrinsics, Observation


def _errors_mm(state, truth: dict[str, np.ndarray]) -> dict[str, float]:
    return {n: 1000 * float(np.linalg.norm(state.keypoints[n][0] - truth[n])) for n in truth}


def test_tshirt_keypoints_of_a_settled_shirt() -> None:
    spec = TShirtSpec(edge_length=0.035)
    scene = default_garment_scene(spec, yaw=math.radians(100), x=0.47, y=0.02, rgb_noise=2.0)
    r = render_garment_scene(scene, 640, 480, settle_time=0.3)
    state = GarmentEstimator("tshirt").estimate(r.obs)
    assert state.detected and tuple(state.keypoints) == TSHIRT_KEYPOINTS
    err = _errors_mm(state, r.corners)
    assert max(err.values()) < 3.0, err
    assert all(0.5 < conf <= 1.0 for _, conf in state.keypoints.values())
    area = tshirt_outline(spec).area
    assert state.coverage_m2 == pytest.approx(area, rel=0.03)
    assert state.flatness < 0.004
    np.testing.assert_allclose(state.table_plane[:3], [0, 0, 1], atol=2e-3)
    assert state.mask.shape == (480, 640) and len(state.outline_world) > 100


def test_pants_keypoints_seen_by_depth_alone() -> None:
    """Cloth the colour of the table: the mask comes from depth only (blurrier edges)."""
    spec = PantsSpec(hem_gap=0.05, edge_length=0.035)
    scene = default_garment_scene(
        spec, yaw=math.radians(78), cloth_rgb=(0.56, 0.45, 0.36), depth_noise=0.0008
    )
    r = render_garment_scene(scene, 640, 480, settle_time=0.3)
    state = GarmentEstimator("pants").estimate(r.obs)
    assert state.detected and state.reason.startswith("segmented by depth")
    assert tuple(state.keypoints) == PANTS_KEYPOINTS
    err = _errors_mm(state, r.corners)
    assert err["crotch"] < 5.0, err
    assert max(v for k, v in err.items() if k != "crotch") < 3.0, err


# ---- synthetic frames: a top-down camera over a flat table, the outline drawn exactly ----------

TABLE_Z = 0.75
W, H = 640, 480


def _top_down_obs(
    polygon_world: np.ndarray | None,
    cloth_height: float = 0.003,
    arm: tuple[float, float, float, float, float] | None = None,
) -> Observation:
    """A noise-free RGB-D frame from 1 m above (0.45, 0) (image up = world −x) of a table with a
    flat cloth `polygon_world` (N×2, world x, y) lying on it, and optionally a dark `arm` box
    (x0, x1, y0, y1, height above the table, m) over it."""
    K = np.array([[880.0, 0, (W - 1) / 2], [0, 880.0, (H - 1) / 2], [0, 0, 1]])
    T = look_at((0.45, 0.0, TABLE_Z + 1.0), (0.45, 0.0, TABLE_Z), (-1.0, 0.0, 0.0))
    u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    dirs = rays @ T[:3, :3].T
    eye = T[:3, 3]
    depth = (TABLE_Z - eye[2]) / dirs[..., 2]
    rgb = np.full((H, W, 3), (150, 130, 110), np.uint8)
    if polygon_world is not None:
        t = (TABLE_Z + cloth_height - eye[2]) / dirs[..., 2]
        hit = eye[:2] + t[..., None] * dirs[..., :2]
        inside = points_inside(hit.reshape(-1, 2), polygon_world).reshape(H, W)
        depth = np.where(inside, t, depth)
        rgb[inside] = (40, 80, 200)
    if arm is not None:
        x0, x1, y0, y1, height = arm
        t = (TABLE_Z + height - eye[2]) / dirs[..., 2]
        hit = eye[:2] + t[..., None] * dirs[..., :2]
        above = (
            (hit[..., 0] >= x0) & (hit[..., 0] <= x1) & (hit[..., 1] >= y0) & (hit[..., 1] <= y1)
        )
        depth = np.where(above, t, depth)
        rgb[above] = (30, 30, 30)
    return Observation(
        rgb=rgb,
        depth=depth.astype(np.float32),
        intrinsics=CameraIntrinsics(K=K, width=W, height=H),
        T_world_camera=T,
    )


def _place(points: np.ndarray, yaw: float, centre=(0.45, 0.0)) -> np.ndarray:
    """Mesh-frame outline points → world x, y (bounding box centred at `centre`, turned by yaw)."""
    p = points - 0.5 * (points.min(axis=0) + points.max(axis=0))
    c, s = math.cos(yaw), math.sin(yaw)
    return p @ np.array([[c, s], [-s, c]]) + np.asarray(centre)


@pytest.mark.parametrize(
    ("kind", "yaw_deg"),
    [
        ("tshirt", 75),
        ("tshirt", 105),
        ("pants", 90),
        # Lying any way round: the top is read from the shape, not from the prior, and every
        # keypoint keeps its own name (a left/right swap would be decimetres off).
        ("tshirt", 0),
        ("tshirt", 180),
        ("tshirt", 250),
        ("pants", 10),
        ("pants", 300),
    ],
)
def test_synthetic_garments(kind: str, yaw_deg: float) -> None:
    outline = (
        tshirt_outline(TShirtSpec(sleeve_angle=0.5))
        if kind == "tshirt"
        else pants_outline(PantsSpec(hem_gap=0.07))
    )
    world = _place(outline.points, math.radians(yaw_deg))
    state = GarmentEstimator(kind).estimate(_top_down_obs(world))
    assert state.detected, state.reason
    truth = {n: np.r_[world[i], TABLE_Z + 0.003] for n, i in outline.keypoints.items()}
    err = _errors_mm(state, truth)
    assert max(err.values()) < 2.0, err
    assert state.coverage_m2 == pytest.approx(outline.area, rel=0.01)


def test_a_narrow_axis_window_keeps_the_garment_near_its_prior() -> None:
    """With the search held to ± 45° of the prior, a sideways T-shirt's axis is not found."""
    outline = tshirt_outline(TShirtSpec(sleeve_angle=0.5))
    obs = _top_down_obs(_place(outline.points, 0.0))
    narrow = GarmentKeypointConfig(axis_window=math.radians(45.0))
    state = GarmentEstimator("tshirt", narrow).estimate(obs)
    assert not state.detected and "not a flat tshirt" in state.reason


def test_flipped_frame_swaps_top_and_right() -> None:
    outline = tshirt_outline(TShirtSpec())
    world = _place(outline.points, math.radians(90))
    frame = symmetry_axis(world, GarmentKeypointConfig())
    back = frame.flipped()
    np.testing.assert_allclose(back.top, -frame.top)
    np.testing.assert_allclose(back.right, -frame.right)
    uv = frame.to_frame(world)
    np.testing.assert_allclose(back.to_frame(world), -uv, atol=1e-12)
    np.testing.assert_allclose(back.to_world(back.to_frame(world)), world, atol=1e-12)


def test_symmetry_axis_points_to_the_top() -> None:
    outline = tshirt_outline(TShirtSpec())
    for yaw_deg in (70, 90, 110):
        world = _place(outline.points, math.radians(yaw_deg))
        dense = np.concatenate(
            [
                np.linspace(a, b, 20, endpoint=False)
                for a, b in zip(world, np.roll(world, -1, 0), strict=True)
            ]
        )
        frame = symmetry_axis(dense, GarmentKeypointConfig())
        top = math.radians(yaw_deg) + math.pi / 2  # mesh +y turned by the yaw
        assert frame.top @ [math.cos(top), math.sin(top)] > math.cos(math.radians(0.2))
        assert frame.residual < 0.001


def test_a_towel_is_no_flat_garment() -> None:
    """A towel is mirror-symmetric but has no neck, armpits or sleeves, and no gap between legs:
    not detected, so a caller falls back to the generic estimator."""
    towel = _place(np.array([[0, 0], [0.3, 0], [0.3, 0.25], [0, 0.25]], float), 0.3)
    obs = _top_down_obs(towel)
    shirt = GarmentEstimator("tshirt").estimate(obs)
    assert not shirt.detected and shirt.keypoints == {}
    assert shirt.reason.startswith("not a flat tshirt: not found: neck")
    assert "left_hem" not in shirt.reason  # the towel's bottom corners pass for hem corners
    pants = GarmentEstimator("pants").estimate(obs)
    assert not pants.detected and "left_leg_inner, right_leg_inner, crotch" in pants.reason


def test_an_asymmetric_outline_is_no_flat_garment() -> None:
    l_shape = np.array([[0, 0], [0.3, 0], [0.3, 0.1], [0.12, 0.1], [0.12, 0.22], [0, 0.22]], float)
    state = GarmentEstimator("pants").estimate(_top_down_obs(_place(l_shape, 0.2)))
    assert not state.detected and "mirror-symmetric" in state.reason


def test_garment_cut_by_the_image_border_is_refused() -> None:
    outline = tshirt_outline(TShirtSpec())
    world = _place(outline.points, math.pi / 2, centre=(0.45, 0.25))
    state = GarmentEstimator("tshirt").estimate(_top_down_obs(world))
    assert not state.detected and "image border" in state.reason
    assert state.keypoints == {} and state.mask.shape == (H, W)


def test_no_cloth_and_bad_input() -> None:
    obs = _top_down_obs(None)
    state = GarmentEstimator("pants").estimate(obs)
    assert not state.detected and state.reason == NO_CLOTH
    bad = Observation(
        obs.rgb, (obs.depth * 1000).astype(np.uint16), obs.intrinsics, obs.T_world_camera
    )
    with pytest.raises(PerceptionError, match="depth must be float"):
        GarmentEstimator("tshirt").estimate(bad)
    with pytest.raises(ConfigError, match="'sock'"):
        GarmentEstimator("sock")
    with pytest.raises(ConfigError, match="axis_window"):
        GarmentKeypointConfig(axis_window=0.0)


@pytest.mark.parametrize(
    ("arm", "hidden", "tolerance_mm"),
    [
        ((0.20, 0.33, -0.16, -0.06, 0.25), "left_waist", 4.0),
        ((0.20, 0.34, 0.04, 0.16, 0.25), "right_waist", 5.0),
        # Hiding more of the waist: the whole outline's mirror residual (6.2 mm) alone refused it.
        ((0.20, 0.35, -0.20, -0.03, 0.25), "left_waist", 8.0),
    ],
)
def test_a_corner_the_arm_hides_is_its_partner_mirrored(arm, hidden: str, tolerance_mm) -> None:
    """The gripper parked over a waist corner (the home pose over the pants of the suite): the
    amodal mask's outline runs straight across what the arm hides, and its corner there lay
    43–58 mm off; the axis is now fitted on the outline the arm leaves in sight and the hidden
    corner is its partner's mirror image."""
    outline = pants_outline(PantsSpec(hem_gap=0.07))
    world = _place(outline.points, math.radians(90))
    truth = {n: np.r_[world[i], TABLE_Z + 0.003] for n, i in outline.keypoints.items()}
    state = GarmentEstimator("pants").estimate(_top_down_obs(world, arm=arm))
    assert state.detected, state.reason
    err = _errors_mm(state, truth)
    assert err[hidden] < tolerance_mm, err
    assert max(v for k, v in err.items() if k != hidden) < 2.0, err
    assert state.keypoints[hidden][1] < 0.3  # still marked as next to the arm


@pytest.mark.parametrize("reach_below", [0.03, 0.05, 0.07])
def test_a_crotch_the_arm_hides_is_where_the_inseams_meet(reach_below: float) -> None:
    """The gripper over the crotch: the outline runs across the top of the gap the arm leaves in
    sight, `reach_below` m (on the table, before the box's perspective) below the crotch. The
    inseams seen below it still meet at the crotch; the crossing with the axis was 73 mm off
    where the box reached 7 cm past it (the colour outline's half-pixel shift had also moved that
    stretch of the outline off the arm)."""
    outline = pants_outline(PantsSpec(hem_gap=0.07))
    world = _place(outline.points, math.radians(90))
    truth = {n: np.r_[world[i], TABLE_Z + 0.003] for n, i in outline.keypoints.items()}
    cx, cy = truth["crotch"][:2]
    arm = (cx - 0.08 + reach_below, cx + reach_below, cy - 0.05, cy + 0.05, 0.25)
    state = GarmentEstimator("pants").estimate(_top_down_obs(world, arm=arm))
    assert state.detected, state.reason
    err = _errors_mm(state, truth)
    assert err["crotch"] < 2.0, err
    assert max(err.values()) < 2.0, err


@pytest.mark.parametrize("reach_below", [0.0, 0.01, 0.02])
def test_a_neckline_the_arm_hides_leaves_the_neck_out(reach_below: float) -> None:
    """The gripper over the neckline (where the one-arm cell parks over a T-shirt's top): the
    outline there is the hull's chord, whose crossing with the axis lay 36–45 mm off the neck;
    the shirt was refused ("not found: neck"). It is recognised now, its neck left out and named
    in the reason, every keypoint a fold is planned from where it is."""
    outline = tshirt_outline(TShirtSpec())
    world = _place(outline.points, math.radians(90))
    truth = {n: np.r_[world[i], TABLE_Z + 0.003] for n, i in outline.keypoints.items()}
    nx, ny = truth["neck"][:2]
    arm = (nx - 0.10, nx + reach_below, ny - 0.04 - reach_below, ny + 0.04 + reach_below, 0.25)
    state = GarmentEstimator("tshirt").estimate(_top_down_obs(world, arm=arm))
    assert state.detected, state.reason
    assert "neck" not in state.keypoints and "the arm hides the neck" in state.reason
    del truth["neck"]
    assert max(_errors_mm(state, truth).values()) < 2.0


@pytest.mark.parametrize("yaw_deg", [250, 270, 290])
def test_the_arm_over_a_hem_is_no_hidden_neck(yaw_deg: float) -> None:
    """A shirt lying the other way round from the prior, the gripper over its hem's middle: read
    top-down first, the hidden hem looked like a hidden neck and every other keypoint was found
    upside down (459 mm off); the way round whose neck is in sight is taken."""
    outline = tshirt_outline(TShirtSpec())
    world = _place(outline.points, math.radians(yaw_deg))
    truth = {n: np.r_[world[i], TABLE_Z + 0.003] for n, i in outline.keypoints.items()}
    mx, my = (truth["left_hem"][:2] + truth["right_hem"][:2]) / 2
    arm = (mx - 0.05, mx + 0.05, my - 0.05, my + 0.05, 0.25)
    state = GarmentEstimator("tshirt").estimate(_top_down_obs(world, arm=arm))
    assert state.detected and "hides" not in state.reason, state.reason
    assert max(_errors_mm(state, truth).values()) < 2.0


@pytest.mark.parametrize(
    "arm",
    [
        (0.47, 0.55, 0.10, 0.16, 0.25),
        (0.50, 0.56, 0.09, 0.14, 0.25),
        (0.45, 0.52, 0.10, 0.15, 0.25),
    ],
)
def test_a_gripper_beside_the_side_seam_leaves_the_shoulder_in_place(arm) -> None:
    """A gripper beside the body's right side edge, between the armpit and the hem: the amodal
    mask's hull bulges round it, and the side line the shoulder is found on was fitted through
    that bulge (the shoulder 40–287 mm off at confidence 1.0); it is fitted to the edge in sight."""
    outline = tshirt_outline(TShirtSpec())
    world = _place(outline.points, math.radians(90))
    truth = {n: np.r_[world[i], TABLE_Z + 0.003] for n, i in outline.keypoints.items()}
    state = GarmentEstimator("tshirt").estimate(_top_down_obs(world, arm=arm))
    assert state.detected, state.reason
    assert max(_errors_mm(state, truth).values()) < 4.0
