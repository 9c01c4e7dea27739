"""Tests for foldbot.metrics against hand-computed cases from notes/metrics.md."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.metrics import (
    FoldLine,
    coverage,
    flat_area,
    flatten_success,
    fold_error_limit_mm,
    fold_error_mm,
    fold_goal,
    fold_pairs,
    perfect_fold_error_mm,
    perfect_normalized,
    physical_layers,
    score_episode,
    self_crossing_pairs,
    self_crossings,
    softgym_performance,
    success,
)

HALF = [0.0, 0.0, 0.0, 1.0]  # line x = 0 pointing +y: moving side is x < 0
SECOND = [0.0, 0.0, 1.0, 0.0]  # line y = 0 pointing +x: moving side is y > 0


def grid(n: int = 11, size: float = 0.3, z: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Flat n×n vertex grid of side `size` centred at the origin, two triangles per cell."""
    xs = np.linspace(-size / 2, size / 2, n)
    gx, gy = np.meshgrid(xs, xs)
    verts = np.stack([gx.ravel(), gy.ravel(), np.full(n * n, z)], axis=1)
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j
            faces += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    return verts, np.asarray(faces, dtype=np.int64)


# --- FoldLine ---------------------------------------------------------------------------------


def test_fold_line_as_list_and_coerce() -> None:
    line = FoldLine(1, 2, 3, 4)
    assert line.as_list() == [1.0, 2.0, 3.0, 4.0]
    assert FoldLine.coerce([1, 2, 3, 4]) == line
    assert FoldLine.coerce(np.array([1.0, 2.0, 3.0, 4.0])) == line


