"""Perception scenes: drawn reproducibly and within their ranges, the arm's pose and a wider
range changing nothing else; a towel mesh folded in half before settling."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.garments.towel import TowelSpec
from foldbot.sim.layout import DEFAULT_LAYOUT
from foldbot.sim.perception_scenes import folded_towel, sample_garment_scene, sample_scene


def test_scene_sampling_is_reproducible_and_in_range() -> None:
    a = [sample_scene(np.random.default_rng([5, i]), i, 0.3, 0.4) for i in range(30)]
    b = [sample_scene(np.random.default_rng([5, i]), i, 0.3, 0.4) for i in range(30)]
    assert a == b
    for s in a:
        assert 0.2 <= s.towel_width <= 0.45 and 0.2 <= s.towel_height <= 0.45
        assert 0.15 <= s.x <= 0.75 and -0.3 <= s.y <= 0.3
    assert {s.state for s in a} == {"flat", "folded"}


def test_towel_sides_range_draws_the_same_scene_otherwise() -> None:
    """`--towel-sides` changes the sizes only: the same draws scaled into the other range."""
    a = [sample_scene(np.random.default_rng([5, i]), i, 0.3, 0.4) for i in range(20)]
    b = [
        sample_scene(np.random.default_rng([5, i]), i, 0.3, 0.4, "anywhere", (0.5, 0.7))
        for i in range(20)
    ]
    for s, t in zip(a, b, strict=True):
        assert 0.5 <= t.towel_width <= 0.7 and 0.5 <= t.towel_height <= 0.7
        assert (t.towel_width - 0.5) / 0.2 == pytest.approx((s.towel_width - 0.2) / 0.25)
        assert (t.state, t.yaw, t.cloth_rgb, t.arm_target) == (
            s.state,
            s.yaw,
            s.cloth_rgb,
            s.arm_target,
        )


def test_folded_towel_mesh() -> None:
    mesh = folded_towel(TowelSpec(0.3, 0.2, 10), "y", lift=0.01)
    v = mesh.vertices
    assert np.ptp(v[:, 0]) == pytest.approx(0.3) and np.ptp(v[:, 1]) == pytest.approx(0.1)
    assert set(np.round(v[:, 2], 6)) == {0.0, 0.01}


@pytest.mark.parametrize("garment", ["tshirt", "pants"])
def test_garment_scene_sampling_is_reproducible_and_in_range(garment: str) -> None:
    a = [sample_garment_scene(np.random.default_rng([5, i]), i, garment) for i in range(20)]
    b = [sample_garment_scene(np.random.default_rng([5, i]), i, garment) for i in range(20)]
    assert a == b
    for s in a:
        assert abs(s.yaw - math.pi / 2) <= math.radians(15)
        assert abs(s.x - 0.45) <= 0.03 and abs(s.y) <= 0.03
        assert s.arm_target is None and s.state == "flat"
    assert len({s.spec for s in a}) == 20


def test_garment_yaw_range_spreads_the_garments() -> None:
    wide = [
        sample_garment_scene(np.random.default_rng([5, i]), i, "tshirt", yaw_range=math.pi)
        for i in range(20)
    ]
    offsets = [abs(s.yaw - math.pi / 2) for s in wide]
    assert max(offsets) <= math.pi and max(offsets) > math.radians(90)


def test_the_arm_at_home_moves_nothing_else() -> None:
    """`--arm-pose home` puts the gripper where the one-arm cell parks while it looks; every
    other draw of the scene stays as it is with the arm anywhere."""
    for i in range(10):
        anywhere = sample_garment_scene(np.random.default_rng([5, i]), i, "pants", 1.0)
        home = sample_garment_scene(np.random.default_rng([5, i]), i, "pants", 1.0, arm_pose="home")
        assert anywhere.arm_target is not None and anywhere.arm_target != home.arm_target
        assert home.arm_target == pytest.approx((0.45, 0.0, DEFAULT_LAYOUT.table_height + 0.25))
        assert dataclasses.replace(home, arm_target=anywhere.arm_target) == anywhere
    towel = sample_scene(np.random.default_rng([5, 0]), 0, 0.0, 1.0, "home")
    assert towel.arm_target == home.arm_target
    with pytest.raises(ConfigError, match=r"arm pose must be one of .*'elbow'"):
        sample_garment_scene(np.random.default_rng(0), 0, "pants", 1.0, arm_pose="elbow")
