"""The garment loop's grasp correction and stage prediction on synthetic states; the loop itself
runs end to end in tests/test_pipeline_garments.py."""

from __future__ import annotations

import numpy as np
import pytest

from foldbot.errors import PerceptionError
from foldbot.garment_loop import (
    RETRY_INSET,
    already_carried,
    corrected_grasp,
    garment_keypoints,
    laid_layer,
    outline_distance,
    snap_to_cloth,
)
from foldbot.grasp_points import GRASP_INSET
from foldbot.loop import LoopConfig
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.types import CameraIntrinsics, Observation

Z = 0.752


def square_state(side: float = 0.2, center=(0.45, 0.0)) -> ClothState:
    c = np.asarray(center)
    corners = c + side / 2 * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
    # A dense outline, as vision gives (contour pixels lifted to the table plane).
    pts = np.concatenate(
        [np.linspace(corners[i], corners[(i + 1) % 4], 20, endpoint=False) for i in range(4)]
    )
    return ClothState(detected=True, outline_world=np.c_[pts, np.full(len(pts), Z)])


def test_outline_distance_sign():
    s = square_state()
    assert outline_distance(s, np.array([0.45, 0.0])) == pytest.approx(0.1, abs=1e-6)
    assert outline_distance(s, np.array([0.60, 0.0])) == pytest.approx(-0.05, abs=1e-6)
    assert outline_distance(ClothState.not_detected(), np.zeros(2)) == float("-inf")


def test_snap_keeps_points_on_cloth_and_moves_near_misses_inside():
    s = square_state()
    on = np.array([0.50, 0.05, Z + 0.01])
    assert np.array_equal(snap_to_cloth(s, on, radius=0.06), on)
    near = np.array([0.58, 0.02, 0.77])  # 3 cm outside the +x side
    snapped = snap_to_cloth(s, near, radius=0.06, inset=0.01)
    assert snapped is not None
    assert outline_distance(s, snapped) == pytest.approx(0.01, abs=0.003)
    assert snapped[2] == 0.77  # the planned height is kept
    assert snap_to_cloth(s, np.array([0.75, 0.0, Z]), radius=0.06) is None


def test_an_unrecognised_garment_is_a_perception_failure():
    # The generic outline estimator's towel corners are no pants keypoints: the loop must say
    # perception failed (the benchmark's cause), naming what it missed, not blame the config.
    s = square_state()
    s.keypoints["near_left"] = (np.array([0.35, 0.1, Z]), 0.9)
    with pytest.raises(
        PerceptionError, match=r"not recognised for recipe 'leg_over_leg'.*left_leg_inner"
    ):
        garment_keypoints(s, "leg_over_leg")
    with pytest.raises(PerceptionError, match="seen: none"):
        garment_keypoints(square_state(), "retail")
    names = ("neck", "left_shoulder", "right_shoulder", "left_sleeve", "right_sleeve")
    names += ("left_armpit", "right_armpit", "left_hem", "right_hem")
    for n in names:
        s.keypoints[n] = (np.array([0.45, 0.0, Z]), 0.8)
    assert set(garment_keypoints(s, "retail")) >= set(names)


