import math

import numpy as np
import pytest

from foldbot.errors import ConfigError, FoldbotError
from foldbot.perception.keypoints import CORNER_LABELS
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.planning.flatten import FlattenConfig
from foldbot.planning.motion import MotionConfig
from foldbot.planning.spread import (
    MARGIN_FREE_SEGMENTS,
    SPREAD_SCALARS,
    SpreadAction,
    SpreadConfig,
    action_as_dict,
    action_from_dict,
    corner_pairs,
    motion_segments,
    palm_underside_rise,
    plan_spread,
    plan_spread_at,
    spread_segments,
    spread_width,
)
from foldbot.planning.tool import (
    GRIPPER_DOWN,
    gripper_leaning_quaternion,
)

TABLE = 0.75
W, H = 0.40, 0.30


def heap_state(corners_xy, confidences, z=TABLE + 0.03) -> ClothState:
    """A perceived heap with four corners (CORNER_LABELS order) at `corners_xy`."""
    xy = np.asarray(corners_xy, dtype=float)
    return ClothState(
        detected=True,
        reason="synthetic",
        keypoints={
            k: (np.array([x, y, z]), c)
            for k, (x, y), c in zip(CORNER_LABELS, xy, confidences, strict=True)
        },
        mask=np.ones((4, 4), bool),
        coverage_m2=0.05,
        outline_world=np.c_[xy, np.full(4, z)],
        table_plane=np.array([0.0, 0.0, 1.0, -TABLE]),
    )


# near_left, near_right, far_right, far_left (counter-clockwise seen from above)
HEAP = [[0.38, 0.08], [0.40, -0.10], [0.55, -0.07], [0.52, 0.12]]


def test_the_surest_adjacent_pair_is_taken():
    state = heap_state(HEAP, [0.9, 0.2, 0.8, 0.85])
    # near_left–near_right: min 0.2; near_right–far_right: 0.2; far_right–far_left: 0.8;
    # far_left–near_left: 0.85 → the best pair.
    pairs = corner_pairs(state)
    assert pairs[0] == ("far_left", "near_left")
    assert pairs[1] == ("far_right", "far_left")
    assert set(pairs[2:]) == {("near_left", "near_right"), ("near_right", "far_right")}
    plan = plan_spread(state, (W, H), SpreadConfig(), FlattenConfig())
    assert set(plan.corners) == {"far_left", "near_left"}
    plan = plan_spread(state, (W, H), SpreadConfig(), FlattenConfig(), pair=pairs[1])
    assert set(plan.corners) == {"far_right", "far_left"}


def test_a_state_without_four_corners_is_refused():
    state = heap_state(HEAP, [0.9, 0.9, 0.9, 0.9])
    del state.keypoints["far_left"]
    with pytest.raises(FoldbotError, match="missing far_left"):
        corner_pairs(state)
    with pytest.raises(FoldbotError, match="no cloth"):
        corner_pairs(ClothState.not_detected())


def test_the_spread_width_is_a_nominal_side():
    assert spread_width(0.12, W, H) == pytest.approx(H)  # a heap: corners seen close
    assert spread_width(0.34, W, H) == pytest.approx(H)
    assert spread_width(0.36, W, H) == pytest.approx(W)


