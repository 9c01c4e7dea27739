import ast
import inspect

import numpy as np
import pytest

import foldbot.planning.recipes as recipes_module
from foldbot.errors import ConfigError
from foldbot.metrics import FoldLine, fold_goal
from foldbot.perception.keypoints import label_corners
from foldbot.planning.recipes import (
    CORNER_NAMES,
    RECIPE_HELP,
    RECIPES,
    carries_stack,
    folded_as,
    half_fold,
    plan_recipe,
    plan_stage,
    predicted_cover,
    predicted_outline,
    recipe_fold_lines,
    recipe_stages,
)

# (centre x, centre y, yaw): several positions and yaws, away from the labelling ties at 45° + k·90°.
POSES = [
    (0.45, 0.0, 0.0),
    (0.40, 0.05, 0.3),
    (0.50, -0.08, -0.7),
    (0.42, 0.1, 1.2),
    (0.5, 0.0, 2.5),
]
# (depth, width) of the flat towel: square, deep, wide.
SHAPES = [(0.3, 0.3), (0.36, 0.24), (0.22, 0.34)]
STAGE_GRASPS = {
    "half": [("far_left", "far_right")],
    "half_y": [("far_left", "near_left")],
    "half_long": "shape",  # half or half_y: the far-apart pair, by the towel's shape
    "quarter": [("far_left", "far_right"), ("far_left", "near_left")],
    "quarter_x": [("far_left", "far_right"), ("far_left", "near_left")],
    "quarter_y": [("far_left", "near_left"), ("far_left", "far_right")],
    "diagonal": None,  # one far corner, chosen by the pose and shape
    "diagonal_corners": None,  # one far corner, chosen by the pose
    "thirds": [("near_left", "near_right"), ("far_left", "far_right")],
}


def towel(cx=0.45, cy=0.0, depth=0.3, width=0.3, yaw=0.0, z=0.752):
    """Corners of a flat rectangular towel, labelled by the perception rule (as perceived)."""
    hx, hy = depth / 2, width / 2
    c, s = np.cos(yaw), np.sin(yaw)
    local = [(-hx, hy), (-hx, -hy), (hx, -hy), (hx, hy)]
    pts = np.array([[cx + c * x - s * y, cy + s * x + c * y, z] for x, y in local])
    return {name: pts[i] for name, i in label_corners(pts).items()}


def square(cx=0.45, cy=0.0, side=0.3, yaw=0.0, z=0.752):
    """Corners of a flat square towel, labelled by the perception rule."""
    return towel(cx, cy, side, side, yaw, z)


def perceive(outline):
    """Corners the pipeline would perceive on a folded outline (a quad), labelled by the rule."""
    assert outline.shape == (4, 3)
    return {name: outline[i] for name, i in label_corners(outline).items()}


def run_recipe(recipe, corners):
    """Plan every stage, each on the corners of the previous stage's predicted outline."""
    plans, outlines, stage_corners = [], [], []
    for k in range(recipe_stages(recipe)):
        stage_corners.append(corners)
        plans.append(plan_stage(recipe, k, corners))
        outlines.append(predicted_outline(recipe, k, corners))
        if k + 1 < recipe_stages(recipe):
            corners = perceive(outlines[-1])
    return plans, outlines, stage_corners


def area(poly):
    """Signed (counter-clockwise positive) shoelace area of a polygon's x, y."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - y * np.roll(x, -1)))


def quad_area(corners):
    """Area of the labelled corner quad."""
    return area(np.array([corners[n] for n in CORNER_NAMES]))


def unit(v):
    """The x, y of a vector, normalised."""
    v = np.asarray(v, dtype=float)[:2]
    return v / np.linalg.norm(v)


def on_line(point, line, tol=1e-9):
    """Whether a point's x, y lies on the (infinite) fold line."""
    rel = np.asarray(point)[:2] - [line.x, line.y]
    d = unit([line.dx, line.dy])
    return abs(rel[0] * d[1] - rel[1] * d[0]) < tol


def inside_convex(xy, poly, tol=1e-9):
    """Mask of points inside (or on) a counter-clockwise convex polygon."""
    ok = np.ones(len(xy), dtype=bool)
    for a, b in zip(poly[:, :2], np.roll(poly, -1, axis=0)[:, :2], strict=True):
        e = unit(b - a)
        ok &= e[0] * (xy[:, 1] - a[1]) - e[1] * (xy[:, 0] - a[0]) >= -tol
    return ok


