"""The operator's go or stop before each motion (`--confirm`): what the arms are about to do
(a pick-and-place, a park, the lift after a missed grasp), said on the terminal, and the fold
moves on Enter or ends, named, on `s`. For a first run on a real arm, beside the dry run and the
speed scale: a person watching the cell decides each motion, with the planned grasp and place in
front of them."""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TextIO

import numpy as np

from foldbot.errors import OperatorStopped

GO_WORDS = ("", "y", "yes", "go")
"""Answers that let the motion run (Enter alone is the usual one)."""
STOP_WORDS = ("s", "stop", "q", "quit", "n", "no")
"""Answers that end the fold before the motion."""


@dataclass(frozen=True)
class PlannedMotion:
    """One arm's pick-and-place as planned, before it moves: its label, arm, grasp and place
    (world xyz, m; a spread's release for its place), steps and seconds of motion."""

    label: str
    arm: int
    grasp: np.ndarray
    place: np.ndarray
    steps: int
    seconds: float

    def text(self) -> str:
        """One line on it."""
        g = ", ".join(f"{v:.3f}" for v in np.asarray(self.grasp, dtype=float))
        p = ", ".join(f"{v:.3f}" for v in np.asarray(self.place, dtype=float))
        return (
            f"{self.label or 'pick-and-place'} with arm {self.arm}: grasp ({g}) m → place ({p}) m, "
            f"{self.steps} steps, {self.seconds:.1f} s"
        )


def arms_words(arms: tuple[int, ...]) -> str:
    """ "arm 0", "arms 0 and 1"."""
    if len(arms) == 1:
        return f"arm {arms[0]}"
    return f"arms {', '.join(str(a) for a in arms[:-1])} and {arms[-1]}"


@dataclass(frozen=True)
class ArmMove:
    """A motion that is not a pick-and-place, before it moves: its label (park, lift), the arms
    it moves, what it does in words and its seconds of motion."""

    label: str
    arms: tuple[int, ...]
    what: str
    seconds: float

    def text(self) -> str:
        """One line on it."""
        return f"{self.label} with {arms_words(self.arms)}: {self.what}, {self.seconds:.1f} s"


def _is_terminal(stream: TextIO) -> bool:
    """Whether `stream` is a terminal (which echoes what is typed)."""
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


def motion_words(motions: Sequence[PlannedMotion | ArmMove]) -> str:
    """The motions' one-line description (two arms' joined by "together with")."""
    return " together with ".join(m.text() for m in motions)


class OperatorGate:
    """Asks before each motion (FoldCell.confirm_motion, confirm_move) on a terminal: Enter (or y)
    lets it run, `s` (or q, n) ends the fold there with OperatorStopped, as does input that
    closes (nothing more can be asked); anything else is asked again. Counts the motions let
    run and the seconds spent waiting (result.json's `operator`)."""

    def __init__(
        self, answers: TextIO | None = None, out: TextIO | None = None, task: str = "the fold"
    ) -> None:
        self.answers = answers
        self.out = out
        self.task = task
        """What a stop ends, as the prompt names it ("the fold", "the calibration")."""
        self.confirmed = 0
        self.wait_seconds = 0.0

    def ask(self, motions: Sequence[PlannedMotion | ArmMove]) -> None:
        """Return when the operator lets `motions` run; OperatorStopped when not."""
        answers = self.answers if self.answers is not None else sys.stdin
        out = self.out if self.out is not None else sys.stdout
        said = motion_words(motions)
        t0 = time.perf_counter()
        try:
            while True:
                out.write(f"next: {said}\n  Enter: move · s: stop {self.task} > ")
                out.flush()
                line = answers.readline()
                if line and not _is_terminal(answers):
                    out.write(f"{line.strip()}\n")  # piped: the answer as a terminal echoes it
                if not line:
                    out.write("\n")
                    raise OperatorStopped(
                        f"no answer (input closed) before {said}: {self.task} stopped there"
                    )
                word = line.strip().lower()
                if word in GO_WORDS:
                    self.confirmed += 1
                    return
                if word in STOP_WORDS:
                    raise OperatorStopped(f"stopped by the operator before {said}")
                out.write(
                    f"  {word!r}: answer Enter (or {', '.join(GO_WORDS[1:])}) to move, "
                    f"{', '.join(STOP_WORDS)} to stop\n"
                )
        finally:
            self.wait_seconds += time.perf_counter() - t0

    def record(self) -> dict[str, Any]:
        """result.json's `operator`: motions let run and seconds spent waiting for answers
        (in wall_seconds, not in the simulated time)."""
        return {"motions_confirmed": self.confirmed, "wait_seconds": self.wait_seconds}
