"""What the fold loops need from a robot cell (`FoldCell`), and what one motion step reports
(`StepLog`).

The in-process simulation implements FoldCell (`pipeline.SimCell`), and so do the ROS nodes
(`foldbot.ros.task_cell.RosCell`), so the loops (`loop`, `garment_loop`, `flatten`) run the same
decisions whether the modules talk by function call or over topics.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from foldbot.errors import UnreachableTargetError
from foldbot.operator import ArmMove, OperatorGate, PlannedMotion
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction, FoldPlan
from foldbot.planning.garment_recipes import GarmentPlan, plan_garment
from foldbot.planning.recipes import plan_stage, predicted_outline
from foldbot.types import GraspResult, Observation


def park_move(arms: tuple[int, ...], seconds: float) -> ArmMove:
    """A park as the operator is asked about it (`arms`: those that move)."""
    return ArmMove("park", arms, "joint move to the park pose, out of the camera's view", seconds)


def lift_move(arm: int, height: float, seconds: float) -> ArmMove:
    """The lift after a missed grasp as the operator is asked about it."""
    return ArmMove(
        "lift after the missed grasp", (arm,), f"open the jaws, straight up {height:.3f} m", seconds
    )


@dataclass
class StepLog:
    """What one motion step (a segment, and its gripper event) did."""

    name: str
    max_tracking_error: float
    grasp: GraspResult | None = None


class FoldCell(abc.ABC):
    """A robot cell as the fold loop drives it: eyes, a planner for motions, an arm that moves."""

    table_height: float
    """Height of the table top in the world (m), for drawing fold lines."""

    gate: OperatorGate | None = None
    """Where set (`--confirm`), the operator is asked before each motion: a pick-and-place
    (confirm_motion), a park or the lift after a missed grasp (confirm_move); None: the arms
    move as planned."""

    @property
    @abc.abstractmethod
    def sim_time(self) -> float:
        """The cell's clock (s)."""

    @abc.abstractmethod
    def observe(self) -> tuple[ClothState, Observation]:
        """A fresh camera frame of the resting cell and what perception makes of it."""

    def plan_stage(
        self,
        recipe: str,
        stage: int,
        corners: dict[str, np.ndarray],
        place_lift: float,
        crease_room: float = 0.0,
    ) -> tuple[FoldPlan, np.ndarray]:
        """The stage's fold plan from perceived corners, and the outline it should leave."""
        return (
            plan_stage(recipe, stage, corners, place_lift, crease_room),
            predicted_outline(recipe, stage, corners, crease_room),
        )

    def plan_garment(
        self, recipe: str, keypoints: dict[str, np.ndarray], place_lift: float, thickness: float
    ) -> GarmentPlan:
        """A garment recipe's every stage, planned from the keypoints perceived on the flat
        garment (planning.garment_recipes.plan_garment)."""
        return plan_garment(recipe, keypoints, place_lift, thickness)

    @abc.abstractmethod
    def plan_action(self, action: FoldAction) -> list[Any]:
        """Motion steps for one pick-and-place, every waypoint's IK solved before anything moves;
        raises UnreachableTargetError naming the infeasible waypoint."""

    @abc.abstractmethod
    def step_seconds(self, step: Any) -> float:
        """How long the active arm takes along a planned step (s), its dwell included, at the
        cell's speed scale: what a dry run reports before anything moves."""

    def confirm_motion(self, planned: list[tuple[int, Any, list[Any]]]) -> None:
        """Before planned pick-and-places move ((arm, action, its planned steps), one per arm
        moving): with a gate, what they will do is said and the operator's answer awaited
        (OperatorStopped on stop); without one, nothing."""
        if self.gate is None:
            return
        previous, motions = self.active_arm, []
        try:
            for arm, action, steps in planned:
                self.use_arm(arm)
                motions.append(
                    PlannedMotion(
                        label=action.label,
                        arm=arm,
                        grasp=np.asarray(action.grasp, dtype=float),
                        place=np.asarray(action.place, dtype=float),  # a spread's: its release
                        steps=len(steps),
                        seconds=float(sum(self.step_seconds(s) for s in steps)),
                    )
                )
        finally:
            self.use_arm(previous)
        self.gate.ask(motions)

    def confirm_move(self, move: ArmMove) -> None:
        """Before a park or the lift after a missed grasp moves: with a gate, what it will do is
        said and the operator's answer awaited (OperatorStopped on stop); without one, nothing."""
        if self.gate is not None:
            self.gate.ask([move])

    @abc.abstractmethod
    def run_step(self, step: Any) -> StepLog:
        """Move along one planned step, then apply its gripper event (close → grasp result)."""

    @abc.abstractmethod
    def release_and_lift(self) -> None:
        """After a failed grasp: open the gripper and move straight up (the retreat height); a
        cell with a gate asks first (confirm_move, lift_move)."""

    @abc.abstractmethod
    def park(self) -> None:
        """Move the arms (joint space) to their park poses, out of the camera's way; a cell with
        a gate asks first where an arm will move (confirm_move, park_move)."""

    @abc.abstractmethod
    def wait(self, seconds: float) -> None:
        """Let the cloth come to rest for `seconds` of cell time."""

    @property
    def arms(self) -> int:
        """Arms in the cell; a cell with two implements the `*_together` methods."""
        return 1

    @property
    def active_arm(self) -> int:
        """The arm single actions use now (use_arm; a cell may switch to another arm in
        plan_action when this one cannot do the action)."""
        return 0

    def use_arm(self, arm: int) -> None:
        """Make `arm` the one plan_action, run_step, release_and_lift and the loop's single
        actions use (a one-arm cell has only arm 0)."""
        if arm != 0:
            raise ValueError(f"this cell has one arm (0), got arm {arm!r}")

    def arm_for(self, point: np.ndarray) -> int:
        """The arm that should handle a grasp at `point`: the one on its side of the cell."""
        return 0

    def plan_on_an_able_arm(self, plan_with: Callable[[int], list[Any]]) -> list[Any]:
        """plan_with(arm) for the active arm first and, when it cannot do the action
        (UnreachableTargetError: IK, or it would meet another arm where that one stands), for
        the others in turn; the arm that can becomes the active one. The first arm's error when
        none can."""
        order = [self.active_arm] + [i for i in range(self.arms) if i != self.active_arm]
        first_error: UnreachableTargetError | None = None
        for arm in order:
            try:
                plan = plan_with(arm)
            except UnreachableTargetError as exc:
                first_error = first_error or exc
                continue
            self.use_arm(arm)
            return plan
        assert first_error is not None
        raise first_error

    def plan_together(self, actions: list[tuple[int, FoldAction]]) -> list[list[Any]]:
        """Two-arm cells: each (arm, action)'s motion steps, every waypoint's IK solved before
        anything moves (UnreachableTargetError names the infeasible one), the arms checked to
        keep clear of each other (ArmsWouldCollideError)."""
        raise NotImplementedError("this cell has one arm")

    def run_together(self, steps: list[tuple[int, Any]]) -> list[StepLog]:
        """Two-arm cells: move each arm along its step at once, then apply the gripper events."""
        raise NotImplementedError("this cell has one arm")

    def release_and_lift_arm(self, arm: int) -> None:
        """Open `arm`'s gripper and lift it straight up (the active arm stays as it was)."""
        previous = self.active_arm
        self.use_arm(arm)
        try:
            self.release_and_lift()
        finally:
            self.use_arm(previous)

    def start_stage(self, stage: int) -> bool:
        """Called before stage `stage` (≥ 1) is planned; True when the previous stage's closing
        observation is stale for planning (the oracle switches corner sources)."""
        return False

    def show(self, state: ClothState | None = None, **overlay: Any) -> None:  # noqa: B027
        """Debug overlay for the video: the latest state and planned points / fold line."""