def grid_inside(corners, n=30):
    """Flat grid points inside the quad (bilinear; staggered so none lies on a fold line)."""
    nl, nr, fr, fl = (corners[k] for k in CORNER_NAMES)
    u, v = np.meshgrid((np.arange(n) + 0.25) / n, (np.arange(n) + 0.75) / n, indexing="ij")
    u, v = u.reshape(-1, 1), v.reshape(-1, 1)
    return (1 - u) * ((1 - v) * nl + v * nr) + u * ((1 - v) * fl + v * fr)


# --- the half fold (kept from the first recipe) ---------------------------------------------------


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
    assert plan.recipe == "half_y"
    centre = np.mean([c for c in corners.values()], axis=0)
    line = FoldLine.coerce(plan.fold_lines[0])
    # The fold line passes through the cloth centre …
    assert on_line(centre, line)
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


# --- recipes and stages ---------------------------------------------------------------------------


def test_recipe_names_and_stage_counts():
    assert set(RECIPES) == {
        "half",
        "half_y",
        "half_long",
        "quarter",
        "quarter_x",
        "quarter_y",
        "diagonal",
        "diagonal_corners",
        "thirds",
    }
    assert set(RECIPE_HELP) == set(RECIPES)
    assert {r: recipe_stages(r) for r in RECIPES} == {
        "half": 1,
        "half_y": 1,
        "half_long": 1,
        "quarter": 2,
        "quarter_x": 2,
        "quarter_y": 2,
        "diagonal": 1,
        "diagonal_corners": 1,
        "thirds": 2,
    }


@pytest.mark.parametrize("recipe", RECIPES)
def test_plan_recipe_is_the_first_stage(recipe):
    corners = towel(0.4, 0.03, 0.28, 0.32, yaw=0.2)
    first, stage0 = (
        plan_recipe(recipe, corners, place_lift=0.007),
        plan_stage(recipe, 0, corners, 0.007),
    )
    assert first.recipe == stage0.recipe == recipe
    assert first.fold_lines == stage0.fold_lines
    assert [a.as_dict() for a in first.actions] == [a.as_dict() for a in stage0.actions]


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("pose", POSES)
@pytest.mark.parametrize("recipe", RECIPES)
def test_every_stage_is_one_fold_whose_places_mirror_the_grasped_corners(recipe, pose, shape):
    cx, cy, yaw = pose
    plans, _, stage_corners = run_recipe(recipe, towel(cx, cy, *shape, yaw=yaw))
    for k, (plan, corners) in enumerate(zip(plans, stage_corners, strict=True)):
        assert plan.recipe == recipe and len(plan.fold_lines) == 1
        line = FoldLine.coerce(plan.fold_lines[0])
        labels = [a.label for a in plan.actions]
        if STAGE_GRASPS[recipe] == "shape":
            # Depth and width as perceived (labels follow the world frame, not the towel's).
            depth = np.linalg.norm(corners["far_left"] - corners["near_left"])
            width = np.linalg.norm(corners["far_left"] - corners["far_right"])
            deep = depth > 1.1 * width
            assert labels == (["far_left", "near_left"] if deep else ["far_left", "far_right"])
        elif STAGE_GRASPS[recipe] is None:
            assert labels in (["far_left"], ["far_right"])
        else:
            assert tuple(labels) == STAGE_GRASPS[recipe][k]
        for action in plan.actions:
            assert action.fold_line == plan.fold_lines[0]
            assert np.array_equal(action.grasp, corners[action.label])
            assert line.moving_mask(action.grasp[None, :2])[0]  # moving side: left of direction
            assert np.allclose(action.place[:2], line.reflect_xy(action.grasp[None, :2])[0])
            assert action.place[2] == pytest.approx(action.grasp[2] + 0.004)
        # The corners not grasped stay (or lie on the line, for the diagonal).
        for name in set(CORNER_NAMES) - set(labels):
            assert line.side(corners[name][None, :2])[0] < 1e-9
        # The line's point and point + direction are where the crease meets the outline.
        quad = np.array([corners[n][:2] for n in CORNER_NAMES])
        ends = np.array([[line.x, line.y], [line.x + line.dx, line.y + line.dy]])
        assert inside_convex(ends, quad, tol=1e-9).all()


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("pose", POSES)
def test_half_lines_join_the_midpoints_of_the_bent_sides(pose, shape):
    cx, cy, yaw = pose
    c = towel(cx, cy, *shape, yaw=yaw)
    line_x = FoldLine.coerce(plan_recipe("half", c).fold_lines[0])
    line_y = FoldLine.coerce(plan_recipe("half_y", c).fold_lines[0])
    for a, b in (("near_left", "far_left"), ("near_right", "far_right")):
        assert on_line((c[a] + c[b]) / 2, line_x)
    for a, b in (("near_left", "near_right"), ("far_left", "far_right")):
        assert on_line((c[a] + c[b]) / 2, line_y)
    # The far side moves for "half", the left side for "half_y".
    assert line_x.moving_mask(np.array([c["far_left"][:2], c["far_right"][:2]])).all()
    assert line_y.moving_mask(np.array([c["far_left"][:2], c["near_left"][:2]])).all()


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("pose", POSES)
def test_quarter_second_line_is_perpendicular_through_the_folded_centre(pose, shape):
    cx, cy, yaw = pose
    plans, outlines, stage_corners = run_recipe("quarter", towel(cx, cy, *shape, yaw=yaw))
    first, second = (FoldLine.coerce(p.fold_lines[0]) for p in plans)
    assert abs(unit([first.dx, first.dy]) @ unit([second.dx, second.dy])) < 1e-9
    folded_centre = np.mean(list(stage_corners[1].values()), axis=0)
    assert on_line(folded_centre, second)
    # The folded rectangle is the near half: the second stage grasps its stacked near corner.
    assert np.allclose(stage_corners[1]["near_left"], stage_corners[0]["near_left"])
    assert area(outlines[1]) == pytest.approx(quad_area(stage_corners[0]) / 4)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("pose", POSES)
