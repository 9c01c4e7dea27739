"""The garment registry, and garments as PyBullet soft bodies (default ClothConfig)."""

import math

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.garments import (
    GARMENT_KEYPOINTS,
    GARMENTS,
    garment_kind,
    make_garment,
    sample_garment,
)
from foldbot.garments.towel import TowelSpec
from foldbot.sim.cloth import ClothConfig, DivergenceMonitor, SoftCloth, settle
from foldbot.sim.oracle import GroundTruthOracle
from foldbot.sim.world import SimWorld


@pytest.mark.parametrize("kind", GARMENTS)
def test_sample_garment_gives_the_named_keypoints(kind: str) -> None:
    spec, mesh = sample_garment(kind, np.random.default_rng(0))
    assert garment_kind(spec) == kind
    assert set(mesh.keypoints) == set(GARMENT_KEYPOINTS[kind])
    again, mesh2 = sample_garment(kind, np.random.default_rng(0))
    assert again == spec
    np.testing.assert_array_equal(mesh.vertices, mesh2.vertices)
    np.testing.assert_array_equal(make_garment(spec).faces, mesh.faces)


def test_edge_length_sets_the_resolution() -> None:
    _, coarse = sample_garment("tshirt", np.random.default_rng(0), edge_length=0.04)
    _, fine = sample_garment("tshirt", np.random.default_rng(0))
    assert len(coarse.vertices) < len(fine.vertices)
    towel, mesh = sample_garment("towel", np.random.default_rng(0), edge_length=0.03)
    assert isinstance(towel, TowelSpec) and mesh.edge_length == pytest.approx(0.034, rel=0.1)


def test_unknown_kind_is_named() -> None:
    with pytest.raises(ConfigError, match="'sock'"):
        sample_garment("sock", np.random.default_rng(0))
    with pytest.raises(ConfigError, match="not a garment spec"):
        make_garment("tshirt")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kind", "seed"), [("tshirt", 0), ("tshirt", 1), ("pants", 0), ("pants", 1)]
)
def test_garment_settles_flat_as_a_soft_body(kind: str, seed: int) -> None:
    """Default ClothConfig (mass 0.1 kg, as the 0.09 m² towel): the garment loads, settles flat
    in place and the oracle reads its keypoints by name."""
    _, mesh = sample_garment(kind, np.random.default_rng(seed))
    with SimWorld() as world:
        lay = world.layout
        yaw = math.pi / 2 + (0.2 if seed else -0.2)
        cloth = SoftCloth(
            world.client, mesh, ClothConfig(drop_height=0.02), lay.table_height,
            lay.workspace_center_xy, yaw,
        )  # fmt: skip
        world.add_step_hook(DivergenceMonitor(cloth, lay.workspace_center_xy, radius=1.0))
        settle(world, cloth, max_time=1.0)
        v = cloth.sim_vertices()
        height = v[:, 2] - lay.table_height
        assert height.min() > 0.0 and height.max() < 0.008  # flat, on the table
        drift = np.linalg.norm(v[:, :2] - cloth.spawn_vertices[:, :2], axis=1)
        assert drift.max() < 0.005
        kp = GroundTruthOracle(cloth).keypoint_positions()
        assert set(kp) == set(GARMENT_KEYPOINTS[kind])
        for name, i in mesh.keypoints.items():
            np.testing.assert_array_equal(kp[name], v[i])
        # The top (neck / waist) points towards the robot (world −x) at yaw ≈ +90°.
        top = "neck" if kind == "tshirt" else "left_waist"
        bottom = "left_hem" if kind == "tshirt" else "left_leg_outer"
        assert kp[top][0] < kp[bottom][0] - 0.2
        with pytest.raises(ConfigError, match="corner_00"):
            GroundTruthOracle(cloth).keypoint_positions(("corner_00",))