def test_a_spread_holds_the_corners_apart_and_lays_the_towel_centred():
    cfg, flat = SpreadConfig(), FlattenConfig()
    state = heap_state(HEAP, [0.9, 0.9, 0.9, 0.9])
    plan = plan_spread(state, (W, H), cfg, flat)
    left, right = plan.actions
    # The corner further along +y goes to the +y side (arm 0): no crossing.
    assert left.grasp[1] > right.grasp[1]
    assert left.hold[1] - right.hold[1] == pytest.approx(plan.width)
    assert plan.width == pytest.approx(H) and plan.hang == pytest.approx(W)
    for a in plan.actions:
        # Each grasp a little inside its perceived corner, on the cloth's top.
        assert a.grasp[2] == pytest.approx(TABLE + flat.grasp_height)  # no surface given
        # The towel hangs clear of the table at the hold, no higher than the arms reach.
        assert a.hold[2] - TABLE == pytest.approx(min(W + cfg.hang_margins[0], cfg.max_hold_height))
        assert a.hold[0] <= cfg.hold_far_x
        # Laid at 45°-ish towards the near side, let go just above the table.
        assert a.touch[2] < a.hold[2] and a.touch[:2] == pytest.approx(a.hold[:2])
        assert a.release[0] < a.hold[0]
        assert a.release[2] == pytest.approx(TABLE + cfg.release_height)
        assert a.release[0] >= flat.workspace[0] + flat.margin - 1e-9
    # Centred on the workspace across y.
    assert left.hold[1] + right.hold[1] == pytest.approx(2 * cfg.center_xy[1])


def test_a_lower_margin_holds_lower():
    cfg, flat = SpreadConfig(), FlattenConfig()
    state = heap_state(HEAP, [0.9, 0.9, 0.9, 0.9])
    high = plan_spread(state, (0.30, 0.25), cfg, flat, margin=0.10)
    low = plan_spread(state, (0.30, 0.25), cfg, flat, margin=0.0)
    assert low.actions[0].hold[2] == pytest.approx(high.actions[0].hold[2] - 0.10)


def test_grasps_take_the_top_layer_from_the_surface():
    flat = FlattenConfig()
    state = heap_state(HEAP, [0.9, 0.9, 0.9, 0.9])
    ny = round((flat.workspace[3] - flat.workspace[2]) / flat.raster) + 1
    nx = round((flat.workspace[1] - flat.workspace[0]) / flat.raster) + 1
    surface = np.full((ny, nx), 0.05, np.float32)  # a heap 5 cm high everywhere
    plan = plan_spread(state, (W, H), SpreadConfig(), flat, surface)
    for a in plan.actions:
        assert a.grasp[2] == pytest.approx(TABLE + 0.05 - SpreadConfig().top_depth, abs=1e-6)


def test_both_arms_get_the_same_steps_with_a_still_hang():
    motion = MotionConfig()
    plan = plan_spread(heap_state(HEAP, [0.9] * 4), (W, H), SpreadConfig(), FlattenConfig())
    lists = [spread_segments(a, np.array([0.45, 0.3, 1.0]), motion) for a in plan.actions]
    names = [[s.name for s in segs] for segs in lists]
    assert names[0] == names[1]
    steps = ["approach", "come_down", "descend", "lift", "spread", "lower", "lay", "retreat"]
    assert names[0] == steps
    for segs, a in zip(lists, plan.actions, strict=True):
        by = {s.name: s for s in segs}
        assert by["descend"].gripper == "close" and by["lay"].gripper == "open"
        assert by["spread"].dwell == pytest.approx(SpreadConfig().hang_time)
        assert by["lay"].speed == pytest.approx(SpreadConfig().lay_speed)
        # Slow only over the last slow_descent above the corner, straight down onto it.
        assert by["descend"].speed == pytest.approx(SpreadConfig().descend_speed)
        assert by["come_down"].speed == pytest.approx(motion.free_speed / 3)
        assert by["come_down"].points[-1] == pytest.approx(by["descend"].points[0])
        drop = by["descend"].points[0] - by["descend"].points[-1]
        assert drop == pytest.approx([0.0, 0.0, SpreadConfig().slow_descent])
        assert by["descend"].points[-1] == pytest.approx(a.grasp + [0, 0, motion.grasp_depth])
        assert by["spread"].points[-1] == pytest.approx(a.hold)
        # The dispatcher gives the same segments.
        again = motion_segments(a, np.array([0.45, 0.3, 1.0]), motion)
        assert [s.name for s in again] == names[0]


