"""The task node's cell (RosCell) without topics: what it waits for before it plans."""

import threading
from types import SimpleNamespace

import numpy as np
import pytest
from ros_helpers import requires_ros

from foldbot.errors import ConfigError, FoldbotError

pytestmark = requires_ros


def test_the_latched_camera_transform_is_waited_for_not_missed():
    # /tf_static's connection can come up after the first frame's: the transform arrives late.
    from foldbot.ros.task_node import RosCell

    cell = SimpleNamespace(T_world_camera=None)
    transform = np.eye(4)
    late = threading.Timer(0.2, setattr, (cell, "T_world_camera", transform))
    late.start()
    try:
        assert RosCell.camera_transform(cell, timeout_s=10.0) is transform
    finally:
        late.cancel()


def test_a_camera_transform_that_never_comes_is_named():
    from foldbot.ros.task_node import RosCell

    cell = SimpleNamespace(T_world_camera=None)
    with pytest.raises(
        FoldbotError,
        match=r"no world → camera transform on /tf_static within 0\.1 s: .*ros-calibrate.*"
        r"--camera-pose",
    ):
        RosCell.camera_transform(cell, timeout_s=0.1)


class _Listened:
    """A publisher with a subscriber connected (rospy's Publisher needs a running node)."""

    resolved_name = "/planner/request"

    def get_num_connections(self) -> int:
        return 1

    def publish(self, msg) -> None:
        pass


def test_a_plan_that_never_comes_because_the_cell_diverged_says_it_diverged(monkeypatch):
    # The cell diverged while running on by itself and took every node down with it: the task,
    # waiting for a plan, raises the cell's report, not the planner's silence.
    import itertools

    from foldbot.errors import SimulationDivergedError
    from foldbot.ros import task_node
    from foldbot.ros.task_node import RosCell, _Inbox

    monkeypatch.setattr(task_node, "REPLY_TIMEOUT_S", 0.2)
    cell = SimpleNamespace(
        _ids=itertools.count(1), pub_plan=_Listened(), plans=_Inbox(), results=_Inbox()
    )
    cell.raise_reported_error = lambda: RosCell.raise_reported_error(cell)
    with pytest.raises(FoldbotError, match=r"no together plan from the planner node within 0 s"):
        RosCell._plan(cell, "together")
    cell.results.put(
        {"command": "run", "ok": False, "error": "cloth simulation diverged: the whole cloth "
         "slid across the table", "error_type": "SimulationDivergedError"}
    )  # fmt: skip
    with pytest.raises(SimulationDivergedError, match="the cell: cloth simulation diverged"):
        RosCell._plan(cell, "together")


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