def test_quarter_y_folds_quarters_lines_the_other_way_round(pose, shape):
    """The same two folds as quarter, left onto right first; its second stage carries the stack's
    far corners, one each side of the folded rectangle's centre line (one per arm)."""
    cx, cy, yaw = pose
    flat = towel(cx, cy, *shape, yaw=yaw)
    plans, outlines, stage_corners = run_recipe("quarter_y", flat)
    first, second = (FoldLine.coerce(p.fold_lines[0]) for p in plans)
    assert abs(unit([first.dx, first.dy]) @ unit([second.dx, second.dy])) < 1e-9
    assert on_line((flat["far_left"] + flat["far_right"]) / 2, first)
    assert on_line(np.mean(list(stage_corners[1].values()), axis=0), second)
    carried = [a.grasp for a in plans[1].actions]
    assert [a.label for a in plans[1].actions] == ["far_left", "far_right"]
    # Half the far edge apart: the folded rectangle's far edge.
    far_edge = float(np.linalg.norm((flat["far_left"] - flat["far_right"])[:2]))
    assert float(np.linalg.norm((carried[0] - carried[1])[:2])) == pytest.approx(far_edge / 2)
    assert area(outlines[1]) == pytest.approx(quad_area(stage_corners[0]) / 4)
    # Both orders end on the same quarter of the towel: the near-right one.
    _, quarter_outlines, _ = run_recipe("quarter", flat)
    centre = np.mean(np.asarray(outlines[1])[:, :2], axis=0)
    assert centre == pytest.approx(
        np.mean(np.asarray(quarter_outlines[1])[:, :2], axis=0), abs=1e-6
    )


