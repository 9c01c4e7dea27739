"""ROS 1 availability for the tests under tests/ros (they skip, with the reason, without it)."""

import socket

import pytest

from foldbot.commands.ros_fold import ros_missing

ROS_MISSING = ros_missing()
requires_ros = pytest.mark.skipif(
    ROS_MISSING is not None, reason=f"ROS 1 not available: {ROS_MISSING}"
)


def free_port() -> int:
    """A free TCP port for a private ROS master (tests never touch a user's roscore)."""
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]
