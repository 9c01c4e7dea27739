"""Publishing only once something listens: ROS 1 drops a message published before a subscriber's
connection is up, so a node that starts late would miss it (a request never answered, a bag
missing the start of a run)."""

from __future__ import annotations

import time
from typing import Any

import rospy

from foldbot.errors import FoldbotError

LISTED_WAIT_S = 10.0
"""Longest wall time a node waits for the subscribers the master lists to connect (a node that
died without unregistering stays listed: the wait then ends with a warning, not a hang)."""


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


def wait_for_listed_subscribers(
    publishers: list[rospy.Publisher], before: str, timeout_s: float = LISTED_WAIT_S
) -> list[str]:
    """Wait until every node the master lists as subscribing to these publishers' topics is
        connected to them, so what is published next reaches it (seen once: rosbag, subscribed
        but not yet connected to the sim node's /sim/result, missed the ready report, a newer one
        having replaced the latched message by the time it connected). Returns what is still not
        connected after `timeout_s` seconds (wall time), as "NODE on TOPIC", and logs it as a warning
    naming what goes out `before` them; empty once all are."""
    import rosgraph

    me = rospy.get_name()
    master = rosgraph.Master(me)
    deadline = time.monotonic() + timeout_s
    while True:
        listed = dict(master.getSystemState()[1])
        missing = [
            f"{node} on {pub.resolved_name}"
            for pub in publishers
            for node in listed.get(pub.resolved_name, ())
            if node != me and not pub.impl.has_connection(node)
        ]
        if not missing or time.monotonic() > deadline or rospy.is_shutdown():
            if missing:
                rospy.logwarn("%s with %s not connected", before, ", ".join(missing))
            return missing
        time.sleep(0.02)
