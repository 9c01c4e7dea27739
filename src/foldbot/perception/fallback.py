"""Chain estimators: the first one that detects the cloth answers.

A garment's keypoint estimator only recognises the flat garment; once folded, the cloth's mask and
outline (all the garment loop needs after its first observation) come from the generic one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

from foldbot.errors import ConfigError
from foldbot.perception.state import ClothState
from foldbot.types import Observation

if TYPE_CHECKING:
    from foldbot.perception.segmentation import Fixture


class Estimator(Protocol):
    def estimate(self, obs: Observation) -> ClothState: ...


class FirstDetected:
    """Ask `estimators` in order; return the first state with detected=True (else the last)."""

    def __init__(self, *estimators: Estimator) -> None:
        if not estimators:
            raise ConfigError("FirstDetected needs at least one estimator")
        self.estimators = estimators

    def estimate(self, obs: Observation) -> ClothState:
        state = ClothState.not_detected()
        for estimator in self.estimators:
            state = estimator.estimate(obs)
            if state.detected:
                return state
        return state


def vision_estimator(garment: str, fixtures: Sequence[Fixture] = ()) -> Estimator:
    """The RGB-D estimator for `garment`: a towel's corners (VisionEstimator), or a garment's
    keypoints on the flat garment and, once folded, the outline and mask of any cloth; the cell's
    `fixtures` (its layout's obstacles) masked as occluders (segmentation.SegmentationConfig)."""
    from foldbot.perception.estimator import EstimatorConfig, VisionEstimator
    from foldbot.perception.garment_keypoints import GarmentEstimator, GarmentKeypointConfig
    from foldbot.perception.segmentation import SegmentationConfig

    seg = SegmentationConfig(fixtures=tuple(fixtures))
    towel = VisionEstimator(EstimatorConfig(segmentation=seg))
    if garment == "towel":
        return towel
    return FirstDetected(GarmentEstimator(garment, GarmentKeypointConfig(segmentation=seg)), towel)
