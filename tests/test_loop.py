"""The closed loop's grasp-point helpers (foldbot.loop): where to grasp a corner that earlier actions
moved, and how low to grasp a folded stack. Pure geometry on hand-made perception states."""

import numpy as np
import pytest

from foldbot.loop import (
    MAX_CLOTH_CREASE_ROOM,
    MIN_ARM_SEPARATION,
    MIN_LEFT,
    LoopConfig,
    arms_apart,
    assign_arms,
    corner_to_grasp,
    inset_grasp,
    moving_side_tip,
    nearest_arm,
    outline_corners,
    place_is_corner,
    regrasp_point,
    shifted_grasp,
    stack_grasp_point,
    stage_crease_room,
    tip_action,
)
from foldbot.metrics import FoldLine
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction

TABLE_Z = 0.75
# Fold line x = 0.45 pointing −y: its left (moving) side is x > 0.45, the far side.
LINE = (0.45, 0.15, 0.0, -0.3)


def state(outline_xy, keypoints, table_z=TABLE_Z):
    outline = np.column_stack([np.asarray(outline_xy, float), np.full(len(outline_xy), 0.76)])
    return ClothState(
        detected=True,
        keypoints={k: (np.asarray(v, float), 0.5) for k, v in keypoints.items()},
        mask=np.zeros((4, 4), bool),
        outline_world=outline,
        table_plane=np.array([0.0, 0.0, 1.0, -table_z]),
    )


def dragged_towel():
    """After the first carry of a half fold: far_left is folded onto near_left; the far_right
    corner was dragged to (0.56, −0.06), the tip of a tent of cloth still on the far side."""
    outline = [
        (0.30, 0.15),  # folded far_left over near_left
        (0.30, -0.15),  # near_right
        (0.45, -0.15),
        (0.56, -0.06),  # the dragged far_right: the tent's tip
        (0.45, 0.05),
    ]
    keypoints = {
        "near_left": (0.30, 0.15, 0.757),
        "near_right": (0.30, -0.15, 0.755),
        # The corner detector fits a quad to the pentagon: its far_right is 3.5 cm off the tip.
        "far_right": (0.535, -0.085, 0.757),
        "far_left": (0.45, 0.05, 0.757),
    }
    return state(outline, keypoints)


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


def test_a_corner_placed_off_is_re_grasped_where_it_lies_whatever_its_label():
    """After a fold the detector labels the new outline's corners afresh: the corner to re-place is
    the one seen nearest where it was found, even when a corner with the planned label is nearer
    than the label radius (grasping that one dragged the towel apart in a benchmark run)."""
    outline = [(0.30, 0.15), (0.30, -0.15), (0.45, -0.15), (0.45, 0.15)]
    relabelled = {
        "near_left": (0.30, 0.15, 0.767),
        "near_right": (0.30, -0.15, 0.757),
        "far_left": (0.45, -0.15, 0.757),
        "far_right": (0.45, 0.03, 0.757),  # 22 cm from the misplaced corner: within label reach
    }
    towel = state(outline, relabelled)
    cfg = LoopConfig()
    action = FoldAction(
        grasp=np.array([0.31, 0.14, 0.767]),  # where the misplaced corner was seen
        place=np.array([0.30, 0.16, 0.76]),
        fold_line=LINE,
        label="far_right",
    )
    again = corner_to_grasp(cfg, towel, "far_right", action, replacing=True)
    assert again == pytest.approx([0.30, 0.15, 0.767])  # the corner found there (near_left)
    carried = corner_to_grasp(cfg, towel, "far_right", action, replacing=False)
    assert carried == pytest.approx([0.45, 0.03, 0.757])  # a corner to carry: by its label


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


def test_the_crease_room_is_the_laid_layers_rise_seen_in_depth():
    cfg = LoopConfig(recipe="thirds", layer_thickness=0.011)
    assert stage_crease_room(cfg, 0.013) == pytest.approx(0.013)
    # A bunch seen rising 4 cm is no single layer: capped.
    assert stage_crease_room(cfg, 0.04) == pytest.approx(MAX_CLOTH_CREASE_ROOM)
    # Depth told nothing (or the open loop): the cloth's layer thickness, capped as well (a 1 m
    # towel meshed with 8 vertices is 5.7 cm thick in Bullet).
    assert stage_crease_room(cfg, None) == pytest.approx(0.011)
    thick = LoopConfig(recipe="thirds", layer_thickness=0.057)
    assert stage_crease_room(thick, None) == pytest.approx(MAX_CLOTH_CREASE_ROOM)
    # Set in the configuration, it wins.
    fixed = LoopConfig(recipe="thirds", layer_thickness=0.011, crease_room=0.0)
    assert stage_crease_room(fixed, 0.013) == 0.0


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


def corner_action(label, grasp_xy, place_xy):
    return FoldAction(
        grasp=np.array([*grasp_xy, 0.757]),
        place=np.array([*place_xy, 0.761]),
        fold_line=LINE,
        label=label,
    )


def test_each_corner_goes_to_the_arm_on_its_side():
    assert nearest_arm(np.array([0.6, 0.12, 0.76]), BASES_Y) == 0
    assert nearest_arm(np.array([0.6, -0.02, 0.76]), BASES_Y) == 1
    half = (
        corner_action("far_right", (0.6, -0.15), (0.3, -0.15)),
        corner_action("far_left", (0.6, 0.15), (0.3, 0.15)),
    )
    assert assign_arms(lambda p: nearest_arm(p, BASES_Y), half) == [1, 0]


def test_two_corners_on_one_side_still_get_one_arm_each_left_to_left():
    # A towel lying off-centre: both grasps nearer the left arm's base.
    pair = (
        corner_action("far_right", (0.6, 0.02), (0.3, 0.02)),
        corner_action("far_left", (0.6, 0.25), (0.3, 0.25)),
    )
    assert assign_arms(lambda p: nearest_arm(p, BASES_Y), pair) == [1, 0]


def test_corners_too_close_for_two_grippers_are_carried_one_after_the_other():
    apart = (
        corner_action("far_left", (0.6, 0.15), (0.3, 0.15)),
        corner_action("far_right", (0.6, -0.15), (0.3, -0.15)),
    )
    assert arms_apart(apart)
    gap = MIN_ARM_SEPARATION * 0.9
    close_grasps = (
        corner_action("a", (0.6, gap / 2), (0.3, 0.15)),
        corner_action("b", (0.6, -gap / 2), (0.3, -0.15)),
    )
    close_places = (
        corner_action("a", (0.6, 0.15), (0.3, gap / 2)),
        corner_action("b", (0.6, -0.15), (0.3, -gap / 2)),
    )
    assert not arms_apart(close_grasps)
    assert not arms_apart(close_places)
