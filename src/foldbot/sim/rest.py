"""Whether a running cell has come to rest: the cloth's vertices and the arms' joints still.

A running cell (`foldbot ros-cell`) steps its physics between goals as a real cell's world runs
on. A folded or heaped soft body left to itself for tens of seconds can creep until it blows up
(a folded towel slid off at 0.61 m/s after 34 s at rest, a heap sank through the table), which a
real towel never does. Once RestWatch finds the cell still, the sim node advances its clock
without stepping the physics (SimWorld.idle) until the next goal. It does not make a running
cell reproducible: goals still arrive, on the wall clock, in gaps shorter than the stillness
it waits for.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

REST_SPEED_MPS = 0.002
"""Fastest a cloth vertex may move (m/s, over one check) for the cloth to count as still: the
speed `sim.cloth.settle` settles to."""
REST_JOINT_SPEED = 0.002
"""Fastest an arm's joint may turn (rad/s) for the arm to count as still."""
CHECK_S = 0.1
"""Time between two checks (s)."""
STILL_CHECKS = 3
"""Checks in a row that must find everything still: the cell rests after 0.3 s of stillness."""


class RestWatch:
    """Counts the physics steps since the last goal and, every CHECK_S, whether the cloth's
    vertices and the arms' joints moved; `resting` once STILL_CHECKS checks in a row found them
    still. `wake()` (a goal arrived) starts the count again."""

    def __init__(
        self,
        vertices: Callable[[], np.ndarray],
        joint_speeds: Sequence[Callable[[], np.ndarray]],
        time_step: float,
    ) -> None:
        self.vertices = vertices
        self.joint_speeds = list(joint_speeds)
        self.every = max(1, round(CHECK_S / time_step))
        self.dt = self.every * time_step
        self.resting = False
        self.rests = 0
        """How many times the cell has come to rest (each idle between goals counts once)."""
        self.wake()

    def wake(self) -> None:
        """A goal arrived: the physics runs again, and stillness is counted from here."""
        self.resting = False
        self._steps = 0
        self._still = 0
        self._last: np.ndarray | None = None

    def stepped(self) -> bool:
        """Note one physics step of the idle cell; returns `resting`."""
        self._steps += 1
        if self._steps % self.every:
            return self.resting
        now = self.vertices()
        last, self._last = self._last, now
        if last is None:
            return self.resting
        fastest = float(np.linalg.norm(now - last, axis=1).max()) / self.dt
        turning = max((float(np.abs(speed()).max()) for speed in self.joint_speeds), default=0.0)
        still = fastest < REST_SPEED_MPS and turning < REST_JOINT_SPEED
        self._still = self._still + 1 if still else 0
        if self._still >= STILL_CHECKS:
            self.resting = True
            self.rests += 1
        return self.resting
