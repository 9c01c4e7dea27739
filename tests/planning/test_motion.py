import dataclasses

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.planning.actions import FoldAction
from foldbot.planning.motion import MotionConfig, action_segments

ACTION = FoldAction(
    grasp=np.array([0.60, 0.10, 0.755]),
    place=np.array([0.30, 0.10, 0.759]),
    fold_line=(0.45, -0.2, 0.0, 0.4),
    label="far_left",
)
START = np.array([0.3, 0.0, 1.0])


def test_default_placement_lowers_straight_onto_the_place_point():
    cfg = MotionConfig()
    segs = action_segments(ACTION, START, cfg)
    assert [s.name for s in segs] == ["approach", "descend", "carry", "lower", "retreat"]
    assert [s.gripper for s in segs] == [None, "close", None, "open", None]
    place_tcp = ACTION.place + [0, 0, cfg.grasp_depth]
    assert segs[2].points[-1] == pytest.approx(ACTION.place + [0, 0, cfg.place_height])
    assert segs[3].points[-1] == pytest.approx(place_tcp)


def test_slide_placement_comes_down_short_and_slides_out_onto_the_place_point():
    cfg = MotionConfig(place_slide=0.02)
    segs = action_segments(ACTION, START, cfg)
    assert [s.name for s in segs] == ["approach", "descend", "carry", "lower", "slide", "retreat"]
    assert [s.gripper for s in segs] == [None, "close", None, None, "open", None]
    place_tcp = ACTION.place + [0, 0, cfg.grasp_depth]
    touch = place_tcp + [0.02, 0.0, 0.0]  # 2 cm back toward the fold line (the carry runs −x)
    assert segs[3].points[-1] == pytest.approx(touch)
    assert segs[4].points[0] == pytest.approx(touch)
    assert segs[4].points[-1] == pytest.approx(place_tcp)
    # The slide runs at the table: constant height, straight along the carry direction.
    assert np.ptp(segs[4].points[:, 2]) == pytest.approx(0.0)
    assert np.allclose(segs[4].points[:, 1], place_tcp[1])
    assert segs[5].points[0] == pytest.approx(place_tcp)


def test_an_action_with_its_own_descent_comes_straight_down_that_far():
    cfg = MotionConfig()
    action = dataclasses.replace(ACTION, descent=0.04)
    segs = action_segments(action, START, cfg)
    assert segs[2].points[-1] == pytest.approx(ACTION.place + [0, 0, 0.04])
    lower = segs[3].points
    assert lower[-1] == pytest.approx(ACTION.place + [0, 0, cfg.grasp_depth])
    assert np.allclose(lower[:, :2], ACTION.place[:2])  # straight down, over the place
    assert segs[3].speed == pytest.approx(cfg.cartesian_speed / 3)
    plain = action_segments(ACTION, START, cfg)  # no descent of its own: the motion's 1 cm
    assert plain[2].points[-1] == pytest.approx(ACTION.place + [0, 0, cfg.place_height])


def test_an_actions_descent_travels_with_it():
    action = dataclasses.replace(ACTION, descent=0.04)
    assert FoldAction.from_dict(action.as_dict()).descent == pytest.approx(0.04)
    assert "descent" not in ACTION.as_dict()  # records of actions without one are as before
    assert FoldAction.from_dict(ACTION.as_dict()).descent is None


@pytest.mark.parametrize("descent", [float("nan"), -0.01, 0.001, 0.5])
def test_a_descent_below_the_grasp_depth_or_above_the_approach_is_refused(descent):
    with pytest.raises(ConfigError, match=r"descent .* must lie between the grasp depth"):
        action_segments(dataclasses.replace(ACTION, descent=descent), START, MotionConfig())


