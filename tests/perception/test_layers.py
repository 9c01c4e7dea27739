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
    layer_cover,
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
