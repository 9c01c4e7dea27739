"""The task node without topics: how it reports a real cell's fold and the layer thickness it
assumes there."""

import numpy as np
import pytest
from ros_helpers import requires_ros

from foldbot.errors import ConfigError

pytestmark = requires_ros


def _record(ious, start_m2=0.09, final_m2=0.045):
    from foldbot.loop import FoldRecord
    from foldbot.perception.state import ClothState
    from foldbot.types import CameraIntrinsics, Observation

    rec = FoldRecord(fold_lines=[(0.5, 0.0, 0.0, 1.0)] * len(ious))
    rec.stages = [
        {"stage": i, "mask_iou_vs_predicted": iou, "verified": iou >= 0.8}
        for i, iou in enumerate(ious)
    ]
    rec.initial_state = ClothState(detected=True, coverage_m2=start_m2)
    rec.final_state = ClothState(detected=True, coverage_m2=final_m2)
    K = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    rec.final_obs = Observation(
        np.zeros((480, 640, 3), np.uint8),
        np.zeros((480, 640), np.float32),
        CameraIntrinsics(640, 480, K),
        np.eye(4),
    )
    return rec


def test_a_real_cells_fold_is_reported_as_seen_and_left_unscored():
    from foldbot.commands.fold import add_arguments, config_from_args
    from foldbot.io.episode import REQUIRED_RESULT_KEYS
    from foldbot.ros.task_node import outcome_line, perceived_outcome, real_cell_result

    seen = perceived_outcome(_record([0.92, 0.85]))
    assert seen["verified"] and seen["stage_mask_iou"] == [0.92, 0.85]
    assert seen["coverage_ratio"] == pytest.approx(0.5)
    assert not perceived_outcome(_record([0.92, 0.7]))["verified"]  # one stage off its plan
    assert not perceived_outcome(_record([]))["verified"]  # nothing folded, nothing verified

    import argparse

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    words = ["--out", "unused", "--recipe", "quarter", "--start", "crumpled"]
    words += ["--flatten-option", "retries=2"]
    cfg = config_from_args(parser.parse_args(words))
    result = real_cell_result(cfg, _record([0.92, 0.85]), 12.0, 13.0)
    assert result["flatten_options"] == {"retries": 2}  # the task's settings, as in process
    assert set(REQUIRED_RESULT_KEYS) <= result.keys()  # the contract's keys, metrics None
    assert result["scored"] is False and result["success"] is None
    assert result["fold_error_mm"] is None and result["seed"] is None
    assert result["camera"]["width"] == 640 and result["recipe"] == "quarter"
    line = outcome_line(result)
    assert "not scored" in line and "every stage verified" in line and "0.50 of its start" in line


def test_a_real_cell_takes_the_simulated_cloths_layer_thickness():
    # Where depth tells nothing of a layer's height, the loop on a real cell assumes what the
    # sim node would publish for the same options: two collision margins.
    import argparse

    from foldbot.commands.fold import add_arguments, config_from_args
    from foldbot.pipeline import seeded_garment
    from foldbot.ros.task_node import real_cell_thickness

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    for words in (["--resolution", "9"], ["--width", "0.4", "--cloth", "margin_divisor=8"]):
        cfg = config_from_args(parser.parse_args(["--out", "unused", *words]))
        edge = seeded_garment(cfg)[1].edge_length
        assert real_cell_thickness(cfg) == pytest.approx(2 * edge / cfg.cloth.margin_divisor)
        # A real towel's own thickness, where the user gives it (`ros-fold --cloth-thickness`).
        assert real_cell_thickness(cfg, 0.003) == 0.003
        with pytest.raises(ConfigError, match=r"cloth thickness must be metres in \(0, 0.05\]"):
            real_cell_thickness(cfg, 0.06)
