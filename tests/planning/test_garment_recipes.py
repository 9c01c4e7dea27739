"""Garment recipes on known keypoints: fold lines, moving sides, grasps and places."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.metrics import FoldLine
from foldbot.planning.garment_recipes import (
    PANTS_KEYPOINTS,
    TSHIRT_KEYPOINTS,
    GarmentPlan,
    fold_outline,
    plan_garment,
    recipe_keypoints,
)
from foldbot.planning.recipes import _signed_area

Z = 0.752

# A child's T-shirt in its own frame (u right, v up from the hem's middle), metres.
TSHIRT_UV = {
    "neck": (0.0, 0.36),
    "left_shoulder": (-0.12, 0.40),
    "right_shoulder": (0.12, 0.40),
    "left_sleeve": (-0.27, 0.30),
    "right_sleeve": (0.27, 0.30),
    "left_armpit": (-0.16, 0.27),
    "right_armpit": (0.16, 0.27),
    "left_hem": (-0.16, 0.0),
    "right_hem": (0.16, 0.0),
}
PANTS_UV = {
    "left_waist": (-0.14, 0.50),
    "right_waist": (0.14, 0.50),
    "left_leg_outer": (-0.15, 0.0),
    "left_leg_inner": (-0.03, 0.0),
    "right_leg_outer": (0.15, 0.0),
    "right_leg_inner": (0.03, 0.0),
    "crotch": (0.0, 0.30),
}


def placed(uv: dict, yaw: float, origin=(0.45, 0.0)) -> dict[str, np.ndarray]:
    """World keypoints of a garment whose up axis (v) points along world angle `yaw` + 90°."""
    up = np.array([math.cos(yaw + math.pi / 2), math.sin(yaw + math.pi / 2)])
    right = np.array([up[1], -up[0]])
    return {n: np.array([*(np.add(origin, u * right + v * up)), Z]) for n, (u, v) in uv.items()}


@pytest.mark.parametrize("yaw", [math.pi / 2, math.pi / 2 + 0.2, -0.3])
def test_tshirt_retail_stages(yaw):
    kp = placed(TSHIRT_UV, yaw)
    plan = plan_garment("retail", kp, place_lift=0.004, thickness=0.006)
    assert plan.recipe == "retail"
    assert [len(s.actions) for s in plan.stages] == [2, 2, 2]
    s1, s2, s3 = plan.stages
    assert [a.label for a in s1.actions] == ["left_sleeve", "left_hem"]
    assert [a.label for a in s2.actions] == ["right_sleeve", "right_hem"]
    for stage, side in ((s1, "left"), (s2, "right")):
        line = FoldLine(*stage.fold_line)
        for a in stage.actions:
            assert line.moving_mask(a.grasp[None, :2])[0], a.label
            assert np.allclose(a.place[:2], line.reflect_xy(a.grasp)[:2])
            assert a.place[2] == pytest.approx(a.grasp[2] + 0.004)
        # Nothing on the other side of the body moves.
        other = "right" if side == "left" else "left"
        assert not line.moving_mask(kp[f"{other}_hem"][None, :2])[0]
        assert not line.moving_mask(kp["neck"][None, :2])[0]
    # The folded sleeve stays short of the other side's line.
    assert not FoldLine(*s2.fold_line).moving_mask(s1.actions[0].place[None, :2])[0]
    # Hem up: the hems move, the shoulders stay; carried from the tip, planned mid-hem on top.
    assert [a.label for a in s3.actions] == ["hem", "hem_rest"] and s3.from_tip
    assert not any(s.top_first for s in plan.stages)  # hem up from the tip: it folded better so
    hem_up = FoldLine(*s3.fold_line)
    assert hem_up.moving_mask(np.array([kp["left_hem"][:2], kp["right_hem"][:2]])).all()
    assert not hem_up.moving_mask(np.array([kp["left_shoulder"][:2]]))[0]
    assert all(a.grasp[2] == pytest.approx(Z + 0.006) for a in s3.actions)
    # The hem-up line is perpendicular to the side lines.
    d1, d3 = np.array(s1.fold_line[2:]), np.array(s3.fold_line[2:])
    assert abs(d1 @ d3) < 1e-9 * np.linalg.norm(d1) * np.linalg.norm(d3) + 1e-12


def _turned(xyz, yaw: float, centre=(0.45, 0.0), shift=(0.0, 0.0)) -> np.ndarray:
    """A point (x, y, z) turned by `yaw` about `centre` in the table's plane, then moved by
    `shift` (m); z kept."""
    c, s, o = math.cos(yaw), math.sin(yaw), np.asarray(centre)
    x, y = np.asarray(xyz, float)[:2] - o
    return np.array([*(o + np.array([c * x - s * y, s * x + c * y]) + shift), xyz[2]])


@pytest.mark.parametrize(("recipe", "uv"), [("retail", TSHIRT_UV), ("leg_over_leg", PANTS_UV)])
def test_plan_is_rotation_equivariant(recipe, uv):
    """The garment turned by 0.4 rad about where it lies (and then moved 5 cm in x, 10 cm in y): every grasp,
    place and fold line is the unturned plan's, turned (and moved) alike."""
    yaw, shift = 0.4, np.array([-0.05, 0.1])
    base = plan_garment(recipe, placed(uv, 0.0), place_lift=0.004, thickness=0.006)
    for origin, moved in (((0.45, 0.0), (0.0, 0.0)), ((0.40, 0.1), shift)):
        plan = plan_garment(recipe, placed(uv, yaw, origin), place_lift=0.004, thickness=0.006)
        assert [len(s.actions) for s in plan.stages] == [len(s.actions) for s in base.stages]
        for sa, sb in zip(base.stages, plan.stages, strict=True):
            assert (sb.from_tip, sb.top_first) == (sa.from_tip, sa.top_first)
            for x, y in zip(sa.actions, sb.actions, strict=True):
                assert y.label == x.label
                np.testing.assert_allclose(y.grasp, _turned(x.grasp, yaw, shift=moved), atol=1e-9)
                np.testing.assert_allclose(y.place, _turned(x.place, yaw, shift=moved), atol=1e-9)
            # The fold line: its point turned (and moved), its direction turned.
            point = _turned([*sa.fold_line[:2], 0.0], yaw, shift=moved)[:2]
            direction = _turned([*sa.fold_line[2:], 0.0], yaw, centre=(0.0, 0.0))[:2]
            np.testing.assert_allclose(sb.fold_line, [*point, *direction], atol=1e-9)