@pytest.mark.parametrize(
    ("args", "match"),
    [((0, 0, 0, 0), "non-zero"), ((0, math.nan, 1, 0), "FoldLine.y"), ((0, 0, math.inf, 1), "dx")],
)
def test_fold_line_rejects_bad_values(args: tuple[float, ...], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        FoldLine(*args)


def test_fold_line_coerce_rejects_wrong_length() -> None:
    with pytest.raises(ConfigError, match="4 numbers"):
        FoldLine.coerce([0.0, 0.0, 1.0])


def test_moving_side_is_left_of_direction() -> None:
    pts = np.array([[0.0, 1.0], [0.0, -1.0], [5.0, 0.0]])
    assert FoldLine(0, 0, 1, 0).moving_mask(pts).tolist() == [True, False, False]
    assert FoldLine(0, 0, -1, 0).moving_mask(pts).tolist() == [False, True, False]


# --- fold goal and fold error -----------------------------------------------------------------


def test_half_fold_goal_by_hand() -> None:
    t = 0.002
    verts = np.array([[-0.15, 0, 0.01], [-0.05, 0, 0.01], [0.05, 0, 0.01], [0.15, 0, 0.01]])
    goal, layers = fold_goal(verts, [HALF], t)
    assert layers.tolist() == [1, 1, 0, 0]
    np.testing.assert_allclose(goal[:, 0], [0.15, 0.05, 0.05, 0.15], atol=1e-12)
    # goal z = the vertex's own start height + n · thickness
    np.testing.assert_allclose(goal[:, 2], [0.01 + t, 0.01 + t, 0.01, 0.01])
    # unmoved cloth: distances sqrt(0.3² + t²), sqrt(0.1² + t²), 0, 0
    expected = 1000 * (math.sqrt(0.09 + t * t) + math.sqrt(0.01 + t * t)) / 4
    assert fold_error_mm(verts, goal) == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(100.0, abs=0.01)


def test_quarter_fold_layers_stack_3_2_over_0_1() -> None:
    verts, _ = grid()
    t = 0.003
    goal, layers = fold_goal(verts, [HALF, SECOND], t)
    x, y = verts[:, 0], verts[:, 1]
    assert set(layers.tolist()) == {0, 1, 2, 3}
    # first fold: x < 0 moves onto layer 1; second fold (y > 0 side) puts layer 1 on 2, 0 on 3
    assert np.all(layers[(x >= 0) & (y <= 0)] == 0)
    assert np.all(layers[(x < 0) & (y <= 0)] == 1)
    assert np.all(layers[(x < 0) & (y > 0)] == 2)
    assert np.all(layers[(x >= 0) & (y > 0)] == 3)
    # everything ends in the quadrant x ≥ 0, y ≤ 0
    assert goal[:, 0].min() >= -1e-12 and goal[:, 1].max() <= 1e-12
    np.testing.assert_allclose(goal[:, 2], layers * t)


def test_fold_goal_uses_previous_goal_for_side_test() -> None:
    # a vertex at x = -0.1 is folded to x = +0.1; a second fold along x = 0.05 pointing -y
    # (moving side x > 0.05) must then move it, although its start x is negative
    verts = np.array([[-0.1, 0.0, 0.0], [0.0, 0.0, 0.0]])
    goal, layers = fold_goal(verts, [HALF, [0.05, 0.0, 0.0, -1.0]], 0.001)
    assert layers.tolist() == [2, 0]
    assert goal[0, 0] == pytest.approx(0.0)


def test_fold_error_zero_for_perfect_fold_and_shape_check() -> None:
    verts, _ = grid()
    goal, _ = fold_goal(verts, [HALF], 0.002)
    assert fold_error_mm(goal, goal) == 0.0
    with pytest.raises(ConfigError, match="shape"):
        fold_error_mm(goal[:-1], goal)


# --- SoftGym performance ----------------------------------------------------------------------


def test_pairs_are_exact_mirrors_on_a_grid() -> None:
    verts, _ = grid()
    a, b = fold_pairs(verts, HALF)
    assert a.size == 55  # 5 columns left of x = 0; the middle column is on the line
    np.testing.assert_allclose(verts[b, 0], -verts[a, 0])
    np.testing.assert_allclose(verts[b, 1], verts[a, 1])


def test_perfect_half_fold_normalized_one() -> None:
    verts, _ = grid()
    goal, _ = fold_goal(verts, [HALF], 0.0)
    perf = softgym_performance(verts, goal, HALF)
    assert perf.group_dist == pytest.approx(0.0, abs=1e-12)
    assert perf.fixation_dist == 0.0
    assert perf.normalized == pytest.approx(1.0, abs=1e-12)
    # with a thickness, group_dist is the layer gap: normalized = 1 − t / group_dist_start
    t = 0.002
    goal_t, _ = fold_goal(verts, [HALF], t)
    perf_t = softgym_performance(verts, goal_t, HALF)
    assert perf_t.group_dist == pytest.approx(t)
    assert perf_t.normalized == pytest.approx(1 - t / -perf_t.performance_start)


def test_unmoved_cloth_normalized_zero() -> None:
    verts, _ = grid()
    perf = softgym_performance(verts, verts, HALF)
    assert perf.normalized == 0.0
    # group_dist_start = mean over the 5 left columns of 2|x| = 2·mean(0.03..0.15) = 0.18
    assert perf.performance_start == pytest.approx(-0.18)


def test_fixation_penalty() -> None:
    verts, _ = grid()
    goal, _ = fold_goal(verts, [HALF], 0.0)
    moved = goal.copy()
    moved[:, 1] += 0.01  # the whole cloth slid 1 cm: group_dist 0, fixation 0.01
    perf = softgym_performance(verts, moved, HALF)
    assert perf.fixation_dist == pytest.approx(0.01)
    assert perf.performance == pytest.approx(-0.012)
    assert perf.normalized == pytest.approx(1 - 0.012 / 0.18)


def test_degenerate_fold_line_raises() -> None:
    verts, _ = grid()
    with pytest.raises(ConfigError, match="does not split"):
        softgym_performance(verts, verts, [1.0, 0.0, 0.0, 1.0])  # whole cloth on moving side
    # moving vertices (numerically) on their partners at the start: performance_start ≈ 0
    touching = np.array([[-1e-14, 0.0, 0.0], [1e-14, 0.0, 0.0]])
    with pytest.raises(ConfigError, match="performance_start"):
        softgym_performance(touching, touching, HALF)


def test_multi_fold_fixation_is_measured_against_the_recipe_goal() -> None:
    verts, _ = grid()
    goal, _ = fold_goal(verts, [HALF, SECOND], 0.0)
    # literal SoftGym: the second fold moved half of the staying side, heavily "penalised"
    literal = softgym_performance(verts, goal, HALF)
    assert literal.normalized < 0.5
    judged = softgym_performance(verts, goal, HALF, staying_reference=goal)
    assert judged.normalized == pytest.approx(1.0, abs=1e-12)
    unmoved = softgym_performance(verts, verts, HALF, staying_reference=goal)
    assert unmoved.normalized == 0.0
    # for a one-fold recipe the reference is the start itself: identical numbers
    one, _ = fold_goal(verts, [HALF], 0.002)
    moved = one + np.array([0.0, 0.004, 0.001])
    assert softgym_performance(verts, moved, HALF, staying_reference=one) == softgym_performance(
        verts, moved, HALF
    )


# --- coverage ---------------------------------------------------------------------------------


def test_flat_area_and_coverage_of_flat_square() -> None:
    verts, faces = grid()
    area = flat_area(verts, faces)
    assert area == pytest.approx(0.09)
    assert coverage(verts, faces, area) == pytest.approx(1.0, abs=0.01)
    # rotated and shifted off the raster grid it still covers its own area
    c, s = math.cos(0.37), math.sin(0.37)
    rot = verts @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + [0.0123, 0.4567, 0.8]
    assert coverage(rot, faces, area) == pytest.approx(1.0, abs=0.01)


def test_coverage_half_and_quarter_fold() -> None:
    verts, faces = grid()
    area = flat_area(verts, faces)
    half, _ = fold_goal(verts, [HALF], 0.002)
    quarter, _ = fold_goal(verts, [HALF, SECOND], 0.002)
    assert coverage(half, faces, area) == pytest.approx(0.5, abs=0.01)
    assert coverage(quarter, faces, area) == pytest.approx(0.25, abs=0.01)


def test_coverage_rejects_coarse_raster() -> None:
    verts, faces = grid()
    with pytest.raises(ConfigError, match="resolution"):
        coverage(verts, faces, 0.09, resolution=0.005)


def test_self_crossings_count_a_cloth_through_itself_only() -> None:
    verts, faces = grid()
    assert self_crossings(verts, faces) == 0  # flat
    half, _ = fold_goal(verts, [HALF], 0.002)
    assert self_crossings(half, faces) == 0  # folded in half, one layer 2 mm on the other
    # Crumpled: the sheet bent into waves without touching itself.
    wavy = verts.copy()
    wavy[:, 2] = 0.05 * np.sin(wavy[:, 0] * 40)
    assert self_crossings(wavy, faces) == 0
    # The folded half's middle vertex pushed 1 cm down, through the layer beneath: the edges
    # round it now pass through that layer's triangles.
    through = half.copy()
    top = np.flatnonzero(half[:, 2] > 0.001)
    k = top[np.argmin(np.linalg.norm(half[top, :2] - [0.075, 0.0], axis=1))]
    through[k, 2] = -0.01
    assert self_crossings(through, faces) > 0
    with pytest.raises(ConfigError, match="vertices"):
        self_crossings(verts[:, :2], faces)


def test_self_crossing_pairs_name_the_edges_and_triangles_that_cross() -> None:
    verts, faces = grid()
    half, _ = fold_goal(verts, [HALF], 0.002)
    assert self_crossing_pairs(half, faces).shape == (0, 3)
    through = half.copy()
    top = np.flatnonzero(half[:, 2] > 0.001)
    k = top[np.argmin(np.linalg.norm(half[top, :2] - [0.075, 0.0], axis=1))]
    through[k, 2] = -0.01  # pushed down through the layer beneath
    pairs = self_crossing_pairs(through, faces)
    assert len(pairs) == self_crossings(through, faces) > 0
    bottom = set(np.flatnonzero(half[:, 2] <= 0.001).tolist())
    for a, b, t in pairs:
        assert {a, b}.isdisjoint(faces[t])
        # k's edges through the layer beneath, or that layer's edges through k's triangles
        if k in (a, b):
            assert set(faces[t].tolist()) <= bottom
        else:
            assert k in faces[t] and {a, b} <= bottom


# --- success ----------------------------------------------------------------------------------


def test_success_thresholds_for_30cm_towel() -> None:
    area = 0.3 * 0.3
    assert fold_error_limit_mm(area) == pytest.approx(15.0)
    assert success(0.8, 15.0, area)
    assert not success(0.8, 15.01, area)
    assert not success(0.79, 1.0, area)
    assert success(1.0, 0.0, area)
    assert not success(math.nan, 0.0, area)
    assert flatten_success(0.9) and not flatten_success(0.89)


# --- score_episode ----------------------------------------------------------------------------


def test_score_episode_perfect_and_unmoved() -> None:
    verts, faces = grid()
    goal, _ = fold_goal(verts, [HALF, SECOND], 0.002)
    good = score_episode(verts, goal, faces, [HALF, SECOND], 0.002)
    assert good.fold_error_mm == 0.0
    assert good.normalized_performance == pytest.approx(1.0, abs=0.02)
    assert good.success is True
    assert good.coverage == pytest.approx(0.25, abs=0.01)
    assert good.flat_area_m2 == pytest.approx(0.09)
    bad = score_episode(verts, verts, faces, [HALF, SECOND], 0.002)
    assert bad.normalized_performance == 0.0
    assert bad.success is False
    assert bad.fold_error_mm > 15.0
    assert set(good.as_dict()) == {
        "fold_error_mm",
        "normalized_performance",
        "coverage",
        "success",
        "flat_area_m2",
        "perfect_fold_error_mm",
        "perfect_normalized",
        "self_crossings",
    }
    assert good.perfect_fold_error_mm == 0.0  # a half then a quarter fold lands on every layer
    assert good.perfect_normalized == pytest.approx(
        perfect_normalized(verts, [HALF, SECOND], 0.002)
    )
    assert bad.self_crossings == 0  # the flat sheet (the goal's creases are not a real cloth's)


def test_perfect_normalized_is_what_the_goal_scores() -> None:
    verts, faces = grid()
    t = 0.002
    a, b = fold_pairs(verts, HALF)
    group_start = float(np.mean(np.linalg.norm(verts[a] - verts[b], axis=1)))
    # On the grid's symmetry every moving vertex lands one thickness above its partner.
    assert perfect_normalized(verts, [HALF], t) == pytest.approx(1.0 - t / group_start)
    assert perfect_normalized(verts, [HALF], 0.0) == pytest.approx(1.0)
    goal, _ = fold_goal(verts, [HALF], t)
    assert perfect_normalized(verts, [HALF], t) == pytest.approx(
        score_episode(verts, goal, faces, [HALF], t).normalized_performance
    )
    # Off the grid's symmetry the nearest partner lies beside the mirror image: under 1 even
    # for a sheet of no thickness, and further under on a coarser mesh of the same towel.
    off = [0.01, 0.0, 0.0, 1.0]
    fine, _ = grid(n=21)
    coarse, _ = grid(n=7)
    assert perfect_normalized(fine, [off], 0.0) < 1.0
    assert perfect_normalized(coarse, [off], 0.0) < perfect_normalized(fine, [off], 0.0)
    with pytest.raises(ConfigError, match="fold_lines is empty"):
        perfect_normalized(verts, [], t)


def test_score_episode_counts_a_fold_through_itself() -> None:
    verts, faces = grid()
    half, _ = fold_goal(verts, [HALF], 0.002)
    top = np.flatnonzero(half[:, 2] > 0.001)
    k = top[np.argmin(np.linalg.norm(half[top, :2] - [0.075, 0.0], axis=1))]
    through = half.copy()
    through[k, 2] = -0.01  # pushed through the layer beneath
    score = score_episode(verts, through, faces, [HALF], 0.002)
    assert score.self_crossings == self_crossings(through, faces) > 0
    assert score_episode(verts, half, faces, [HALF], 0.002).self_crossings == 0


def test_score_episode_requires_a_fold_line() -> None:
    verts, faces = grid()
    with pytest.raises(ConfigError, match="fold_lines"):
        score_episode(verts, verts, faces, [], 0.002)
    with pytest.raises(ConfigError, match="thickness"):
        score_episode(verts, verts, faces, [HALF], -1.0)


# --- a perfect fold under the layer rule ---------------------------------------------------------

# Two side folds that do not overlap (a T-shirt's sides): the left two columns of the 11 × 11 grid
# onto columns 3-4, then the right two onto columns 6-7. The rule puts the second on layer 3.
LEFT_IN = [-0.09, 0.0, 0.0, 1.0]  # moving side x < -0.09
RIGHT_IN = [0.09, 0.0, 0.0, -1.0]  # moving side x > 0.09


def test_physical_layers_count_the_sheets_beneath() -> None:
    verts, faces = grid()
    goal, layers = fold_goal(verts, [LEFT_IN, RIGHT_IN], 0.002)
    resting = physical_layers(goal, layers, faces)
    column = np.round((verts[:, 0] + 0.15) / 0.03).astype(int)
    assert set(layers[column >= 9]) == {3} and set(layers[column <= 1]) == {1}
    assert set(resting[(column <= 1) | (column >= 9)]) == {1}  # each strip lies on the body only
    assert set(resting[(column >= 2) & (column <= 8)]) == {0}


def test_perfect_fold_error_of_disjoint_folds_and_of_stacked_ones() -> None:
    verts, faces = grid()
    t = 0.002
    # 22 of 121 vertices sit two layers lower than the rule asks.
    assert perfect_fold_error_mm(verts, faces, [LEFT_IN, RIGHT_IN], t) == pytest.approx(
        1000 * t * 2 * 22 / 121
    )
    assert perfect_fold_error_mm(verts, faces, [HALF], t) == 0.0
    assert perfect_fold_error_mm(verts, faces, [HALF, SECOND], t) == 0.0


def test_a_physically_perfect_fold_scores_perfect_fold_error() -> None:
    verts, faces = grid()
    t = 0.002
    goal, layers = fold_goal(verts, [LEFT_IN, RIGHT_IN], t)
    resting = goal.copy()
    resting[:, 2] = verts[:, 2] + physical_layers(goal, layers, faces) * t
    score = score_episode(verts, resting, faces, [LEFT_IN, RIGHT_IN], t)
    assert score.fold_error_mm == pytest.approx(score.perfect_fold_error_mm)
    assert score.perfect_fold_error_mm > 0.5
    assert score_episode(verts, goal, faces, [LEFT_IN, RIGHT_IN], t).fold_error_mm == 0.0


def test_physical_layers_rejects_mismatched_layers() -> None:
    verts, faces = grid()
    with pytest.raises(ConfigError, match="layers has 3 entries, goal has 121 vertices"):
        physical_layers(verts, np.zeros(3, dtype=int), faces)
