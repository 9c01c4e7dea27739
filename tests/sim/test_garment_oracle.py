"""The garment oracle: a T-shirt's true state, its keypoints the mesh's named keypoint vertices
where the simulated cloth has them now (ground truth, for comparison and tests only)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foldbot.garments.tshirt import TShirtSpec, make_tshirt
from foldbot.sim.cloth import ClothConfig, SoftCloth
from foldbot.sim.garment_oracle import GarmentOracleEstimator
from foldbot.sim.oracle import GroundTruthOracle
from foldbot.sim.world import SimWorld


@pytest.fixture(scope="module")
def shirt():
    """A T-shirt turned 90°, lying as spawned."""
    world = SimWorld()
    mesh = make_tshirt(TShirtSpec(edge_length=0.04))
    cloth = SoftCloth(
        world.client, mesh, ClothConfig(), world.layout.table_height, (0.45, 0.0), math.pi / 2
    )
    world.step(1)
    yield world, cloth
    world.close()


def test_the_keypoints_are_the_named_vertices_where_they_lie_now(shirt):
    _world, cloth = shirt
    oracle = GroundTruthOracle(cloth)
    state = GarmentOracleEstimator(oracle).estimate()
    assert state.detected
    assert set(state.keypoints) == set(cloth.mesh.keypoints)
    assert {"neck", "left_shoulder", "left_sleeve", "right_hem"} <= set(state.keypoints)
    v = oracle.cloth_vertices()
    for name, (point, confidence) in state.keypoints.items():
        np.testing.assert_array_equal(point, v[cloth.mesh.keypoints[name]])
        assert confidence == 1.0
    # Turned 90°: the neck (mesh +y) lies toward the robot (world −x) of the hem.
    assert state.keypoints["neck"][0][0] < state.keypoints["left_hem"][0][0] - 0.2
    # Moved, it follows the cloth: its keypoints are read afresh, not kept.
    moved = cloth.node_positions()
    moved[:, 1] += 0.05
    cloth.set_node_positions(moved)
    again = GarmentOracleEstimator(oracle).estimate()
    np.testing.assert_allclose(
        again.keypoints["neck"][0], state.keypoints["neck"][0] + [0, 0.05, 0], atol=1e-9
    )
