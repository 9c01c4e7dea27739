"""The task node's cell (RosCell) without topics: what it waits for before it plans."""

import threading
from types import SimpleNamespace

import numpy as np
import pytest
from ros_helpers import requires_ros

from foldbot.errors import FoldbotError

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
        FoldbotError, match=r"no world → camera transform on /tf_static within 0\.1 s"
    ):
        RosCell.camera_transform(cell, timeout_s=0.1)
