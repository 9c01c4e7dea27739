"""A fold action keeps every field through its JSON form (how the ROS nodes pass it); two corners'
carries join into one by their edge's middle."""

import json

import numpy as np
import pytest
from test_recipes import run_recipe, towel

from foldbot.metrics import FoldLine
from foldbot.planning.actions import FoldAction, edge_middle


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


@pytest.mark.parametrize("yaw", [0.0, 0.4, -1.1])
def test_quarters_stack_is_carried_by_the_middle_of_its_edge_onto_its_mirror(yaw):
    """Quarter's second stage joined into one carry: grasped midway along the stack's edge (as
    many layers as its corners are grasped with), laid on that point's mirror across the stage's line, which is
    the middle of the two corners' places."""
    plans, _, _ = run_recipe("quarter", towel(0.45, 0.02, 0.36, 0.28, yaw=yaw))
    second = plans[1]
    edge = edge_middle(second.actions)
    a, b = second.actions
    np.testing.assert_allclose(edge.grasp, (a.grasp + b.grasp) / 2)
    line = FoldLine.coerce(edge.fold_line)
    np.testing.assert_allclose(edge.place[:2], line.reflect_xy(edge.grasp)[:2], atol=1e-9)
    assert edge.layers == max(a.layers, b.layers)
    assert edge.label == f"middle_{a.label}_{b.label}" and edge.fold_line == a.fold_line


def test_only_two_carries_over_one_line_join():
    a = FoldAction(np.zeros(3), np.ones(3), (0.0, 0.0, 1.0, 0.0), "far_left", layers=2)
    c = FoldAction(np.ones(3), np.ones(3) * 3, (0.0, 0.0, 1.0, 0.0), "near_left")
    joined = edge_middle([a, c])
    assert joined.layers == 2 and joined.label == "middle_far_left_near_left"
    assert edge_middle([c, c], layers=3).layers == 3
    np.testing.assert_allclose(joined.place, [2.0, 2.0, 2.0])
    with pytest.raises(ValueError, match="joins 2 actions, got 1"):
        edge_middle([a])
    b = FoldAction(np.zeros(3), np.ones(3), (0.0, 0.1, 1.0, 0.0), "near_left")
    with pytest.raises(ValueError, match="over one fold line"):
        edge_middle([a, b])
