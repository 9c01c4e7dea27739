"""ros-check's arm as modelled (check_node.arm_model_offsets, model_words): the flange a UR's
controller reports (the sim node's ur_tool_in_base on the simulated arm) against foldbot's model
of the arm at the same joints; another model is named, with the one that fits."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest
from ros_helpers import requires_ros

from foldbot.sim.layout import DEFAULT_LAYOUT
from foldbot.sim.robots import make_robot

pytestmark = requires_ros


@pytest.fixture(scope="module")
def client():
    cid = p.connect(p.DIRECT)
    yield cid
    p.disconnect(cid)


@pytest.mark.parametrize("model", ["ur5", "ur5e"])
def test_the_arm_as_its_controller_reports_it_fits_its_own_model(client, model):
    from foldbot.ros.check_node import arm_model_offsets, model_words
    from foldbot.ros.sim_node import ur_tool_in_base

    arm = make_robot(model, client, DEFAULT_LAYOUT)
    other = "ur5e" if model == "ur5" else "ur5"
    for q in (arm.home_q, arm.out_of_view_q, arm.home_q + [0.3, -0.2, 0.4, 0.1, -0.5, 1.0]):
        arm.reset_joints(q)
        offsets = arm_model_offsets(np.asarray(q), ur_tool_in_base(arm), model)
        assert list(offsets) == [model, other]
        dist, angle = offsets[model]
        assert dist < 1e-5 and angle < 1e-5
        ok, words = model_words(model, offsets)
        assert ok and words.startswith(f"the {model}'s kinematics put the flange 0.0 mm and 0.00°")
        # Told the other model, the check names the offset and the arm it is.
        wrong, why = model_words(
            other, arm_model_offsets(np.asarray(q), ur_tool_in_base(arm), other)
        )
        assert not wrong and offsets[other][0] > 0.02
        assert "(at most 10 mm and 1°)" in why
        assert why.endswith(f"off: the arm is a {model} (--robot {model})")


def test_an_arm_no_model_fits_is_asked_about():
    from foldbot.ros.check_node import model_words

    ok, words = model_words("ur5", {"ur5": (0.012, 0.0), "ur5e": (0.05, 0.0)})
    assert not ok
    assert words == (
        "the ur5's kinematics put the flange 12.0 mm and 0.00° from where the arm's controller "
        "says it is (at most 10 mm and 1°): is --robot the arm's model? (or its calibration far "
        "from its nominal lengths)"
    )
    assert not model_words("ur5", {"ur5": (0.001, np.radians(1.5))})[0]
