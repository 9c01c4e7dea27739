import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.metrics import FoldLine
from foldbot.planning.recipes import half_fold, plan_recipe


def square(cx=0.45, cy=0.0, side=0.3, yaw=0.0, z=0.752):
    h = side / 2
    local = {"near_left": (-h, h), "near_right": (-h, -h), "far_right": (h, -h), "far_left": (h, h)}
    c, s = np.cos(yaw), np.sin(yaw)
    return {n: np.array([cx + c * x - s * y, cy + s * x + c * y, z]) for n, (x, y) in local.items()}


def test_half_fold_along_x_moves_far_corners_onto_near_corners():
    corners = square()
    plan = half_fold(corners, axis="x", place_lift=0.01)
    assert plan.recipe == "half" and len(plan.fold_lines) == 1
    line = FoldLine.coerce(plan.fold_lines[0])
    # The line runs through the middle of the towel, parallel to y.
    assert line.x == pytest.approx(0.45)
    assert abs(line.dx) < 1e-12
    # The far half (x > 0.45) is the moving side: left of the line's direction.
    assert line.moving_mask(np.array([[0.55, 0.0]]))[0]
    assert not line.moving_mask(np.array([[0.35, 0.0]]))[0]
    assert [a.label for a in plan.actions] == ["far_left", "far_right"]
    for action, target in zip(plan.actions, ("near_left", "near_right"), strict=True):
        assert np.allclose(action.grasp, corners[action.label])
        assert np.allclose(action.place[:2], corners[target][:2], atol=1e-9)
        assert action.place[2] == pytest.approx(corners[action.label][2] + 0.01)


@pytest.mark.parametrize("yaw", [0.3, -0.7, 1.2])
def test_half_fold_follows_the_perceived_pose(yaw):
    corners = square(cx=0.4, cy=0.05, side=0.26, yaw=yaw)
    plan = half_fold(corners, axis="y")
    centre = np.mean([c for c in corners.values()], axis=0)
    line = FoldLine.coerce(plan.fold_lines[0])
    # The fold line passes through the cloth centre …
    rel = centre[:2] - [line.x, line.y]
    d = np.array([line.dx, line.dy]) / np.hypot(line.dx, line.dy)
    assert abs(rel[0] * d[1] - rel[1] * d[0]) < 1e-9
    # … and each place point is its grasp point mirrored across it.
    for action in plan.actions:
        mirrored = line.reflect_xy(action.grasp[None, :2])[0]
        assert np.allclose(action.place[:2], mirrored)
        assert line.moving_mask(action.grasp[None, :2])[0]


def test_missing_corner_and_unknown_recipe_are_rejected():
    corners = square()
    del corners["far_left"]
    with pytest.raises(ConfigError, match="far_left"):
        half_fold(corners)
    with pytest.raises(ConfigError, match="origami"):
        plan_recipe("origami", square())
    with pytest.raises(ConfigError, match="axis"):
        half_fold(square(), axis="z")
