"""ros-check's look at the cloth (check_node.check_cloth): the towel found whole and over the
workspace, as the fold's first look will see it; a bare table, or a towel the layout's
workspace leaves out, named."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from ros_helpers import requires_ros

pytestmark = requires_ros


@pytest.fixture(scope="module")
def towel_view():
    from rgbd_views import render_views

    color, _depth, corners = render_views()  # a 30 cm towel at (0.55, 0.10), turned 0.3 rad
    return color, corners


def test_a_towel_on_the_table_is_found_whole_over_the_workspace(towel_view):
    from foldbot.ros.check_node import check_cloth
    from foldbot.sim.layout import DEFAULT_LAYOUT

    obs, _corners = towel_view
    check, state = check_cloth(obs, DEFAULT_LAYOUT, "towel")
    assert check.ok and check.name == "the towel", check.detail
    seen = float(re.match(r"found, 4 keypoints, ([0-9.]+) m² seen from above", check.detail)[1])
    assert 0.08 < seen < 0.095  # a 30 cm × 30 cm towel
    assert check.detail.endswith("every one over the workspace")
    assert state.detected


def test_a_towel_the_workspace_leaves_out_is_named_by_its_corners(towel_view):
    from foldbot.ros.check_node import check_cloth
    from foldbot.sim.layout import DEFAULT_LAYOUT

    obs, corners = towel_view
    # A 40 cm workspace (x 0.25–0.65, y ±0.20 m): the towel's far corners lie beyond it.
    small = dataclasses.replace(DEFAULT_LAYOUT, workspace_size=0.4)
    check, _state = check_cloth(obs, small, "towel")
    assert not check.ok
    x0, x1, y0, y1 = small.workspace_bounds
    beyond = [k for k, (x, y, _z) in corners.items() if not (x0 <= x <= x1 and y0 <= y <= y1)]
    assert beyond and "outside the workspace x 0.25–0.65, y -0.20–0.20 m: " in check.detail
    named = check.detail.split(" m: ")[1].split(" (")[0].split(", ")
    assert sorted(named) == sorted(beyond)


def test_a_bare_table_says_to_lay_the_cloth():
    from foldbot.ros.check_node import check_cloth
    from foldbot.sim.camera import CameraConfig, RGBDCamera
    from foldbot.sim.layout import DEFAULT_LAYOUT
    from foldbot.sim.world import SimConfig, SimWorld

    with SimWorld(SimConfig()) as world:
        obs = RGBDCamera(world.client, CameraConfig()).observe()
    check, state = check_cloth(obs, DEFAULT_LAYOUT, "tshirt")
    assert not check.ok and not state.detected
    assert check.name == "the T-shirt" and check.detail.startswith("not found (")
    assert check.detail.endswith("lay it flat on the table")


def test_a_towel_cut_by_the_image_edge_is_named(towel_view):
    from foldbot.ros.check_node import check_cloth
    from foldbot.sim.layout import DEFAULT_LAYOUT

    obs, _corners = towel_view
    # The frame's left 300 px cropped off, as a camera with a narrower view sees it (its
    # principal point moved with the crop): the towel (about u 165–440) runs off its edge.
    K = obs.intrinsics.K.copy()
    K[0, 2] -= 300
    narrow = dataclasses.replace(obs.intrinsics, width=obs.intrinsics.width - 300, K=K)
    cut = dataclasses.replace(
        obs,
        rgb=np.ascontiguousarray(obs.rgb[:, 300:]),
        depth=np.ascontiguousarray(obs.depth[:, 300:]),
        intrinsics=narrow,
    )
    check, state = check_cloth(cut, DEFAULT_LAYOUT, "towel")
    assert not check.ok
    assert check.detail == "found, but cut by the image's edge: its corners cannot all be seen"
    assert state.mask[:, 0].any()


def test_a_tray_the_layout_names_is_not_taken_for_the_towel():
    # layouts/cloth_tray.toml's tray beside a folded towel (eval-perception's scene 19): ros-check
    # knows it as the cell's fixture, as the fold's perception does, and finds the towel.
    from pathlib import Path

    from foldbot.ros.check_node import check_cloth
    from foldbot.sim.layout import load_layout
    from foldbot.sim.perception_scenes import render_scene, sample_scene

    layout = load_layout(Path(__file__).resolve().parents[2] / "layouts" / "cloth_tray.toml")
    scene = sample_scene(np.random.default_rng([0, 19]), 19, 0.3, 0.0, layout=layout)
    r = render_scene(scene, 320, 240, 10, 19, layout=layout)
    check, state = check_cloth(r.obs, layout, "towel")
    assert check.ok, check.detail
    assert state.detected and (state.mask & r.cloth_mask).sum() > 0.97 * r.cloth_mask.sum()
    assert (state.mask & ~r.cloth_mask).sum() < 0.03 * r.cloth_mask.sum()
