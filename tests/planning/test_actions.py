"""A fold action keeps every field through its JSON form (how the ROS nodes pass it)."""

import json

import numpy as np

from foldbot.planning.actions import FoldAction


def test_fold_action_round_trip():
    a = FoldAction(
        np.array([0.6, 0.1, 0.76]),
        np.array([0.3, 0.1, 0.77]),
        (0.45, 0.2, 0.0, -0.4),
        "far_left",
        layers=2,
    )
    b = FoldAction.from_dict(json.loads(json.dumps(a.as_dict())))
    np.testing.assert_array_equal(a.grasp, b.grasp)
    np.testing.assert_array_equal(a.place, b.place)
    # A stack grasp stays one (over ROS it used to come back as a one-layer grasp).
    assert a.fold_line == b.fold_line and a.label == b.label and b.layers == 2