def test_quarter_is_folded_as_quarter_y_and_only_the_quarters_second_stages_are_stacks():
    assert folded_as("quarter") == "quarter_y"
    for recipe in RECIPES:
        if recipe != "quarter":
            assert folded_as(recipe) == recipe
    stacks = {(r, k) for r in RECIPES for k in range(recipe_stages(r)) if carries_stack(r, k)}
    assert stacks == {("quarter", 1), ("quarter_x", 1), ("quarter_y", 1)}


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("pose", POSES)
def test_quarter_x_is_quarters_own_order_planned_as_written(pose, shape):
    """quarter_x, the order `folded_as` does not pick for quarter, plans quarter's stages as its
    docstring states them: the same lines, grasps and places, stage by stage."""
    cx, cy, yaw = pose
    flat = towel(cx, cy, *shape, yaw=yaw)
    plans_x, outlines_x, _ = run_recipe("quarter_x", flat)
    plans_q, outlines_q, _ = run_recipe("quarter", flat)
    for px, pq in zip(plans_x, plans_q, strict=True):
        np.testing.assert_allclose(px.fold_lines, pq.fold_lines)
        for ax, aq in zip(px.actions, pq.actions, strict=True):
            assert ax.label == aq.label
            np.testing.assert_allclose(ax.grasp, aq.grasp)
            np.testing.assert_allclose(ax.place, aq.place)
    np.testing.assert_allclose(outlines_x[1], outlines_q[1])
    with pytest.raises(ConfigError, match=r"'origami'.*allowed: half"):
        folded_as("origami")


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("pose", POSES)
def test_thirds_lines_lie_a_third_from_the_near_then_the_far_edge(pose, shape):
    cx, cy, yaw = pose
    flat = towel(cx, cy, *shape, yaw=yaw)
    plans, _, stage_corners = run_recipe("thirds", flat)
    depth_axis = unit(flat["far_left"] - flat["near_left"])
    depth = float((flat["far_left"] - flat["near_left"])[:2] @ depth_axis)
    near = flat["near_left"][:2]
    for plan, fraction in zip(plans, (1 / 3, 2 / 3), strict=True):
        line = FoldLine.coerce(plan.fold_lines[0])
        # Parallel to the near edge, at `fraction` of the original depth from it.
        assert abs(unit([line.dx, line.dy]) @ depth_axis) < 1e-9
        assert (np.array([line.x, line.y]) - near) @ depth_axis == pytest.approx(fraction * depth)
    # After stage 1 the perceived outline spans 2/3 of the depth, up to the original far edge.
    c1 = stage_corners[1]
    assert np.allclose(c1["far_left"], flat["far_left"])
    assert (c1["far_left"] - c1["near_left"])[:2] @ depth_axis == pytest.approx(2 / 3 * depth)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("pose", POSES[:3])
def test_thirds_second_line_leaves_crease_room_past_the_laid_third(pose, shape):
    """Stage 2's line lies on the laid near third's free edge; the crease room moves it that far
    toward the far edge (its moving side), so the far corners land twice the room short of the
    stack's crease corners, and the predicted outline and cover move with it."""
    cx, cy, yaw = pose
    flat = towel(cx, cy, *shape, yaw=yaw)
    stack = perceive(predicted_outline("thirds", 0, flat))
    room = 0.012
    plain, roomy = plan_stage("thirds", 1, stack), plan_stage("thirds", 1, stack, crease_room=room)
    a, b = FoldLine.coerce(plain.fold_lines[0]), FoldLine.coerce(roomy.fold_lines[0])
    assert abs(unit([a.dx, a.dy]) @ unit([-b.dy, b.dx])) < 1e-9  # parallel
    # b lies `room` onto a's moving side (normalised side() is the signed distance).
    assert a.side(np.array([[b.x, b.y, 0.0]]))[0] / np.hypot(a.dx, a.dy) == pytest.approx(room)
    for p, q in zip(plain.actions, roomy.actions, strict=True):
        assert p.label == q.label and np.allclose(p.grasp, q.grasp)
        assert np.linalg.norm((q.place - p.place)[:2]) == pytest.approx(2 * room)
        assert b.side(q.place[None])[0] < 0 < b.side(q.grasp[None])[0]
    laid = predicted_cover("thirds", 1, stack, crease_room=room)
    assert area(laid) == pytest.approx(area(predicted_cover("thirds", 1, stack)) - room * shape[1])
    # The staying part, which the laid far third lies on, is `room` deeper.
    assert area(predicted_outline("thirds", 1, stack, crease_room=room)) == pytest.approx(
        area(predicted_outline("thirds", 1, stack)) + room * shape[1]
    )
    # Stages whose line lies along no laid edge take no room.
    for recipe, stage, corners in (("thirds", 0, flat), ("half", 0, flat), ("quarter", 1, stack)):
        roomy, plain = (plan_stage(recipe, stage, corners, crease_room=r) for r in (room, 0.0))
        assert roomy.fold_lines == plain.fold_lines
        assert all(
            np.allclose(p.place, q.place) for p, q in zip(plain.actions, roomy.actions, strict=True)
        )