def test_pants_leg_over_leg():
    kp = placed(PANTS_UV, math.pi / 2 + 0.1)
    plan = plan_garment("leg_over_leg", kp, place_lift=0.0, thickness=0.005)
    s1, s2 = plan.stages
    assert [a.label for a in s1.actions] == ["left_waist", "left_leg"]
    assert not s1.from_tip and s2.from_tip
    assert s2.top_first and not s1.top_first  # the left leg, laid on the right one, goes first
    # Symmetric pants: the left waist corner lands on the right one.
    assert np.allclose(s1.actions[0].place[:2], kp["right_waist"][:2], atol=1e-9)
    line = FoldLine(*s1.fold_line)
    assert line.moving_mask(np.array([kp["left_leg_outer"][:2], kp["left_waist"][:2]])).all()
    assert not line.moving_mask(np.array([kp["right_leg_outer"][:2]]))[0]
    # In half: carried from the tip of the leg stack, planned at its hem's middle, on top.
    assert [a.label for a in s2.actions] == ["legs", "legs_rest"]
    hem_mid = (kp["right_leg_outer"] + kp["right_leg_inner"]) / 2
    stack = s2.actions[0].grasp
    assert np.linalg.norm(stack[:2] - hem_mid[:2]) == pytest.approx(0.01)
    assert stack[2] == pytest.approx(Z + 0.005)
    half = FoldLine(*s2.fold_line)
    assert half.moving_mask(stack[None, :2])[0]
    assert not half.moving_mask(kp["right_waist"][None, :2])[0]


