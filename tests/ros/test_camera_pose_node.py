"""The camera pose node's arguments: static_transform_publisher's, checked by name."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from foldbot.errors import ConfigError
from foldbot.ros.camera_pose_node import parse_pose_args


def test_the_words_give_the_transform_and_the_frames():
    T, parent, child = parse_pose_args(
        [
            "1.0",
            "0.5",
            "1.7",
            "0",
            "0",
            "0.7071068",
            "0.7071068",
            "world",
            "camera_color_optical_frame",
        ]
    )
    assert (parent, child) == ("world", "camera_color_optical_frame")
    assert np.allclose(T[:3, 3], [1.0, 0.5, 1.7])
    assert np.allclose(T[:3, :3], Rotation.from_euler("z", 90, degrees=True).as_matrix())


@pytest.mark.parametrize(
    ("words", "needle"),
    [
        ("1 2 3 0 0 0 1 world", "got 8 words"),
        ("1 2 x 0 0 0 1 world cam", "a static transform is x y z qx qy qz qw"),
        ("1 2 3 0 0 0 0 world cam", "non-zero quaternion"),
        ("1 2 nan 0 0 0 1 world cam", "finite numbers"),
    ],
)
def test_bad_words_are_refused_by_name(words, needle):
    with pytest.raises(ConfigError, match=needle):
        parse_pose_args(words.split())