@pytest.mark.parametrize("pose", POSES)
def test_corner_diagonal_runs_through_opposite_corners_and_brings_a_far_corner_closer(pose):
    cx, cy, yaw = pose
    c = square(cx, cy, 0.3, yaw=yaw)
    plan = plan_recipe("diagonal_corners", c)
    line = FoldLine.coerce(plan.fold_lines[0])
    (action,) = plan.actions
    pivots = (
        ("near_left", "far_right") if action.label == "far_left" else ("near_right", "far_left")
    )
    opposite = "near_right" if action.label == "far_left" else "near_left"
    assert all(on_line(c[p], line) for p in pivots)
    assert np.allclose(action.place[:2], c[opposite][:2], atol=1e-9)  # a square: onto the corner
    # Of the two diagonals, the carried corner moves most toward the robot (−x).
    other = "far_right" if action.label == "far_left" else "far_left"
    other_target = "near_left" if other == "far_right" else "near_right"
    moved = action.place[0] - action.grasp[0]
    assert moved < 0
    assert moved <= c[other_target][0] - c[other][0] + 1e-12


@pytest.mark.parametrize("recipe", ["diagonal", "diagonal_corners"])
def test_diagonal_tie_carries_far_left(recipe):
    plan = plan_recipe(recipe, square(yaw=0.0))
    assert [a.label for a in plan.actions] == ["far_left"]
    assert on_line(square()["near_left"], FoldLine.coerce(plan.fold_lines[0]))


@pytest.mark.parametrize("pose", POSES)
def test_on_a_square_the_triangle_fold_is_the_corner_diagonal(pose):
    cx, cy, yaw = pose
    c = square(cx, cy, 0.3, yaw=yaw)
    tri, diag = plan_recipe("diagonal", c), plan_recipe("diagonal_corners", c)
    (a,), (b,) = tri.actions, diag.actions
    assert a.label == b.label
    assert np.allclose(a.place, b.place, atol=1e-9)
    line = FoldLine.coerce(tri.fold_lines[0])
    other = FoldLine.coerce(diag.fold_lines[0])
    ends = ([other.x, other.y], [other.x + other.dx, other.y + other.dy])
    assert all(on_line(end, line) for end in ends)


@pytest.mark.parametrize("shape", SHAPES[1:])
@pytest.mark.parametrize("pose", POSES)
def test_the_triangle_fold_lays_a_far_corner_on_the_cloth_at_45_degrees(pose, shape):
    cx, cy, yaw = pose
    c = towel(cx, cy, *shape, yaw=yaw)
    plan = plan_recipe("diagonal", c)
    line = FoldLine.coerce(plan.fold_lines[0])
    (action,) = plan.actions
    quad = np.array([c[n] for n in CORNER_NAMES])
    # The pivot is the carried corner's neighbour along the towel's shorter side, on the line.
    k = CORNER_NAMES.index(action.label)
    neighbours = [CORNER_NAMES[(k + 1) % 4], CORNER_NAMES[(k - 1) % 4]]
    pivot = min(neighbours, key=lambda n: np.linalg.norm(c[n] - c[action.label]))
    assert on_line(c[pivot], line)
    short = min(shape)
    assert np.linalg.norm(c[pivot] - c[action.label]) == pytest.approx(short)
    # The crease runs at 45° to the towel's sides, and the corner lands on the cloth, on the
    # pivot's other side at the short side's length from it: no overhang.
    side = unit(c[action.label] - c[pivot])
    assert abs(unit([line.dx, line.dy]) @ side) == pytest.approx(np.sqrt(0.5))
    assert inside_convex(action.place[None, :2], quad, tol=1e-9)[0]
    assert np.linalg.norm(action.place[:2] - c[pivot][:2]) == pytest.approx(short)
    # Of the allowed folds, the carried corner comes toward the robot, by the short side.
    moved = action.place[:2] - action.grasp[:2]
    assert moved[0] < 0
    assert np.linalg.norm(moved) == pytest.approx(np.sqrt(2) * short)


# --- composed goals and predicted outlines -------------------------------------------------------

EXPECTED_LAYERS = {
    "half": {0: 1 / 2, 1: 1 / 2},
    "half_y": {0: 1 / 2, 1: 1 / 2},
    "half_long": {0: 1 / 2, 1: 1 / 2},
    "quarter": {0: 1 / 4, 1: 1 / 4, 2: 1 / 4, 3: 1 / 4},
    "quarter_x": {0: 1 / 4, 1: 1 / 4, 2: 1 / 4, 3: 1 / 4},
    "quarter_y": {0: 1 / 4, 1: 1 / 4, 2: 1 / 4, 3: 1 / 4},
    # metrics' rule 2·n_max + 1 − n puts the far third (layer 0 before) at index 3: three layers.
    "thirds": {0: 1 / 3, 1: 1 / 3, 3: 1 / 3},
    "diagonal": {0: 1 / 2, 1: 1 / 2},
    "diagonal_corners": {0: 1 / 2, 1: 1 / 2},
}
EXPECTED_AREA = {
    "half": 1 / 2,
    "half_y": 1 / 2,
    "half_long": 1 / 2,
    "quarter": 1 / 4,
    "quarter_x": 1 / 4,
    "quarter_y": 1 / 4,
    "thirds": 1 / 3,
    "diagonal": 1 / 2,
    "diagonal_corners": 1 / 2,
}


