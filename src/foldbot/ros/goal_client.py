"""A SimpleActionClient that cannot miss the result of a goal its server ends at once.

actionlib's SimpleActionClient (noetic, Python) publishes a goal and only then records its
handle; a status or result that comes back in between reaches its transition callback for a
handle it does not track yet ("Got a transition callback on a goal handle that we're not
tracking"), is dropped, and the goal never reads as done: wait_for_result waits forever. A
driver that refuses a goal, or a gripper that acts at once, answers within that window on a
loaded machine (CI saw the drivers' probe hang so). GoalClient takes one lock around sending a
goal and around its callbacks, so they run only once the handle is recorded.
"""

from __future__ import annotations

import threading
import time

import actionlib
import rospy

from foldbot.errors import FoldbotError


class GoalClient(actionlib.SimpleActionClient):
    """actionlib.SimpleActionClient whose goal's callbacks wait until the goal is tracked."""

    def __init__(self, ns: str, action_spec) -> None:
        self._sending = threading.RLock()
        """Held while a goal is sent and while a callback runs (re-entrant: a done callback may
        send the next goal)."""
        super().__init__(ns, action_spec)

    def send_goal(self, goal, done_cb=None, active_cb=None, feedback_cb=None) -> None:
        with self._sending:
            super().send_goal(goal, done_cb, active_cb, feedback_cb)

    def _handle_transition(self, gh) -> None:
        with self._sending:
            super()._handle_transition(gh)

    def _handle_feedback(self, gh, feedback) -> None:
        with self._sending:
            super()._handle_feedback(gh, feedback)

    @property
    def done(self) -> bool:
        """Whether the last goal sent has its result (its status alone may say SUCCEEDED
        before the result has come)."""
        return self.simple_state == actionlib.SimpleGoalState.DONE

    def wait_done(self, what: str, timeout_s: float) -> None:
        """Wait for the last goal's result, at most `timeout_s` of wall time (a cell that stops
        also stops its simulated clock, which wait_for_result's timeout runs on); raise naming
        `what` when it does not come."""
        deadline = time.monotonic() + timeout_s
        while not self.done:
            if time.monotonic() > deadline or rospy.is_shutdown():
                raise FoldbotError(f"{what}: no result within {timeout_s:g} s")
            time.sleep(0.005)
