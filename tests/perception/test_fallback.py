"""Chained estimators: the first that detects the cloth answers. A garment's keypoints while the
garment lies flat and is recognised; any cloth's outline (the towel estimator) once it is not."""

import pytest

from foldbot.errors import ConfigError
from foldbot.garments.tshirt import TShirtSpec
from foldbot.perception.estimator import VisionEstimator
from foldbot.perception.fallback import FirstDetected, vision_estimator
from foldbot.perception.garment_keypoints import GarmentEstimator
from foldbot.sim.perception_scenes import (
    default_garment_scene,
    default_scene,
    render_garment_scene,
    render_scene,
)

W, H = 320, 240
TOWEL_CORNERS = ["far_left", "far_right", "near_left", "near_right"]


@pytest.fixture(scope="module")
def towel_obs():
    return render_scene(default_scene(yaw=0.3), W, H, 10, settle_time=0).obs


@pytest.fixture(scope="module")
def shirt_obs():
    return render_garment_scene(default_garment_scene(TShirtSpec()), W, H, settle_time=0).obs


def test_a_recognised_garment_answers_with_its_keypoints(shirt_obs):
    state = vision_estimator("tshirt").estimate(shirt_obs)
    assert state.detected
    assert {"neck", "left_shoulder", "right_armpit", "left_sleeve"} <= set(state.keypoints)


def test_a_cloth_the_garment_estimator_does_not_recognise_falls_back_to_its_outline(towel_obs):
    assert not GarmentEstimator("tshirt").estimate(towel_obs).detected
    state = vision_estimator("tshirt").estimate(towel_obs)
    assert state.detected and sorted(state.keypoints) == TOWEL_CORNERS


def test_the_estimators_are_asked_in_order(shirt_obs, towel_obs):
    chain = FirstDetected(GarmentEstimator("pants"), GarmentEstimator("tshirt"), VisionEstimator())
    assert "neck" in chain.estimate(shirt_obs).keypoints  # pants: not detected; the T-shirt next
    # Where none detects the cloth, the last one's answer stands.
    none = FirstDetected(GarmentEstimator("pants"), GarmentEstimator("tshirt"))
    state = none.estimate(towel_obs)
    assert not state.detected and not state.keypoints


def test_a_towel_has_the_towel_estimator_alone():
    assert isinstance(vision_estimator("towel"), VisionEstimator)


def test_a_chain_of_no_estimator_is_refused():
    with pytest.raises(ConfigError, match="at least one estimator"):
        FirstDetected()