# A corner-diagonal fold of a non-square towel overhangs: see the union test below; a triangle
# fold of one lays a triangle of side² / 2 of its area on layer 1 (expected_layers).
COMPOSE_CASES = [
    (recipe, pose, shape)
    for recipe in RECIPES
    for pose in POSES
    for shape in SHAPES
    if recipe != "diagonal_corners" or shape[0] == shape[1]
]


def expected_layers(recipe, shape):
    """Area fraction of each goal layer, and the final outline's fraction of the flat area."""
    if recipe == "diagonal":
        laid = min(shape) / (2 * max(shape))  # the triangle: side² / 2 of side × long side
        return {0: 1 - laid, 1: laid}, 1 - laid
    return EXPECTED_LAYERS[recipe], EXPECTED_AREA[recipe]


@pytest.mark.parametrize(("recipe", "pose", "shape"), COMPOSE_CASES)
def test_composed_goal_has_the_expected_layers_inside_the_predicted_outline(recipe, pose, shape):
    cx, cy, yaw = pose
    flat = towel(cx, cy, *shape, yaw=yaw)
    plans, outlines, _ = run_recipe(recipe, flat)
    points = grid_inside(flat)
    lines = [p.fold_lines[0] for p in plans]
    goal, layers = fold_goal(points, lines, thickness=0.002)
    values, counts = np.unique(layers, return_counts=True)
    expected, expected_area = expected_layers(recipe, shape)
    assert set(values.tolist()) == set(expected)
    tol = 1.5 / 30  # one grid row of the staggered grid (the diagonal cuts it unevenly)
    for v, n in zip(values, counts, strict=True):
        assert n / len(points) == pytest.approx(expected[int(v)], abs=tol)
    final = outlines[-1]
    assert area(final) > 0  # counter-clockwise
    assert area(final) == pytest.approx(expected_area * quad_area(flat), rel=1e-9)
    assert inside_convex(goal[:, :2], final).all()
    assert final[:, 2] == pytest.approx(flat["near_left"][2])


@pytest.mark.parametrize("pose", POSES[:3])
def test_corner_diagonal_outline_of_a_rectangle_is_the_union_of_the_two_triangles(pose):
    cx, cy, yaw = pose
    flat = towel(cx, cy, 0.24, 0.36, yaw=yaw)
    plan = plan_recipe("diagonal_corners", flat)
    line = FoldLine.coerce(plan.fold_lines[0])
    outline = predicted_outline("diagonal_corners", 0, flat)
    quad = np.array([flat[n] for n in CORNER_NAMES])
    staying = quad[line.side(quad) < 1e-9]  # the two pivots and the staying corner
    carried = quad[line.side(quad) > 1e-9]
    mirrored = np.vstack([staying[np.abs(line.side(staying)) < 1e-9], line.reflect_xy(carried)])

    def ccw(tri):
        """The triangle in counter-clockwise order."""
        return tri if area(tri) > 0 else tri[::-1]

    lo, hi = quad[:, :2].min(axis=0) - 0.1, quad[:, :2].max(axis=0) + 0.1
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 400), np.linspace(lo[1], hi[1], 400))
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    in_union = inside_convex(xy, ccw(staying)) | inside_convex(xy, ccw(mirrored))
    cell = (hi[0] - lo[0]) / 399 * (hi[1] - lo[1]) / 399
    assert area(outline) == pytest.approx(in_union.sum() * cell, rel=0.02)
    assert area(ccw(staying)) < area(outline) < quad_area(flat)
    assert len(outline) == 5  # the overhanging tip adds two corners to the triangle


