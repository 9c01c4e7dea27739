"""Depth layers (foldbot.perception.layers): heights over the table, and the gap a laid layer left
in the region it should cover, on synthetic top-down frames."""

from __future__ import annotations

import numpy as np
import pytest
from layer_scene import TABLE_PLANE, box, observe

from foldbot.errors import PerceptionError
from foldbot.perception.layers import (
    deepest_gap,
    height_map,
    laid_corner,
    laid_layer_mask,
    layer_cover,
    mask_points,
)
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState

LAYER = 0.005
FLAT = box(-0.1, 0.1, -0.1, 0.1, LAYER)  # a 20 cm towel, one layer
# After a half fold of the x > 0 half onto x < 0, the region to cover is the x < 0 half.
COVER = np.array([[-0.1, -0.1, 0.0], [0.0, -0.1, 0.0], [0.0, 0.1, 0.0], [-0.1, 0.1, 0.0]])


def folded(*gaps):
    """The folded towel: two layers over x < 0, except one layer where a gap (x0, x1, y0, y1) is."""
    return observe(
        box(-0.1, 0.0, -0.1, 0.1, 2 * LAYER),
        *(box(*g, LAYER) for g in gaps),
    )


def find_cover_gap(before, before_plane, after, after_plane, polygon):
    """The deepest gap, from the region's layer cover."""
    return deepest_gap(layer_cover(before, before_plane, after, after_plane, polygon), after)


def test_height_map_is_the_surface_over_the_table() -> None:
    h = height_map(observe(FLAT), TABLE_PLANE)
    assert h.shape == (200, 240)
    assert np.nanmax(h) == pytest.approx(LAYER, abs=1e-6)
    assert np.nanmin(h) == pytest.approx(0.0, abs=1e-6)


def test_height_map_refuses_a_plane_that_is_not_the_table() -> None:
    with pytest.raises(PerceptionError, match="upward unit normal"):
        height_map(observe(FLAT), np.array([1.0, 0.0, 0.0, 0.0]))


def test_a_corner_the_layer_left_uncovered_is_found() -> None:
    gap = find_cover_gap(
        observe(FLAT), TABLE_PLANE, folded((-0.1, -0.07, 0.04, 0.1)), TABLE_PLANE, COVER
    )
    assert gap is not None
    # The deepest uncovered point is the region's corner (less the ignored border).
    assert np.linalg.norm(gap.deepest[:2] - [-0.1, 0.1]) < 0.012
    # The laid layer's nearest edge is the gap's side 3 cm in, at the layer's height.
    assert gap.edge[0] == pytest.approx(-0.07, abs=0.006)
    assert gap.edge[2] == pytest.approx(2 * LAYER, abs=1e-4)
    assert 0.015 < gap.depth < 0.03


def test_a_fully_covered_region_has_no_gap() -> None:
    assert find_cover_gap(observe(FLAT), TABLE_PLANE, folded(), TABLE_PLANE, COVER) is None


def test_no_layer_laid_means_nothing_to_judge() -> None:
    assert find_cover_gap(observe(FLAT), TABLE_PLANE, observe(FLAT), TABLE_PLANE, COVER) is None


def test_surfaces_far_above_the_table_are_not_cloth() -> None:
    # The parked arm hides part of the region in both frames: it is neither covered nor a gap.
    arm = box(-0.1, -0.06, 0.05, 0.1, 0.3)
    gap = find_cover_gap(
        observe(FLAT, arm),
        TABLE_PLANE,
        observe(box(-0.1, 0.0, -0.1, 0.1, 2 * LAYER), arm),
        TABLE_PLANE,
        COVER,
    )
    assert gap is None


def test_frames_of_different_sizes_are_refused() -> None:
    small = observe(FLAT)
    small = type(small)(
        rgb=small.rgb[:100],
        depth=small.depth[:100],
        intrinsics=small.intrinsics,
        T_world_camera=small.T_world_camera,
    )
    with pytest.raises(PerceptionError, match="frames differ in size"):
        find_cover_gap(small, TABLE_PLANE, folded(), TABLE_PLANE, COVER)


