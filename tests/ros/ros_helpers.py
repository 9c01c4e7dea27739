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


def wait_for_master(port: int, timeout_s: float = 60.0) -> None:
    """Wait until the ROS master on `port` answers (a cell started in the background)."""
    import time

    import rosgraph

    master = rosgraph.Master("/test_wait", master_uri=f"http://localhost:{port}")
    deadline = time.monotonic() + timeout_s
    while not master.is_online():
        assert time.monotonic() < deadline, f"no ROS master on port {port} within {timeout_s} s"
        time.sleep(0.2)
