"""The options every node shares: the finger joints a slip watch reads, how far a finger may move
before a hold counts as lost, and the fold's options parsed as `foldbot fold` parses them."""

import pytest

from foldbot.errors import ConfigError
from foldbot.ros.node_args import (
    SLIP_FINGER_TRAVEL,
    finger_joint_names,
    finger_travel_for,
    parse_fold_args,
)

ROBOT_FINGERS = ("finger_left_joint", "finger_right_joint")


@pytest.mark.parametrize(
    ("text", "names"),
    [
        ("", ROBOT_FINGERS),  # the robot model's own
        ("  ", ROBOT_FINGERS),
        ("none", ()),  # a gripper whose fingers are not watched
        ("knuckle", ("knuckle",)),
        ("left_finger, right_finger", ("left_finger", "right_finger")),
    ],
)
def test_finger_joints_named(text, names):
    assert finger_joint_names(text, ROBOT_FINGERS) == names


@pytest.mark.parametrize("text", ["a,,b", "a,", "left finger"])
def test_finger_joints_that_are_no_names_are_refused(text):
    with pytest.raises(ConfigError, match="comma-separated joint names, 'none', or empty"):
        finger_joint_names(text, ROBOT_FINGERS)


@pytest.mark.parametrize(
    ("given", "joints", "thickness", "travel", "source"),
    [
        (0.0015, "", 0.0036, 0.0015, "given"),
        (None, "", 0.0036, 0.0009, "cloth thickness"),  # a quarter of a 3.6 mm layer
        (None, "", 0.02, SLIP_FINGER_TRAVEL, "cloth thickness"),  # at most 2 mm
        (None, "knuckle", 0.0036, SLIP_FINGER_TRAVEL, "default"),  # joints of unknown travel
    ],
)
def test_finger_travel_and_where_it_came_from(given, joints, thickness, travel, source):
    found, came_from = finger_travel_for(given, joints, thickness)
    assert found == pytest.approx(travel) and came_from == source


def test_the_nodes_parse_the_fold_options_as_fold_does():
    args, cfg = parse_fold_args("--out e --width 0.28 --resolution 9 --no-odd-grid --seed 3")
    assert str(args.out) == "e" and cfg.seed == 3
    assert (cfg.towel.width, cfg.towel.height, cfg.towel.resolution) == (0.28, 0.30, 9)
    assert cfg.towel.odd_grid is False
    _args, cfg = parse_fold_args("--out e")
    assert cfg.towel.odd_grid is True  # fold's default, where the option is not given
    with pytest.raises(ConfigError, match="--width shapes a towel"):
        parse_fold_args("--out e --garment tshirt --width 0.4")
