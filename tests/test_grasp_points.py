"""Grasp points on the cloth seen now (foldbot.grasp_points): where to grasp a corner that earlier
actions moved, how low to grasp a folded stack, what is left past a fold line, and which
placements make a corner. Pure geometry on hand-made perception states."""

import numpy as np
import pytest
from cloth_states import LINE, TABLE_Z, dragged_towel, state
from layer_scene import TABLE_PLANE, box, observe

from foldbot.grasp_points import (
    ARM_HEIGHT,
    MIN_LEFT,
    inset_grasp,
    moving_side_tip,
    outline_corners,
    place_is_corner,
    regrasp_point,
    shifted_grasp,
    stack_grasp_point,
    surface_height,
    tip_action,
    top_layer_action,
)
from foldbot.metrics import FoldLine
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction


def test_moving_side_tip_is_the_farthest_point_from_the_fold_line():
    tip = moving_side_tip(dragged_towel(), LINE, near=np.array([0.6, -0.15, 0.0]), band=0.01)
    assert tip[:2] == pytest.approx([0.56, -0.06])


def test_no_tip_when_nothing_is_left_on_the_moving_side():
    folded = state([(0.30, 0.15), (0.30, -0.15), (0.45, -0.15), (0.45, 0.15)], {})
    assert moving_side_tip(folded, LINE, near=np.array([0.6, 0.0, 0.0]), band=0.01) is None


def test_dragged_corner_is_grasped_at_the_tip_at_its_planned_height():
    planned = np.array([0.62, -0.15, 0.755])  # where far_right was before the first carry
    point = regrasp_point(dragged_towel(), "far_right", planned, 0.06, 0.25, line=LINE)
    assert point == pytest.approx([0.56, -0.06, 0.755])
    # Without the fold line: the labelled keypoint, as before.
    point = regrasp_point(dragged_towel(), "far_right", planned, 0.06, 0.25)
    assert point == pytest.approx([0.535, -0.085, 0.757])


def test_a_well_fitted_corner_keeps_its_refined_keypoint():
    """A flat towel: the moving side's far edge is level with the line, and the labelled corner
    lies on it, so the refined keypoint stays (not an outline pixel)."""
    outline = [(0.30, 0.15), (0.30, -0.15), (0.60, -0.15), (0.60, 0.15)]
    keypoints = {
        "near_left": (0.30, 0.15, 0.755),
        "near_right": (0.30, -0.15, 0.755),
        "far_right": (0.602, -0.152, 0.755),
        "far_left": (0.602, 0.152, 0.755),
    }
    planned = np.array([0.60, 0.15, 0.755])
    point = regrasp_point(state(outline, keypoints), "far_left", planned, 0.06, 0.25, line=LINE)
    assert point == pytest.approx([0.602, 0.152, 0.755])


def test_a_corner_to_re_place_on_the_staying_side_ignores_the_tip():
    """Re-grasping a corner placed off its place point (it lies on the staying side) must not
    jump to the other corner's tent."""
    planned = np.array([0.31, 0.14, 0.767])
    point = regrasp_point(dragged_towel(), "near_left", planned, 0.06, 0.25, line=LINE)
    assert point == pytest.approx([0.30, 0.15, 0.757])


def test_stack_grasp_point_goes_down_to_the_table():
    s = dragged_towel()
    top = np.array([0.47, 0.2, 0.772])  # top of a two-layer stack
    assert stack_grasp_point(s, top, 0.004) == pytest.approx([0.47, 0.2, TABLE_Z + 0.004])
    # Never raised, and left alone without a usable table plane.
    low = np.array([0.47, 0.2, 0.751])
    assert stack_grasp_point(s, low, 0.004) == pytest.approx(low)
    flat = ClothState(detected=True, table_plane=np.zeros(4))
    assert stack_grasp_point(flat, top, 0.004) == pytest.approx(top)


def test_a_placement_is_checked_only_where_it_should_make_a_corner():
    corners = np.array(
        [[0.3, 0.15, 0.76], [0.3, -0.15, 0.76], [0.45, -0.15, 0.76], [0.45, 0.15, 0.76]]
    )
    assert place_is_corner(np.array([0.31, 0.16, 0.76]), corners, 0.03)
    # A corner laid inside the outline (thirds' first stage) is no corner keypoint: not checked.
    assert not place_is_corner(np.array([0.37, 0.0, 0.76]), corners, 0.03)
    # Without a predicted outline every placement is checked.
    assert place_is_corner(np.array([0.37, 0.0, 0.76]), None, 0.03)


def test_inset_grasp_moves_inside_and_keeps_the_corner_landing_on_its_place():
    s = dragged_towel()
    corner = np.array([0.45, 0.05, 0.757])
    line = FoldLine(*LINE)
    place = line.reflect_xy(corner)
    action = FoldAction(grasp=corner, place=place, fold_line=LINE, label="far_left")
    moved = inset_grasp(s, action, corner, 0.012)
    assert np.linalg.norm(moved.grasp[:2] - corner[:2]) == pytest.approx(0.012)
    centre = np.asarray(s.outline_world)[:, :2].mean(axis=0)
    assert np.linalg.norm(moved.grasp[:2] - centre) < np.linalg.norm(corner[:2] - centre)
    # The grasp still maps onto the place by the fold: the corner lands where it was planned.
    assert line.reflect_xy(moved.grasp)[:2] == pytest.approx(moved.place[:2])
    assert moved.grasp[2] == corner[2] and moved.place[2] == place[2]
    assert inset_grasp(s, action, corner, 0.0) is action


