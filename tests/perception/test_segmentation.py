"""Cloth segmentation on rendered scenes: colour, depth-only, arm in view, noise, no cloth."""

from __future__ import annotations

import numpy as np
import pytest

from foldbot.commands.eval_perception import default_scene, render_mesh, render_scene
from foldbot.errors import ConfigError
from foldbot.garments.mesh import ClothMesh
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.perception.segmentation import SegmentationConfig, heap_tops, segment_cloth
from foldbot.perception.state import mask_iou
from foldbot.sim.camera import CameraConfig, RGBDCamera
from foldbot.sim.world import SimWorld

W, H = 320, 240


def test_distinct_colours_use_the_colour_cue() -> None:
    r = render_scene(default_scene(yaw=0.4, rgb_noise=3.0), W, H, 10, settle_time=0)
    obs, truth = r.obs, r.cloth_mask
    seg = segment_cloth(obs)
    assert seg.cue == "colour"
    assert mask_iou(seg.mask, truth) > 0.97
    # Heights are above the fitted table plane; the plane is the table top (z = 0.75 m, up).
    np.testing.assert_allclose(seg.plane_world.normal, [0, 0, 1], atol=2e-3)
    assert seg.plane_world.offset == pytest.approx(-0.75, abs=5e-4)
    assert seg.height.shape == (H // 2, W // 2)  # one height per 2×2 block
    table = ~truth[::2, ::2] & np.isfinite(seg.height)
    assert np.abs(np.median(seg.height[table])) < 2e-4


def test_same_colour_as_the_table_falls_back_to_depth() -> None:
    """A settled cloth lies only ~2 mm above the table: depth alone must find it, with noise."""
    scene = default_scene(yaw=-0.3, cloth_rgb=(0.55, 0.45, 0.35), depth_noise=0.001, rgb_noise=2.0)
    r = render_scene(scene, W, H, 10, settle_time=0.6)
    obs, truth = r.obs, r.cloth_mask
    seg = segment_cloth(obs)
    assert seg.cue == "depth"
    assert 0.001 < seg.cloth_height < 0.008
    assert mask_iou(seg.mask, truth) > 0.93


def test_arm_over_the_cloth_is_not_cloth() -> None:
    scene = default_scene(yaw=0.2, arm_target=(0.45, 0.0, 0.90), depth_dropout=0.01)
    r = render_scene(scene, W, H, 10, settle_time=0)
    seg = segment_cloth(r.obs)
    assert r.robot_mask.sum() > 500 and seg.occluder.sum() > 500  # the gripper is in view
    # The mask also covers the cloth hidden under the gripper: score what the arm leaves visible.
    assert mask_iou(seg.mask & ~r.robot_mask, r.cloth_mask) > 0.97
    assert (seg.mask & ~r.cloth_mask & ~seg.occluder).sum() < 0.01 * r.cloth_mask.sum()


def test_empty_table_has_no_cloth() -> None:
    with SimWorld() as world:
        cfg = CameraConfig(width=W, height=H, depth_noise=0.001, rgb_noise=3.0)
        obs = RGBDCamera(world.client, cfg).observe()
    seg = segment_cloth(obs)
    assert not seg.found and seg.cue == "none"


def test_config_is_validated() -> None:
    with pytest.raises(ConfigError, match="smooth_size"):
        SegmentationConfig(smooth_size=4)
    with pytest.raises(ConfigError, match="occluder_height"):
        SegmentationConfig(occluder_height=-1.0)
    with pytest.raises(ConfigError, match="max_heap_height"):
        SegmentationConfig(max_heap_height=0.05)  # under occluder_height (0.06)


def ridge_towel() -> ClothMesh:
    """A 40 × 30 cm towel draped over a ridge across it, 10 cm high (a crumpled heap's top is
    as high): steep down to the flat left part, gentle down to the right edge."""
    towel = make_towel(TowelSpec(0.40, 0.30, 17))
    v = towel.vertices.copy()
    x = v[:, 0]
    left = np.clip(0.10 * (1.0 - (-0.06 - x) / 0.04), 0.0, None)
    v[:, 2] = np.where(x < -0.06, left, 0.10 - 0.09 * (x + 0.06) / 0.26)
    return ClothMesh(v, towel.faces, towel.keypoints, towel.grid_shape)


def test_a_heap_higher_than_the_arm_threshold_is_cloth() -> None:
    """Cloth over `occluder_height` (6 cm) that is cloth-coloured, low and clear of the image
    border is a heap's top: the whole towel is one mask. (Taken for the arm, the ridge's top
    cut the towel in two and the flat part was dropped: IoU 0.43.)"""
    r = render_mesh(default_scene(yaw=0.0), ridge_towel(), lambda o: {}, W, H, 0, 0.0)
    seg = segment_cloth(r.obs)
    assert seg.cue == "colour"
    assert mask_iou(seg.mask, r.cloth_mask) > 0.97
    assert not seg.occluder.any()
    # The heap's top has heights (the arm's pixels have none).
    assert np.nanmax(seg.height) > 0.08


def test_heap_tops_are_low_cloth_coloured_blobs_inside_the_image() -> None:
    occ = np.zeros((40, 60), bool)
    height = np.full(occ.shape, 0.01, np.float32)
    cloth = np.zeros(occ.shape, bool)
    occ[10:20, 10:20] = cloth[10:20, 10:20] = True  # a heap's top
    height[10:20, 10:20] = 0.09
    occ[10:20, 30:40] = True  # the gripper: not cloth-coloured
    height[10:20, 30:40] = 0.09
    occ[25:35, 10:20] = cloth[25:35, 10:20] = True  # cloth-coloured, but higher than a heap
    height[25:35, 10:20] = 0.35
    occ[0:8, 50:60] = cloth[0:8, 50:60] = True  # cloth-coloured, entering from the border
    height[0:8, 50:60] = 0.09
    tops = heap_tops(occ, height, cloth, 0.2)
    expected = np.zeros(occ.shape, bool)
    expected[10:20, 10:20] = True
    np.testing.assert_array_equal(tops, expected)
    occ[10:20, 10:20] = False
    assert heap_tops(occ, height, cloth, 0.2) is None
