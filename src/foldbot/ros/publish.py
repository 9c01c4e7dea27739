"""Publishing a request or reply only once something listens: ROS 1 drops a message published
before a subscriber's connection is up, so a node that starts late would miss it and never answer."""

from __future__ import annotations

import time
from typing import Any

import rospy

from foldbot.errors import FoldbotError


def publish_when_heard(pub: rospy.Publisher, msg: Any, timeout_s: float) -> None:
    """Publish `msg` on `pub` once at least one subscriber is connected (seen once in CI: the
    planner node, building its robots on a loaded machine, subscribed after the task's first
    request went out, and the fold waited out its reply timeout). Raises FoldbotError naming the
    topic when nothing subscribes within `timeout_s` seconds (wall time)."""
    deadline = time.monotonic() + timeout_s
    while pub.get_num_connections() == 0:
        if time.monotonic() > deadline or rospy.is_shutdown():
            raise FoldbotError(f"nothing subscribed to {pub.resolved_name} within {timeout_s:g} s")
        time.sleep(0.02)
    pub.publish(msg)
