"""GROUND TRUTH garment keypoints — the oracle a garment's vision is compared with.

Like `foldbot.sim.oracle.OracleEstimator`, but the keypoints are the garment mesh's named
keypoint vertices (T-shirt: neck, shoulders, …; pants: waist corners, …) at their true current
positions. For comparison and tests only: nothing that would run on a real robot reads it.
"""

from __future__ import annotations

import dataclasses

from foldbot.perception.state import ClothState
from foldbot.sim.oracle import GroundTruthOracle, OracleEstimator
from foldbot.types import Observation


class GarmentOracleEstimator:
    """A ClothState from GROUND TRUTH whose keypoints are the mesh's named keypoint vertices."""

    def __init__(self, oracle: GroundTruthOracle) -> None:
        self.oracle = oracle
        self._outline = OracleEstimator(oracle, corners="outline")

    def estimate(self, obs: Observation | None = None) -> ClothState:
        """The garment's true state: mask, hull outline and its named keypoints."""
        state = self._outline.estimate(obs)
        v = self.oracle.cloth_vertices()
        keypoints = {
            name: (v[i].copy(), 1.0) for name, i in self.oracle.cloth.mesh.keypoints.items()
        }
        return dataclasses.replace(state, keypoints=keypoints)
