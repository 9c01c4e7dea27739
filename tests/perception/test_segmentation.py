"""Cloth segmentation on rendered scenes: colour, depth-only, arm in view, noise, no cloth."""

from __future__ import annotations

import numpy as np
import pytest

from foldbot.commands.eval_perception import default_scene, render_scene
from foldbot.errors import ConfigError
from foldbot.perception.segmentation import SegmentationConfig, segment_cloth
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


def test_a_towel_filling_most_of_the_view_leaves_the_table_plane_level() -> None:
    """A settled 50 cm towel covers more of the view than the table: the plane through it must
    not be taken for the table (it was, tilted, and cut 7 % of the towel off the mask)."""
    r = render_scene(
        default_scene(towel_width=0.5, towel_height=0.5), 640, 480, 12, settle_time=1.0
    )
    seg = segment_cloth(r.obs)
    np.testing.assert_allclose(seg.plane_world.normal, [0, 0, 1], atol=2e-3)
    assert seg.plane_world.offset == pytest.approx(-0.75, abs=5e-4)
    assert mask_iou(seg.mask, r.cloth_mask) > 0.98