def test_gripper_down_all_along_unless_tilted():
    plan = plan_spread(heap_state(HEAP, [0.9] * 4), (W, H), SpreadConfig(), FlattenConfig())
    for a in plan.actions:
        assert a.tilt == 0.0
        segs = spread_segments(a, np.array([0.45, 0.3, 1.0]), MotionConfig())
        assert all(s.orientations is None for s in segs)  # the executor's gripper-down


def test_a_tilted_spread_leans_each_wrist_away_from_the_other_arm_at_the_grasp():
    state = heap_state(HEAP, [0.9] * 4)
    plan = plan_spread(state, (W, H), SpreadConfig(), FlattenConfig(), tilt=0.3)
    (left, right) = plan.actions  # the +y arm's part first
    assert (left.tilt, right.tilt) == (0.3, -0.3)
    assert left.hold[1] > right.hold[1]
    # Only the tools turn: every point is where the untilted spread puts it.
    flat = plan_spread(state, (W, H), SpreadConfig(), FlattenConfig())
    for a, b in zip(plan.actions, flat.actions, strict=True):
        for k in ("grasp", "hold", "touch", "release"):
            np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    for a in plan.actions:
        by = {s.name: s for s in spread_segments(a, np.array([0.45, 0.3, 1.0]), MotionConfig())}
        tilted = gripper_leaning_quaternion(a.tilt, math.pi / 2)
        turn = by["approach"].orientations
        assert turn.shape == (len(by["approach"].points), 4)
        np.testing.assert_allclose(turn[0], GRIPPER_DOWN)  # turned on the way in
        np.testing.assert_allclose(turn[-1], tilted)
        for name in ("come_down", "descend", "lift"):  # held tilted down to the corner and off
            np.testing.assert_allclose(
                by[name].orientations, np.tile(tilted, (len(by[name].points), 1))
            )
        back = by["spread"].orientations  # turned back on the rise to the hold
        np.testing.assert_allclose(back[0], tilted)
        np.testing.assert_allclose(back[-1], GRIPPER_DOWN, atol=1e-12)
        assert all(by[n].orientations is None for n in ("lower", "lay", "retreat"))


def test_the_way_to_the_corners_is_the_same_at_every_margin():
    """flatten._spread_once moves on to the next pair when one of these segments fails, without
    trying the lower margins: they must not depend on the margin."""
    motion, cfg, flat = MotionConfig(), SpreadConfig(), FlattenConfig()
    state = heap_state(HEAP, [0.9] * 4)
    start = np.array([0.45, 0.3, 1.0])
    by_margin = [
        {
            s.name: s
            for s in spread_segments(
                plan_spread(state, (W, H), cfg, flat, margin=m).actions[0], start, motion
            )
        }
        for m in cfg.hang_margins
    ]
    assert set(by_margin[0]) >= MARGIN_FREE_SEGMENTS
    for other in by_margin[1:]:
        for name in MARGIN_FREE_SEGMENTS:
            np.testing.assert_array_equal(other[name].points, by_margin[0][name].points)
            assert other[name].speed == by_margin[0][name].speed
        assert not np.array_equal(other["spread"].points, by_margin[0]["spread"].points)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"hang_time": -1.0}, "hang_time"),
        ({"lay_speed": 0.0}, "lay_speed"),
        ({"descend_speed": 0.0}, "descend_speed"),
        ({"slow_descent": 0.0}, "slow_descent"),
        ({"hang_margins": ()}, "hang_margins"),
        ({"hang_margins": (0.5,)}, "hang_margins"),
        ({"pull_from": -0.1}, r"pull_from must be None or in \[0, 1.5\], got -0.1"),
        ({"pull_from": float("inf")}, "pull_from"),
        ({"grasp_tilt": 0.7}, r"grasp_tilt must be in \[0, 0.6\], got 0.7"),
        ({"grasp_tilt": -0.1}, "grasp_tilt"),
    ],
)
def test_bad_config_is_named(kw, match):
    with pytest.raises(ConfigError, match=match):
        SpreadConfig(**kw)