@pytest.mark.parametrize("pose", POSES[:3])
def test_the_cover_of_a_half_fold_is_the_staying_half_less_the_crease_band(pose):
    cx, cy, yaw = pose
    flat = towel(cx, cy, 0.3, 0.24, yaw=yaw)
    line = FoldLine.coerce(plan_recipe("half", flat).fold_lines[0])
    quad = np.array([flat[n] for n in CORNER_NAMES])
    cover = predicted_cover("half", 0, flat)
    assert area(cover) == pytest.approx(quad_area(flat) / 2, rel=1e-6)
    assert np.all(line.side(cover) <= 1e-9)  # on the staying side
    banded = predicted_cover("half", 0, flat, crease_band=0.02)
    assert area(banded) == pytest.approx(quad_area(flat) / 2 - 0.02 * 0.24, rel=1e-6)
    assert np.all(line.side(banded) / np.hypot(line.dx, line.dy) <= -0.02 + 1e-9)
    assert cover[:, 2] == pytest.approx(np.full(len(cover), quad[:, 2].mean()))
    # A band wider than the region leaves nothing to cover.
    assert predicted_cover("half", 0, flat, crease_band=0.5).shape == (0, 3)


# --- bad inputs ------------------------------------------------------------------------------------


def test_bad_inputs_are_rejected_with_the_reason():
    good = square()
    missing = dict(good)
    del missing["near_right"], missing["far_left"]
    with pytest.raises(ConfigError, match=r"near_right.*far_left"):
        plan_stage("quarter", 0, missing)
    with pytest.raises(ConfigError, match="missing"):
        predicted_outline("half", 0, missing)
    coincident = dict(good, near_right=good["near_left"].copy())
    with pytest.raises(ConfigError, match="degenerate"):
        plan_stage("half", 0, coincident)
    collinear = dict(good, near_right=(good["near_left"] + good["far_right"]) / 2)
    with pytest.raises(ConfigError, match="collinear"):
        plan_stage("diagonal", 0, collinear)
    swapped = dict(good, near_left=good["near_right"], near_right=good["near_left"])
    with pytest.raises(ConfigError, match="counter-clockwise"):
        plan_stage("half", 0, swapped)
    with pytest.raises(ConfigError, match="finite"):
        plan_stage("half", 0, dict(good, far_right=np.array([np.nan, 0.0, 0.75])))
    with pytest.raises(ConfigError, match="finite"):
        plan_stage("half", 0, dict(good, far_right=np.array([0.5, 0.0])))
    with pytest.raises(
        ConfigError,
        match=r"origami.*half, half_y, half_long, quarter, quarter_x, quarter_y, diagonal, "
        r"diagonal_corners, thirds",
    ):
        plan_stage("origami", 0, good)
    with pytest.raises(ConfigError, match="origami"):
        recipe_stages("origami")
    with pytest.raises(ConfigError, match="origami"):
        predicted_outline("origami", 0, good)
    for recipe, stage in (("half", 1), ("quarter", 2), ("thirds", -1), ("diagonal", 5)):
        with pytest.raises(ConfigError, match="out of range"):
            plan_stage(recipe, stage, good)
        with pytest.raises(ConfigError, match="out of range"):
            predicted_outline(recipe, stage, good)
    with pytest.raises(ConfigError, match="integer"):
        plan_stage("quarter", 1.0, good)
    for room in (-0.001, 0.2, float("nan"), True, "1cm"):
        with pytest.raises(ConfigError, match=r"crease_room = .* must be a number in \[0, 0.05\]"):
            plan_stage("thirds", 1, good, crease_room=room)
        with pytest.raises(ConfigError, match="crease_room"):
            predicted_cover("thirds", 1, good, crease_room=room)


def test_planning_never_imports_the_simulator():
    tree = ast.parse(inspect.getsource(recipes_module))
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add(node.module or "")
    assert not any(m.startswith(("pybullet", "foldbot.sim")) for m in imported)


@pytest.mark.parametrize(
    ("width_x", "width_y", "expected_moving"),
    [
        (0.40, 0.27, {"far_left", "near_left"}),  # deep and narrow: fold left onto right
        (0.27, 0.40, {"far_left", "far_right"}),  # wide: far half onto the near half
        (0.30, 0.30, {"far_left", "far_right"}),  # square: the `half` axis
        (0.315, 0.30, {"far_left", "far_right"}),  # within the 10 % margin: still `half`
    ],
)
def test_half_long_carries_the_far_apart_corners(width_x, width_y, expected_moving):
    hx, hy = width_x / 2, width_y / 2
    corners = {
        "near_left": np.array([0.45 - hx, hy, 0.752]),
        "near_right": np.array([0.45 - hx, -hy, 0.752]),
        "far_right": np.array([0.45 + hx, -hy, 0.752]),
        "far_left": np.array([0.45 + hx, hy, 0.752]),
    }
    from foldbot.planning.recipes import plan_stage

    plan = plan_stage("half_long", 0, corners)
    assert {a.label for a in plan.actions} == expected_moving
    # The carried pair: along the longer side, unless within the margin (then `half`'s far edge).
    a, b = (a.grasp for a in plan.actions)
    expected = width_x if width_x > 1.1 * width_y else width_y
    assert np.linalg.norm(a - b) == pytest.approx(expected)