def overhead_view(surface_z: float, camera_z: float = 1.5) -> Observation:
    """A camera 1.5 m up over (0.45, 0) looking straight down at a flat surface at `surface_z`."""
    K = np.array([[300.0, 0.0, 160.0], [0.0, 300.0, 120.0], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # camera x = world x, y = −y, z (forward) = −z
    T[:3, 3] = [0.45, 0.0, camera_z]
    depth = np.full((240, 320), camera_z - surface_z, np.float32)
    return Observation(np.zeros((240, 320, 3), np.uint8), depth, CameraIntrinsics(320, 240, K), T)


def test_a_retried_tip_grasp_closes_farther_inside_the_cloth():
    s, obs = square_state(), overhead_view(Z)
    line = (0.45, 0.0, 0.0, -1.0)  # moving side: x > 0.45, whose tip is the +x side at 0.55
    planned = FoldAction(np.array([0.55, 0.0, Z]), np.array([0.35, 0.0, Z]), line, "legs")
    first = corrected_grasp(LoopConfig(recipe="leg_over_leg"), s, obs, planned, planned, True)
    again = corrected_grasp(LoopConfig(recipe="leg_over_leg"), s, obs, planned, first, True, 1)
    assert first.grasp[0] == pytest.approx(0.55 - GRASP_INSET, abs=1e-6)
    assert again.grasp[0] == pytest.approx(0.55 - GRASP_INSET - RETRY_INSET, abs=1e-6)
    # Placed at its mirror across the line, at the height the camera sees the cloth.
    assert again.place[0] == pytest.approx(0.45 - (again.grasp[0] - 0.45), abs=1e-6)
    assert again.grasp[2] == pytest.approx(Z, abs=1e-3)


def test_a_retried_grasp_on_the_cloth_moves_toward_its_centre():
    """A T-shirt's hem corner whose grasp missed: the retry closes RETRY_INSET per retry toward
    the perceived cloth's centre (0.45, 0), not on the point that just missed."""
    s, obs = square_state(), overhead_view(Z)
    line = (0.40, 0.0, 0.0, -1.0)
    planned = FoldAction(np.array([0.53, 0.08, Z]), np.array([0.27, 0.08, Z]), line, "left_hem")
    cfg = LoopConfig(recipe="retail")
    first = corrected_grasp(cfg, s, obs, planned, planned)
    assert first.grasp[:2] == pytest.approx([0.53, 0.08])
    to_centre = np.array([0.45 - 0.53, 0.0 - 0.08]) / np.hypot(0.08, 0.08)
    for retry in (1, 2):
        again = corrected_grasp(cfg, s, obs, planned, first, retry=retry)
        expected = np.array([0.53, 0.08]) + to_centre * retry * RETRY_INSET
        assert again.grasp[:2] == pytest.approx(expected, abs=1e-6)
        assert again.place[:2] == pytest.approx(planned.place[:2])
        assert again.grasp[2] == pytest.approx(Z, abs=1e-3)


def test_a_part_dragged_away_is_carried_from_what_is_left_past_the_line():
    """A T-shirt's hem corner after its cuff's carry: nothing seen within the regrasp radius of
    the planned grasp, so the grasp goes where the cloth left past the line reaches farthest."""
    s, obs = square_state(), overhead_view(Z)  # the cloth spans x 0.35–0.55, y −0.1–0.1
    line = (0.50, 0.0, 0.0, -1.0)  # moving side: x > 0.50, whose tip is the +x side at 0.55
    planned = FoldAction(np.array([0.70, 0.0, Z]), np.array([0.30, 0.0, Z]), line, "left_hem")
    cfg = LoopConfig(recipe="retail")
    assert snap_to_cloth(s, planned.grasp, cfg.regrasp_radius) is None
    action = corrected_grasp(cfg, s, obs, planned, planned)
    assert action.grasp[:2] == pytest.approx([0.55 - GRASP_INSET, 0.0], abs=1e-6)
    assert action.place[0] == pytest.approx(0.50 - (action.grasp[0] - 0.50), abs=1e-6)
    assert action.label == "left_hem" and action.grasp[2] == pytest.approx(Z, abs=1e-3)
    # A planned grasp that still has cloth near it is snapped onto it, as before.
    near = FoldAction(np.array([0.53, 0.05, Z]), np.array([0.47, 0.05, Z]), line, "left_hem")
    assert corrected_grasp(cfg, s, obs, near, near).grasp[:2] == pytest.approx([0.53, 0.05])


def test_a_stacks_top_layer_is_grasped_first_where_it_reaches_farthest():
    """Pants' legs: the layer the previous stage laid ends at x = 0.52, short of the stack's tip
    at 0.55; given its points, the first grasp takes that layer's end, at the surface seen there."""
    s, obs = square_state(), overhead_view(Z)
    line = (0.45, 0.0, 0.0, -1.0)
    planned = FoldAction(np.array([0.55, 0.0, Z]), np.array([0.35, 0.0, Z]), line, "legs")
    xs, ys = np.meshgrid(np.linspace(0.36, 0.52, 17), np.linspace(-0.05, 0.05, 11))
    laid = np.c_[xs.ravel(), ys.ravel(), np.full(xs.size, Z)]
    cfg = LoopConfig(recipe="leg_over_leg")
    top = corrected_grasp(cfg, s, obs, planned, planned, True, top=laid)
    assert top.grasp[:2] == pytest.approx([0.52 - GRASP_INSET, 0.0], abs=1e-6)
    assert top.place[0] == pytest.approx(0.45 - (top.grasp[0] - 0.45), abs=1e-6)
    assert top.grasp[2] == pytest.approx(Z, abs=1e-3) and top.layers == 1
    # No laid layer past the line: the stack is carried from its tip, as without one.
    stack = corrected_grasp(cfg, s, obs, planned, planned, True, top=laid[laid[:, 0] < 0.46])
    assert stack.grasp[0] == pytest.approx(0.55 - GRASP_INSET, abs=1e-6)


def test_no_laid_layer_is_looked_for_when_top_layer_first_is_off():
    s = square_state()
    s = ClothState(
        detected=True, outline_world=s.outline_world, table_plane=np.r_[0, 0, 1.0, -0.75]
    )
    before, after = overhead_view(Z), overhead_view(Z + 0.005)
    on = laid_layer(LoopConfig(recipe="leg_over_leg"), s, before, s, after)
    assert on is not None and len(on) > 1000  # the whole view rose by a layer
    off = LoopConfig(recipe="leg_over_leg", top_layer_first=False)
    assert laid_layer(off, s, before, s, after) is None


def test_a_part_with_no_cloth_near_it_or_past_its_line_is_already_carried():
    """What decides a skip before the first grasp, and the end of the retries after a miss
    (T-shirt seed 23's hem corner, whose retry closed again on bare table where the first had)."""
    s = square_state()  # the cloth spans x 0.35–0.55, y −0.1–0.1
    cfg = LoopConfig(recipe="retail")
    past = (0.50, 0.0, 0.0, -1.0)  # moving side x > 0.50: the cloth reaches 5 cm past it
    clear = (0.60, 0.0, 0.0, -1.0)  # moving side x > 0.60: no cloth there
    far = np.array([0.70, 0.0, Z])  # no cloth within the regrasp radius
    gone = FoldAction(far, np.array([0.50, 0.0, Z]), clear, "right_hem")
    assert already_carried(cfg, s, gone)
    assert already_carried(cfg, s, gone, from_tip=True)
    # Cloth left past the line (and the place not covered): carried from its tip, not skipped.
    left = FoldAction(far, np.array([0.30, 0.0, Z]), past, "right_hem")
    assert not already_carried(cfg, s, left)
    # Cloth near the planned grasp: grasped there, whatever lies past the line.
    near = FoldAction(np.array([0.53, 0.05, Z]), np.array([0.67, 0.05, Z]), clear, "right_hem")
    assert not already_carried(cfg, s, near)
    assert already_carried(cfg, s, near, from_tip=True)
