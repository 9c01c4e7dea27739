import dataclasses

import numpy as np
import pytest

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


def test_a_corner_carried_with_another_comes_straight_down_its_last_4_cm():
    cfg = MotionConfig()
    pair = cfg.for_pair()
    assert pair.place_height == pytest.approx(0.04) and cfg.place_height == pytest.approx(0.01)
    assert dataclasses.replace(pair, place_height=cfg.place_height) == cfg  # nothing else differs
    segs = action_segments(ACTION, START, pair)
    assert segs[2].points[-1] == pytest.approx(ACTION.place + [0, 0, 0.04])
    lower = segs[3].points
    assert lower[-1] == pytest.approx(ACTION.place + [0, 0, pair.grasp_depth])
    assert np.allclose(lower[:, :2], ACTION.place[:2])  # straight down, over the place
    assert segs[3].speed == pytest.approx(pair.cartesian_speed / 3)