def test_a_bad_expected_size_is_named():
    with pytest.raises(ConfigError, match="expected width"):
        plan_spread(heap_state(HEAP, [0.9] * 4), (0.0, H), SpreadConfig(), FlattenConfig())


def test_the_edge_just_laid_is_tried_last():
    state = heap_state(HEAP, [0.9, 0.9, 0.8, 0.85])
    first = corner_pairs(state)[0]
    assert first == ("near_left", "near_right")
    # The last spread let go where near_left and near_right now lie: that edge goes last.
    laid = np.array([[*HEAP[0], TABLE], [*HEAP[1], TABLE]])
    pairs = corner_pairs(state, laid)
    assert pairs[-1] == ("near_left", "near_right")
    assert pairs[0] == ("far_left", "near_left")


def _raster(flat: FlattenConfig, height: float) -> np.ndarray:
    ny = round((flat.workspace[3] - flat.workspace[2]) / flat.raster) + 1
    nx = round((flat.workspace[1] - flat.workspace[0]) / flat.raster) + 1
    return np.full((ny, nx), height, np.float32)


def test_a_corner_under_a_heap_is_not_palm_clear():
    flat = FlattenConfig()
    state = heap_state(HEAP, [0.9] * 4)
    surface = _raster(flat, 0.01)  # cloth 1 cm high everywhere: the palm clears it
    assert plan_spread(state, (W, H), SpreadConfig(), flat, surface).palm_clear
    # A 10 cm heap 4 cm from the far_left corner: the grasp must rise 6 cm for the palm to
    # clear it, where the jaws no longer reach the corner's cloth.
    x, y = HEAP[3][0] - 0.04, HEAP[3][1]
    j = round((y - flat.workspace[2]) / flat.raster)
    i = round((x - flat.workspace[0]) / flat.raster)
    surface[j, i] = 0.10
    plan = plan_spread(state, (W, H), SpreadConfig(), flat, surface, pair=("far_left", "near_left"))
    assert not plan.palm_clear
    far_left = next(a for a in plan.actions if a.label == "spread far_left")
    assert far_left.grasp[2] == pytest.approx(TABLE + 0.10 - flat.palm_clearance, abs=1e-6)


def test_a_leaning_palm_comes_lower_on_the_side_the_wrist_leans_to():
    """The palm's underside turns with the tool: 11 mm lower at its edge on the wrist's side at
    20°, 6 mm higher at the other; past its edges, the edge's height."""
    assert np.all(palm_underside_rise(np.array([-0.1, 0.0, 0.1]), 0.0) == 0.0)
    low, mid, high = palm_underside_rise(np.array([0.06, 0.045 * math.sin(0.35), -0.06]), 0.35)
    assert low == pytest.approx(0.045 * math.cos(0.35) - 0.025 * math.sin(0.35) - 0.045)
    assert low == pytest.approx(-0.0113, abs=0.0001)
    assert high == pytest.approx(0.045 * math.cos(0.35) + 0.025 * math.sin(0.35) - 0.045)
    assert mid == pytest.approx(0.045 * math.cos(0.35) - 0.045)
    np.testing.assert_allclose(
        palm_underside_rise(np.array([0.02]), -0.35), palm_underside_rise(np.array([0.02]), 0.35)
    )


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_tilted_grasp_rises_over_cloth_where_the_palm_leans_and_less_elsewhere(side):
    """A 6 cm heap 5 cm beside the +y arm's grasp (far_left, leaning to +y): on the side its
    wrist leans to, the grasp rises 11 mm more than gripper down for the palm to clear it; on
    the other side 6 mm less."""
    flat = FlattenConfig()
    state = heap_state(HEAP, [0.9] * 4)
    pair = ("far_left", "near_left")

    def far_left(plan):
        return next(a for a in plan.actions if a.label == "spread far_left")

    surface = _raster(flat, 0.0)
    xy = far_left(plan_spread(state, (W, H), SpreadConfig(), flat, surface, pair=pair)).grasp
    x, y = xy[0], xy[1] + side * 0.05
    surface[
        round((y - flat.workspace[2]) / flat.raster), round((x - flat.workspace[0]) / flat.raster)
    ] = 0.06
    down = plan_spread(state, (W, H), SpreadConfig(), flat, surface, pair=pair)
    tilted = plan_spread(state, (W, H), SpreadConfig(), flat, surface, pair=pair, tilt=0.35)
    assert far_left(tilted).tilt == 0.35  # the +y arm's wrist leans to +y
    assert far_left(down).grasp[2] == pytest.approx(TABLE + 0.06 - flat.palm_clearance)
    rise = palm_underside_rise(np.array([side * 0.1]), 0.35)[0]
    assert far_left(tilted).grasp[2] == pytest.approx(far_left(down).grasp[2] - rise)
    np.testing.assert_array_equal(far_left(tilted).grasp[:2], far_left(down).grasp[:2])