@pytest.mark.parametrize(
    ("recipe", "uv", "unplanned"),
    [
        ("retail", "tshirt", ("neck", "left_armpit", "right_armpit")),
        ("leg_over_leg", "pants", ("crotch",)),
    ],
)
def test_keypoints_no_fold_is_planned_from_may_be_missing(recipe, uv, unplanned) -> None:
    """The neck, armpits and crotch recognise a garment; no line or grasp is computed from them,
    so a garment whose neck the parked arm hides is planned all the same, and alike."""
    kp = placed(TSHIRT_UV if uv == "tshirt" else PANTS_UV, 0.3)
    assert set(recipe_keypoints(recipe)) == set(kp) - set(unplanned)
    fewer = {n: p for n, p in kp.items() if n not in unplanned}
    assert plan_garment(recipe, fewer).as_dict() == plan_garment(recipe, kp).as_dict()


def test_missing_and_degenerate_keypoints_are_named():
    kp = placed(TSHIRT_UV, 0.0)
    del kp["left_sleeve"]
    with pytest.raises(ConfigError, match="left_sleeve"):
        plan_garment("retail", kp)
    swapped = placed(TSHIRT_UV, 0.0)
    swapped["left_hem"], swapped["right_hem"] = swapped["right_hem"], swapped["left_hem"]
    with pytest.raises(ConfigError, match="left_hem is not left of right_hem"):
        plan_garment("retail", swapped)
    bad = placed(PANTS_UV, 0.0)
    bad["left_leg_inner"] = np.array([np.nan, 0.0, Z])
    with pytest.raises(ConfigError, match="left_leg_inner"):
        plan_garment("leg_over_leg", bad)
    with pytest.raises(ConfigError, match="unknown garment recipe 'half'"):
        plan_garment("half", kp)
    with pytest.raises(ConfigError, match="place_lift"):
        plan_garment("retail", placed(TSHIRT_UV, 0.0), place_lift=-1.0)


def test_keypoint_name_lists_match_the_plans():
    assert set(TSHIRT_UV) == set(TSHIRT_KEYPOINTS)
    assert set(PANTS_UV) == set(PANTS_KEYPOINTS)


def test_fold_outline_halves_a_square():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    parts = fold_outline([square], (0.0, 0.5, 1.0, 0.0))  # moving side: y > 0.5
    assert len(parts) == 2
    areas = sorted(abs(_signed_area(p)) for p in parts)
    assert areas == pytest.approx([0.5, 0.5])
    for p in parts:  # both halves now lie on y ≤ 0.5
        assert p[:, 1].max() <= 0.5 + 1e-12
    # A line missing the polygon leaves it whole.
    (whole,) = fold_outline([square], (0.0, 2.0, 1.0, 0.0))
    assert abs(_signed_area(whole)) == pytest.approx(1.0)


@pytest.mark.parametrize(("recipe", "uv"), [("retail", TSHIRT_UV), ("leg_over_leg", PANTS_UV)])
def test_plan_survives_its_json_form(recipe, uv):
    """The ROS planner node sends a garment plan as JSON: every stage, line and action field
    (layers, from_tip and top_first included) comes back as it was."""
    import json

    plan = plan_garment(recipe, placed(uv, math.pi / 2 + 0.1), place_lift=0.004, thickness=0.01)
    again = GarmentPlan.from_dict(json.loads(json.dumps(plan.as_dict())))
    assert again.recipe == plan.recipe and again.fold_lines == plan.fold_lines
    for a, b in zip(plan.stages, again.stages, strict=True):
        assert a.from_tip == b.from_tip and a.top_first == b.top_first
        assert [x.as_dict() for x in a.actions] == [x.as_dict() for x in b.actions]
