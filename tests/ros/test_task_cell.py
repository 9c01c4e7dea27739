"""The task node's cell (task_cell.RosCell) without topics: what it waits for before it plans."""

import threading
from types import SimpleNamespace

import numpy as np
import pytest
from ros_helpers import requires_ros

from foldbot.errors import FoldbotError

pytestmark = requires_ros


def test_the_latched_camera_transform_is_waited_for_not_missed():
    # /tf_static's connection can come up after the first frame's: the transform arrives late.
    from foldbot.ros.task_cell import RosCell

    cell = SimpleNamespace(T_world_camera=None)
    transform = np.eye(4)
    late = threading.Timer(0.2, setattr, (cell, "T_world_camera", transform))
    late.start()
    try:
        assert RosCell.camera_transform(cell, timeout_s=10.0) is transform
    finally:
        late.cancel()


def test_a_camera_transform_that_never_comes_is_named():
    from foldbot.ros.task_cell import RosCell

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
    from foldbot.ros import task_cell
    from foldbot.ros.task_cell import RosCell, _Inbox

    monkeypatch.setattr(task_cell, "REPLY_TIMEOUT_S", 0.2)
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