def test_a_segments_orientations_are_one_per_waypoint():
    from foldbot.planning.motion import Segment, line_path

    points = line_path(START, START + [0.1, 0.0, 0.0])
    turned = np.tile([0.0, 1.0, 0.0, 0.0], (len(points), 1))
    assert Segment("move", points, 0.1, orientations=turned).orientations is turned
    with pytest.raises(
        ConfigError,
        match=r"segment 'move': orientations must be 12×4 finite quaternions \(one per "
        r"waypoint\), got shape \(11, 4\)",
    ):
        Segment("move", points, 0.1, orientations=turned[:-1])
    turned[3, 0] = np.nan
    with pytest.raises(ConfigError, match="finite quaternions"):
        Segment("move", points, 0.1, orientations=turned)


RELAY = FoldAction(
    grasp=np.array([0.458, 0.10, 0.765]),  # a laid corner 8 mm short of its place
    place=np.array([0.45, 0.10, 0.759]),
    fold_line=(0.45, -0.2, 0.0, 0.4),
    label="relay_far_left",
    carry="stadium",
)


def test_a_stadium_carry_goes_up_over_a_half_circle_and_down():
    cfg = MotionConfig()
    carry = action_segments(RELAY, START, cfg)[2].points
    start, end = RELAY.grasp + [0, 0, cfg.grasp_depth], RELAY.place + [0, 0, cfg.place_height]
    assert carry[0] == pytest.approx(start) and carry[-1] == pytest.approx(end)
    assert carry[:, 2].max() == pytest.approx(start[2] + cfg.min_arc_height, abs=1e-4)
    # Straight up over the grasp, straight down over the place, nowhere outside the two.
    x = carry[:, 0]
    assert x.min() >= end[0] - 1e-9 and x.max() <= start[0] + 1e-9
    tip_radius = 0.008 / 2  # half the carry, against the half-sine's d²/(π²h) = 0.13 mm
    top = carry[carry[:, 2] >= carry[:, 2].max() - tip_radius]
    assert np.ptp(top[:, 0]) == pytest.approx(0.008, abs=1e-4)
    # The half-sine arc of the same carry, as every other carry still goes.
    arc = action_segments(dataclasses.replace(RELAY, carry="arc"), START, cfg)[2].points
    assert len(arc) == cfg.arc_points
    assert arc[:, 2].max() == pytest.approx(carry[:, 2].max(), abs=1e-4)


def test_an_actions_carry_travels_with_it_and_is_checked():
    assert FoldAction.from_dict(RELAY.as_dict()).carry == "stadium"
    assert "carry" not in ACTION.as_dict() and FoldAction.from_dict(ACTION.as_dict()).carry == "arc"
    with pytest.raises(ConfigError, match="carry must be 'arc' or 'stadium', got 'loop'"):
        dataclasses.replace(ACTION, carry="loop")


def test_an_actions_own_lift_raises_its_carry_and_travels_with_it():
    """A slipped corner laid back (LoopConfig.slip_lay_back_lift) goes up that high, both paths."""
    cfg = MotionConfig()
    lifted = dataclasses.replace(RELAY, lift=0.15)
    start_z = RELAY.grasp[2] + cfg.grasp_depth
    for carry in ("stadium", "arc"):
        points = action_segments(dataclasses.replace(lifted, carry=carry), START, cfg)[2].points
        assert points[:, 2].max() == pytest.approx(start_z + 0.15, abs=5e-4)
    # A long carry still rises in proportion to its length (above a lift that is lower).
    long_low = action_segments(dataclasses.replace(ACTION, lift=0.01), START, cfg)[2].points
    np.testing.assert_array_equal(long_low, action_segments(ACTION, START, cfg)[2].points)
    assert FoldAction.from_dict(lifted.as_dict()).lift == 0.15
    assert "lift" not in RELAY.as_dict() and FoldAction.from_dict(RELAY.as_dict()).lift is None


@pytest.mark.parametrize("lift", [0.0, -0.1, 0.6, float("nan")])
def test_a_lift_that_is_no_height_is_refused(lift):
    with pytest.raises(ConfigError, match=r"lift must be a height in \(0, 0.5\] m or None"):
        dataclasses.replace(ACTION, lift=lift)