def test_stage_grasp_layers_reach_the_actions(monkeypatch):
    for recipe in RECIPES:  # none is marked yet: every grasp holds the top layer
        plans, _, _ = run_recipe(recipe, towel(depth=0.36, width=0.3))
        assert all(a.layers == 1 for plan in plans for a in plan.actions)
    monkeypatch.setitem(recipes_module._GRASP_LAYERS, ("quarter", 1), 2)
    plans, _, _ = run_recipe("quarter", towel(depth=0.36, width=0.3))
    assert [a.layers for a in plans[0].actions] == [1, 1]
    assert [a.layers for a in plans[1].actions] == [2, 2]


def test_a_corner_is_released_above_a_thicker_stack_at_its_place():
    """Thirds, second stage: the far third's single-layer corners land on the crease ends of the
    first fold, which stand higher: each is released above the higher of the two."""
    c = towel(depth=0.36, width=0.3)
    outline = predicted_outline("thirds", 0, c)
    corners = perceive(outline)
    base = corners["far_left"][2]
    for name in ("near_left", "near_right"):  # the first stage's crease ends: two layers
        corners[name] = corners[name] + [0.0, 0.0, 0.012]
    plan = plan_stage("thirds", 1, corners, place_lift=0.004)
    for action in plan.actions:
        assert action.label.startswith("far_")
        assert corners[action.label][2] == pytest.approx(base)
        assert action.place[2] == pytest.approx(base + 0.012 + 0.004)


@pytest.mark.parametrize("recipe", RECIPES)
@pytest.mark.parametrize("pose", POSES[:3])
@pytest.mark.parametrize("shape", SHAPES)
def test_a_recipes_fold_lines_from_one_set_of_corners_are_its_stages_lines(recipe, pose, shape):
    """The goal's lines: each stage planned on the outline the earlier ones predict, in the
    order the cells fold the recipe, as a cell that perceived each outline exactly would."""
    cx, cy, yaw = pose
    flat = towel(cx, cy, *shape, yaw=yaw)
    plans, _, _ = run_recipe(folded_as(recipe), flat)
    lines = recipe_fold_lines(recipe, flat)
    assert len(lines) == recipe_stages(recipe)
    for line, plan in zip(lines, plans, strict=True):
        np.testing.assert_allclose(line, plan.fold_lines[0], atol=1e-12)


def test_a_recipes_fold_lines_on_an_uneven_quad_take_the_outlines_four_corners():
    """A towel's true corners are no exact rectangle: the folded outline's mirrored corners then
    lie just off its sides, and the next stage is planned on its largest quad."""
    flat = towel(0.45, 0.02, 0.36, 0.3, yaw=0.2)
    flat["near_left"] = flat["near_left"] + np.array([0.004, -0.003, 0.0])
    assert len(predicted_outline("thirds", 0, flat)) > 4
    first, second = recipe_fold_lines("thirds", flat)
    np.testing.assert_allclose(first, plan_stage("thirds", 0, flat).fold_lines[0])
    # The far third's line: halfway across what stage 1 left, about 2/3 of the depth from the
    # near edge, parallel to it within the skew.
    near_mid = (flat["near_left"] + flat["near_right"]) / 2
    far_mid = (flat["far_left"] + flat["far_right"]) / 2
    depth = np.linalg.norm((far_mid - near_mid)[:2])
    line = FoldLine(*second)
    offset = line.side(near_mid[None, :])[0] / np.hypot(line.dx, line.dy)
    assert abs(offset) == pytest.approx(2 * depth / 3, abs=0.005)


def test_a_recipes_fold_lines_refuse_bad_corners():
    with pytest.raises(ConfigError, match="missing"):
        recipe_fold_lines("half", {"near_left": np.zeros(3)})
    with pytest.raises(ConfigError, match="unknown recipe 'pleat'"):
        recipe_fold_lines("pleat", towel())