def test_tools_leaning_apart_lean_along_the_line_between_the_corners():
    """`lean="apart"`: each wrist leans away from the other corner, whichever way the pair
    lies; two corners lying along x lean along x, where leaning along ±y cannot part them."""
    along_x = [[0.40, 0.01], [0.40, -0.20], [0.60, -0.20], [0.52, 0.0]]
    state = heap_state(along_x, [0.9] * 4)
    pair = ("far_left", "near_left")  # (0.52, 0.0) and (0.40, 0.01)
    plan = plan_spread(
        state, (W, H), SpreadConfig(), FlattenConfig(), pair=pair, tilt=0.3, lean="apart"
    )
    for a in plan.actions:
        other = next(b for b in plan.actions if b is not a)
        away = a.grasp[:2] - other.grasp[:2]
        assert a.tilt == 0.3
        assert a.tilt_heading == pytest.approx(math.atan2(away[1], away[0]))
        by = {s.name: s for s in spread_segments(a, np.array([0.45, 0.3, 1.0]), MotionConfig())}
        np.testing.assert_allclose(
            by["descend"].orientations[-1], gripper_leaning_quaternion(0.3, a.tilt_heading)
        )
    far = next(a for a in plan.actions if a.label == "spread far_left")
    assert abs(math.cos(far.tilt_heading)) > 0.99 and math.cos(far.tilt_heading) > 0  # +x
    with pytest.raises(ConfigError, match="lean must be one of sides, apart, got 'up'"):
        plan_spread(state, (W, H), SpreadConfig(), FlattenConfig(), tilt=0.3, lean="up")
    with pytest.raises(ConfigError, match="grasp_lean must be one of sides, apart, got 'x'"):
        SpreadConfig(grasp_lean="x")


def test_a_pair_just_missed_is_tried_last_after_the_edge_just_laid():
    state = heap_state(HEAP, [0.9, 0.2, 0.8, 0.85])
    assert corner_pairs(state)[0] == ("far_left", "near_left")
    xy = {k: np.array([x, y, TABLE]) for k, (x, y) in zip(CORNER_LABELS, HEAP, strict=True)}
    missed = np.array([xy["far_left"], xy["near_left"]]) + [0.01, -0.01, 0.0]
    laid = np.array([xy["far_right"], xy["far_left"]])
    pairs = corner_pairs(state, laid, missed=missed)
    assert pairs[-1] == ("far_left", "near_left"), "the pair whose grasps just missed"
    assert pairs[-2] == ("far_right", "far_left"), "the edge just laid, before it"
    # Points away from every corner change nothing.
    far = np.array([[0.0, 0.9, TABLE], [0.1, 0.9, TABLE]])
    assert corner_pairs(state, missed=far) == corner_pairs(state)