def test_tip_action_carries_the_cloth_left_past_the_line_and_nothing_less():
    s = dragged_towel()  # the dragged far_right reaches 11 cm past the line x = 0.45
    planned = FoldAction(
        grasp=np.array([0.6, -0.15, 0.757]),
        place=np.array([0.3, -0.15, 0.761]),
        fold_line=LINE,
        label="far_right",
    )
    extra = tip_action(s, planned)
    assert extra is not None
    assert extra.grasp[:2] == pytest.approx([0.55, -0.06])  # the tip, 1 cm back toward the line
    assert extra.place[:2] == pytest.approx(FoldLine(*LINE).reflect_xy(extra.grasp)[:2])
    assert extra.place[2] == planned.place[2]
    folded = state([(0.30, 0.15), (0.30, -0.15), (0.45 + MIN_LEFT / 2, -0.15)], {})
    assert tip_action(folded, planned) is None


def test_the_top_layer_is_carried_from_where_it_reaches_farthest_past_the_line():
    """Pants' legs: the left leg laid on the right ends short of its tip; the laid layer's
    farthest point past the line x = 0.45 (moving side x > 0.45) is grasped, 1 cm back toward
    the line, at its top, and placed at its mirror as one layer."""
    planned = FoldAction(
        grasp=np.array([0.6, 0.0, 0.757]),
        place=np.array([0.3, 0.0, 0.761]),
        fold_line=LINE,
        label="legs",
        layers=2,
    )
    xs, ys = np.meshgrid(np.linspace(0.40, 0.56, 17), np.linspace(-0.05, 0.05, 11))
    laid = np.c_[xs.ravel(), ys.ravel(), np.full(xs.size, 0.77)]
    lead = top_layer_action(laid, planned)
    assert lead is not None
    assert lead.grasp == pytest.approx([0.55, 0.0, 0.77])  # the nearest of the farthest, inset
    assert lead.place[:2] == pytest.approx([0.35, 0.0]) and lead.place[2] == planned.place[2]
    assert lead.layers == 1 and lead.label == "legs"
    short = laid[laid[:, 0] <= 0.45 + MIN_LEFT / 2]
    assert top_layer_action(short, planned) is None  # only the crease's bulge past the line
    assert top_layer_action(np.zeros((0, 3)), planned) is None


def test_a_shifted_grasp_still_lands_the_aimed_point_on_its_place():
    action = FoldAction(
        grasp=np.array([0.6, 0.1, 0.76]), place=np.array([0.3, 0.1, 0.77]), fold_line=LINE
    )
    moved = shifted_grasp(action, np.array([-0.01, -0.03]))
    assert moved.grasp == pytest.approx([0.59, 0.07, 0.76])
    # Mirrored across x = 0.45: along the line the shift is kept, across it reversed.
    assert moved.place == pytest.approx([0.31, 0.07, 0.77])


def test_a_corner_laid_short_of_a_corner_is_not_checked_against_it():
    """Thirds' second stage with 12 mm of crease room: the far corners land on the stack's sides,
    24 mm short of its crease corners (within the placement tolerance of them), where the corner
    detector sees no corner; a place on a corner is one to round-off."""
    corners = np.array(
        [[0.3, 0.15, 0.76], [0.3, -0.15, 0.76], [0.45, -0.15, 0.76], [0.45, 0.15, 0.76]]
    )
    assert not place_is_corner(np.array([0.324, 0.15, 0.77]), corners)
    assert place_is_corner(np.array([0.3005, 0.1498, 0.77]), corners)
    assert place_is_corner(np.array([0.324, 0.15, 0.77]), corners, tol=0.03)


def test_outline_corners_are_the_detectors_four_not_a_bump_on_a_side():
    # Thirds' first stage: the staying two thirds, and the mirrored far corner 4 mm past the left
    # side (a bump the four-corner detector does not report).
    outline = np.array(
        [[0.3, 0.15], [0.3, -0.15], [0.5, -0.15], [0.5, 0.15], [0.4, 0.154], [0.39, 0.15]]
    )
    corners = outline_corners(outline)
    assert len(corners) == 4
    assert not place_is_corner(np.array([0.4, 0.154]), corners, 0.03)
    assert place_is_corner(np.array([0.31, 0.14]), corners, 0.03)


# --- two arms ------------------------------------------------------------------------------------

BASES_Y = (0.3, -0.3)  # CellLayout.arm_layouts(2): arm 0 on the left (+y), arm 1 on the right


def test_the_surface_under_a_grasp_is_the_cloth_not_the_arm_hiding_it():
    """A gripper parked over the grasp point (pants seed 8's waist corner under the home pose)
    is seen 25 cm up; given the table plane, the height is the cloth's beside it."""
    cloth = box(-0.2, 0.2, -0.2, 0.2, 0.005)
    point = np.array([0.05, 0.02, 0.0])
    plain = observe(cloth)
    assert surface_height(plain, point) == pytest.approx(0.005, abs=1e-6)
    assert surface_height(plain, point, table_plane=TABLE_PLANE) == surface_height(plain, point)
    hidden = observe(cloth, box(0.04, 0.06, 0.01, 0.03, 0.25))
    assert surface_height(hidden, point) == pytest.approx(0.25, abs=1e-6)
    assert surface_height(hidden, point, table_plane=TABLE_PLANE) == pytest.approx(0.005, abs=1e-6)
    # A cloth stack up to ARM_HEIGHT is still cloth.
    stack = observe(cloth, box(0.04, 0.06, 0.01, 0.03, ARM_HEIGHT - 0.005))
    assert surface_height(stack, point, table_plane=TABLE_PLANE) == pytest.approx(
        ARM_HEIGHT - 0.005, abs=1e-6
    )
    # The arm hiding everything within the search: no height rather than the arm's.
    covered = observe(cloth, box(-0.1, 0.2, -0.1, 0.15, 0.25))
    assert surface_height(covered, point, table_plane=TABLE_PLANE) is None