def test_layer_cover_splits_the_region_into_covered_and_exposed() -> None:
    cover = layer_cover(
        observe(FLAT), TABLE_PLANE, folded((-0.1, -0.07, 0.04, 0.1)), TABLE_PLANE, COVER
    )
    assert cover is not None
    assert cover.layer_rise == pytest.approx(LAYER, abs=1e-4)
    assert not (cover.covered & cover.exposed).any()
    assert cover.covered.sum() > 10 * cover.exposed.sum() > 0


def test_the_stage_overlay_tints_what_the_laid_layer_left_uncovered() -> None:
    after = folded((-0.1, -0.07, 0.04, 0.1))
    cover = layer_cover(observe(FLAT), TABLE_PLANE, after, TABLE_PLANE, COVER)
    assert cover is not None
    state = ClothState(detected=True, table_plane=TABLE_PLANE.copy())
    plain = draw_overlay(after, state)
    tinted = draw_overlay(after, state, uncovered=cover.exposed)
    changed = (tinted != plain).any(axis=2)
    assert changed[cover.exposed].all()
    assert not changed[~cover.exposed & (np.arange(200)[:, None] > 30)].any()  # below the label


# The half fold's far-left corner, at (0.1, 0.1), is laid on its mirror (-0.1, 0.1).
PLACE = np.array([-0.1, 0.1, LAYER])


def laid(after):
    return laid_layer_mask(observe(FLAT), TABLE_PLANE, after, TABLE_PLANE, LAYER / 2)


def test_the_laid_layer_is_the_surface_that_rose_over_the_stage() -> None:
    after = folded()
    mask = laid(after)
    height = height_map(after, TABLE_PLANE)
    assert mask[height > 1.5 * LAYER].mean() > 0.95  # the folded half, less its blurred border
    assert not mask[height < 1.5 * LAYER].any()  # the staying layer, and the half that left


def test_a_layer_laid_past_the_cloth_onto_bare_table_is_laid_too() -> None:
    after = observe(box(-0.1, 0.0, -0.1, 0.1, 2 * LAYER), box(-0.13, -0.1, -0.1, 0.1, LAYER))
    mask = laid(after)
    x = (np.arange(240) - 120) / 300.0  # the synthetic camera's x at the table, per column
    assert mask[:, (x > -0.125) & (x < -0.105)].any(axis=0).all()


def test_the_laid_layer_needs_a_positive_rise() -> None:
    with pytest.raises(PerceptionError, match=r"min_rise must be > 0 m, got 0\.0"):
        laid_layer_mask(observe(FLAT), TABLE_PLANE, folded(), TABLE_PLANE, 0.0)


def test_a_laid_corner_that_sprang_back_is_seen_where_the_layer_ends() -> None:
    # The laid layer ends 3 cm short of the near edge: the layer beneath still shows there.
    after = observe(box(-0.1, 0.0, -0.1, 0.1, LAYER), box(-0.07, 0.0, -0.1, 0.1, 2 * LAYER))
    seen = laid_corner(laid(after), after, PLACE)
    assert seen is not None
    assert np.linalg.norm(seen.corner[:2] - [-0.07, 0.1]) < 0.007  # two pixels
    assert seen.corner[2] == pytest.approx(2 * LAYER, abs=1e-4)
    # Picked just inside, on the laid layer's top.
    assert seen.grasp[0] > seen.corner[0] and seen.grasp[1] < seen.corner[1]
    assert seen.grasp[2] == pytest.approx(2 * LAYER, abs=1e-4)


def test_no_laid_layer_has_no_corner() -> None:
    assert laid_corner(laid(observe(FLAT)), observe(FLAT), PLACE) is None


def test_mask_points_are_the_laid_layers_top_surface() -> None:
    after = folded()
    pts = mask_points(laid(after), after)
    assert len(pts) > 100
    assert pts[:, 0].max() < 0.002 and pts[:, 0].min() > -0.102  # over the x < 0 half
    assert pts[:, 2] == pytest.approx(np.full(len(pts), 2 * LAYER), abs=1e-4)


def test_mask_points_refuse_a_mask_of_another_size() -> None:
    with pytest.raises(PerceptionError, match=r"mask is \(3, 3\), the depth image \(200, 240\)"):
        mask_points(np.zeros((3, 3), bool), folded())