def test_an_action_travels_as_data_and_comes_back_the_same():
    # For a planner in another process (the ROS planner node): a spread's part with every speed
    # and its hang, or a pick-and-place, named by kind.
    cfg = SpreadConfig(hang_time=0.5, lay_speed=0.08)
    plan = plan_spread(
        heap_state(HEAP, [0.9] * 4), (W, H), cfg, FlattenConfig(), tilt=0.2, lean="apart"
    )
    for action in plan.actions:
        d = action_as_dict(action)
        assert d["kind"] == "spread" and d["hang_time"] == 0.5 and d["lay_speed"] == 0.08
        back = action_from_dict(d)
        assert isinstance(back, SpreadAction) and back.label == action.label
        for k in ("grasp", "hold", "touch", "release"):
            assert np.array_equal(getattr(back, k), getattr(action, k))
        for k in SPREAD_SCALARS:
            assert getattr(back, k) == getattr(action, k)
        segs = [
            spread_segments(a, np.array([0.45, 0.3, 1.0]), MotionConfig()) for a in (action, back)
        ]
        assert [(s.name, s.speed, s.dwell) for s in segs[0]] == [
            (s.name, s.speed, s.dwell) for s in segs[1]
        ]
        assert back.tilt == action.tilt != 0.0
        for s0, s1 in zip(*segs, strict=True):
            assert (s0.orientations is None) == (s1.orientations is None)
            if s0.orientations is not None:
                np.testing.assert_array_equal(s0.orientations, s1.orientations)
    fold = FoldAction(np.array([0.4, 0.1, 0.75]), np.array([0.6, 0.1, 0.75]), (0.5, 0, 0, 1), "c")
    d = action_as_dict(fold)
    assert d["kind"] == "fold"
    back = action_from_dict(d)
    assert isinstance(back, FoldAction) and np.array_equal(back.place, fold.place)
    # No kind: a pick-and-place, as before spreads travelled.
    assert isinstance(action_from_dict(fold.as_dict()), FoldAction)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"kind": "fling"}, "unknown action kind 'fling'; allowed: fold, spread"),
        ({"hold": None}, "spread action's 'hold' must be 3 finite numbers, got None"),
        ({"touch": [0.6, 0.1]}, "'touch' must be 3 finite numbers"),
        ({"release": [0.3, 0.1, float("nan")]}, "'release' must be 3 finite numbers"),
        ({"hang_time": "long"}, "'hang_time' must be a finite number, got 'long'"),
        ({"lay_speed": float("inf")}, "'lay_speed' must be a finite number, got inf"),
    ],
)
def test_a_bad_action_is_named(change, match):
    plan = plan_spread(heap_state(HEAP, [0.9] * 4), (W, H), SpreadConfig(), FlattenConfig())
    with pytest.raises(FoldbotError, match=match):
        action_from_dict({**action_as_dict(plan.actions[0]), **change})


