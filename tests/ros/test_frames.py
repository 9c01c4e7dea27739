"""/tf_static's transforms as a tree: a real camera's colour and depth optical frames hang under
its own link, and the nodes look one up in the other."""

import numpy as np
import pytest

pytest.importorskip("rospy", reason="ROS 1 Python packages not installed (scripts/install_ros.sh)")

from scipy.spatial.transform import Rotation
from tf2_msgs.msg import TFMessage

from foldbot.ros.convert import transform_msg
from foldbot.ros.frames import StaticFrames


def _pose(rotvec: list[float], xyz: list[float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = xyz
    return T


def test_a_frame_is_found_in_another_through_their_common_parent():
    T_world_link = _pose([0.1, -0.2, 0.3], [0.5, 0.0, 1.2])
    T_link_color = _pose([-1.2, 0.0, -1.5], [0.0, 0.015, 0.0])
    T_link_depth = _pose([-1.2, 0.01, -1.5], [0.0, 0.0, 0.0])
    frames = StaticFrames()
    # As drivers publish them: in separate messages, a leading slash on one.
    frames.add(TFMessage(transforms=[transform_msg(T_world_link, "world", "camera_link", 0.0)]))
    frames.add(
        TFMessage(
            transforms=[
                transform_msg(T_link_color, "/camera_link", "camera_color_optical_frame", 0.0),
                transform_msg(T_link_depth, "camera_link", "camera_depth_optical_frame", 0.0),
            ]
        )
    )
    T = frames.transform("camera_color_optical_frame", "camera_depth_optical_frame")
    np.testing.assert_allclose(T, np.linalg.inv(T_link_color) @ T_link_depth, atol=1e-12)
    np.testing.assert_allclose(
        frames.transform("world", "camera_color_optical_frame"),
        T_world_link @ T_link_color,
        atol=1e-12,
    )
    np.testing.assert_array_equal(frames.transform("a", "a"), np.eye(4))
    assert frames.transform("camera_color_optical_frame", "somewhere_else") is None


def test_a_loop_of_transforms_does_not_hang():
    frames = StaticFrames()
    frames.add(
        TFMessage(
            transforms=[
                transform_msg(np.eye(4), "a", "b", 0.0),
                transform_msg(np.eye(4), "b", "a", 0.0),
            ]
        )
    )
    assert frames.transform("a", "c") is None