def test_a_corner_seen_out_on_the_table_is_grasped_on_the_first_cloth_inward():
    # A heap's rounded tip: the outline's sides meet 4 cm out on bare table at far_left.
    flat = FlattenConfig()
    state = heap_state(HEAP, [0.9] * 4)
    surface = _raster(flat, 0.01)
    corner = np.array(HEAP[3])
    centre = np.mean(HEAP, axis=0)
    inward = (centre - corner) / np.linalg.norm(centre - corner)
    ny, nx = surface.shape
    jj, ii = np.mgrid[0:ny, 0:nx]
    cell_xy = np.stack([flat.workspace[0] + ii * flat.raster, flat.workspace[2] + jj * flat.raster])
    along = np.tensordot(inward, cell_xy - corner[:, None, None], axes=1)
    surface[along < 0.04] = np.nan  # no cloth seen within 4 cm of the corner, towards the centre
    pair = ("far_left", "near_left")

    def grasp(cfg: SpreadConfig) -> np.ndarray:
        plan = plan_spread(state, (W, H), cfg, flat, surface, pair=pair)
        return next(a for a in plan.actions if a.label == "spread far_left").grasp

    as_seen = grasp(SpreadConfig(seek_cloth=0.0))
    np.testing.assert_allclose(as_seen[:2], corner + 0.008 * inward, atol=1e-9)
    sought = grasp(SpreadConfig(seek_cloth=0.1))
    went = float((sought[:2] - corner) @ inward)
    assert 0.04 - flat.raster <= went - 0.008 <= 0.04 + flat.raster, went
    assert np.linalg.norm(sought[:2] - (corner + went * inward)) < 1e-9, "straight inward"
    i = round((sought[0] - flat.workspace[0]) / flat.raster)
    j = round((sought[1] - flat.workspace[2]) / flat.raster)
    assert np.isfinite(surface[j, i]), "the jaws close over cloth seen"
    # Not far enough to reach it: aimed as seen. A corner on cloth is not moved.
    np.testing.assert_allclose(grasp(SpreadConfig(seek_cloth=0.02)), as_seen)
    on_cloth = plan_spread(state, (W, H), SpreadConfig(seek_cloth=0.1), flat, _raster(flat, 0.01))
    plain = plan_spread(state, (W, H), SpreadConfig(seek_cloth=0.0), flat, _raster(flat, 0.01))
    for a, b in zip(on_cloth.actions, plain.actions, strict=True):
        np.testing.assert_array_equal(a.grasp, b.grasp)
    # A corner just off the outline (its own cell bare, the next inward cloth): one cell in.
    surface[:] = 0.01
    surface[along < 0.004] = np.nan
    went = float((grasp(SpreadConfig(seek_cloth=0.1))[:2] - corner) @ inward) - 0.008
    assert 0.0 < went <= flat.raster + 1e-9, went


def test_seek_cloth_out_of_range_is_named():
    with pytest.raises(ConfigError, match=r"seek_cloth must be in \[0, 0.2\], got 0.5"):
        SpreadConfig(seek_cloth=0.5)


def test_a_spread_from_two_chosen_points_grasps_there_and_spreads_as_from_corners():
    """plan_spread_at (a policy's two grasp points): the jaws close on the points themselves, on
    the surface seen there, and the hold, hang and lay are the corners' spread's."""
    cfg, flat = SpreadConfig(), FlattenConfig()
    state = heap_state(HEAP, [0.9] * 4)
    surface = _raster(flat, 0.05)
    a, b = np.array([0.42, -0.05]), np.array([0.50, 0.09])
    plan = plan_spread_at(state, (a, b), (W, H), cfg, flat, surface)
    assert plan.corners == ("pick_b", "pick_a")  # the +y point's arm first
    np.testing.assert_allclose(plan.actions[0].grasp[:2], b)
    np.testing.assert_allclose(plan.actions[1].grasp[:2], a)
    for act in plan.actions:
        assert act.grasp[2] == pytest.approx(TABLE + 0.05 - cfg.top_depth, abs=1e-6)
        assert act.tilt == 0.0
    # The same grasps taken as corners spread the same way.
    corners = heap_state([b, a, [0.6, 0.0], [0.6, 0.1]], [0.9] * 4)
    as_corners = plan_spread(corners, (W, H), cfg, flat, surface, pair=("near_left", "near_right"))
    assert plan.width == pytest.approx(as_corners.width)
    for mine, theirs in zip(plan.actions, as_corners.actions, strict=True):
        np.testing.assert_allclose(mine.hold, theirs.hold)
        np.testing.assert_allclose(mine.release, theirs.release)


@pytest.mark.parametrize(
    "points", [(np.array([0.4, 0.0]),), (np.array([0.4, np.nan]), np.array([0.5, 0.1]))]
)
def test_bad_spread_points_are_named(points):
    with pytest.raises(ConfigError, match="a spread takes two finite table points"):
        plan_spread_at(heap_state(HEAP, [0.9] * 4), points, (W, H), SpreadConfig(), FlattenConfig())
