"""One towel episode simulated in a process of its own, driven by pick-and-place steps: a
crumpled towel to flatten (TowelFlatten, TowelSpread) or a flat one to fold (TowelFold).

Bullet's soft-body solver keeps process-global state, so an episode reproduces from its seed only
as the first simulation in its process (README, Determinism): a second crumple in one process
lands centimetres elsewhere. Each episode of an environment therefore runs in a fresh child
process (forked from a process that has imported foldbot and simulated nothing: fork_server; as
`foldbot bench` gives each episode a fresh worker; not multiprocessing's spawn, which would re-run
an unguarded caller's script), talking over a socket pair; only small values cross it: the
camera's frame and each step's outcome.
"""

from __future__ import annotations

import contextlib
import socket
import traceback
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from foldbot import metrics
from foldbot.carry import assign_arms, execute_action, execute_together
from foldbot.envs import fork_server
from foldbot.errors import (
    ArmsWouldCollideError,
    ConfigError,
    FoldbotError,
    SimulationDivergedError,
    UnreachableTargetError,
    failed_segment,
)
from foldbot.flatten_options import flatten_configs
from foldbot.grasp_points import surface_height
from foldbot.metrics import FoldScore, score_episode
from foldbot.perception.state import ClothState
from foldbot.pipeline import (
    EpisodeConfig,
    SimCell,
    build_sim_cell,
    crumple_start,
    episode_cell,
    true_start_keypoints,
)
from foldbot.planning.actions import FoldAction
from foldbot.planning.flatten import FlattenConfig, cloth_surface, grasp_level, pull_action, table_z
from foldbot.planning.recipes import recipe_fold_lines
from foldbot.planning.spread import MARGIN_FREE_SEGMENTS, SpreadConfig, plan_spread_at
from foldbot.sim.cloth import settle
from foldbot.sim.world import SimWorld
from foldbot.types import Observation

_ENTRY = "foldbot.envs.episode_process:serve_socket"
"""What the child runs, given its socket's file descriptor (fork_server.start)."""
REPLY_TIMEOUT_S = 900.0
"""Longest wall time (s) one reset or step may take before the child is given up as hung."""


@dataclass(frozen=True)
class StepOutcome:
    """What one reset or pick-and-place step ended on: the camera's frame, the cloth's coverage
    (GROUND TRUTH, for the reward) and how the step went."""

    observation: Observation
    coverage: float
    """Top-view area of the cloth over its flat area (metrics.coverage, from the simulator)."""
    grasp_success: bool | None = None
    """Whether the jaws held cloth when they closed; None where no grasp was tried."""
    grasp_reason: str = ""
    infeasible: str | None = None
    """Why the arm could not do the step (nothing moved), or None."""
    grasp: tuple[float, ...] | None = None
    """Where the jaws closed (world, m), (x, y, z): the pick point at the height the step
    grasps at; a spread's two, the +y arm's first, (x, y, z, x, y, z); a fold pair's one per
    carry made, in the action's order."""
    place: tuple[float, ...] | None = None
    """Where the jaws opened (world, m), as `grasp`."""
    sim_seconds: float = 0.0
    """Simulated time the step took (s)."""
    fold: FoldScore | None = None
    """A fold episode's score of the cloth as it lies now against the recipe's goal (GROUND
    TRUTH: metrics.score_episode on the goal's fold lines); None for a flattening episode."""


class EpisodeFailed(FoldbotError):
    """The episode could not go on: a foldbot error in the child (the crumple threw the towel
    out of the workspace, the camera lost the cloth …); its message is the child's."""


class EpisodeDiverged(EpisodeFailed):
    """The simulated cloth blew up in the child; its message is the monitor's."""


def pick_and_place(
    cell: SimCell,
    state: ClothState,
    obs: Observation,
    pick_xy: np.ndarray,
    place_xy: np.ndarray,
    flatten: FlattenConfig,
) -> dict[str, Any]:
    """Grasp the cloth at `pick_xy` and let go over `place_xy` (world, m) with the cell's arm, as
    a flattening pull does: the grasp height comes from the depth image (raised so the palm
    clears heaped cloth), the release `flatten.release_height` over the table, the place kept
    `flatten.margin` inside the workspace, both planned on the frame the policy was shown (`obs`,
    seen as `state`). Park and settle after. Perception only, no ground truth; an unreachable
    step moves nothing and says why."""
    if not state.detected:
        raise FoldbotError(f"the cell's camera sees no cloth: {state.reason}")
    surface = cloth_surface(obs, state, flatten)
    level, _reaches = grasp_level(surface, pick_xy, flatten)
    grasp = np.array([pick_xy[0], pick_xy[1], table_z(state.table_plane, pick_xy) + level])
    action = pull_action(grasp, place_xy, state.table_plane, flatten, "pick-and-place")
    return carry_one(cell, action, flatten.settle_time)


def carry_one(cell: SimCell, action: FoldAction, settle_time: float) -> dict[str, Any]:
    """Run one arm's pick-and-place, then park and settle `settle_time`: the step's record
    (grasp, place, and how the grasp went, or why nothing moved)."""
    record: dict[str, Any] = {
        "grasp": tuple(float(v) for v in action.grasp),
        "place": tuple(float(v) for v in action.place),
    }
    try:
        outcome = execute_action(cell, action)
    except UnreachableTargetError as exc:
        return record | {"infeasible": str(exc)}
    cell.park()
    cell.wait(settle_time)
    return record | {
        "grasp_success": bool(outcome["grasp_success"]),
        "grasp_reason": str(outcome["grasp_reason"]),
    }


def spread_at(
    cell: SimCell,
    state: ClothState,
    obs: Observation,
    a_xy: np.ndarray,
    b_xy: np.ndarray,
    flatten: FlattenConfig,
    spread: SpreadConfig,
    expected_size: tuple[float, float],
) -> dict[str, Any]:
    """Grasp the cloth at table points `a_xy` and `b_xy` (world, m) with the two arms, lift,
    spread, hang and lay it as the two-arm flattening spreads do (planning.spread.plan_spread_at,
    at each of `spread.hang_margins` until both arms reach) on the frame the policy was shown,
    then park and settle. Perception only; a spread the arms cannot make, or whose palm would
    press into the heap, moves nothing and says why."""
    if not state.detected:
        raise FoldbotError(f"the cell's camera sees no cloth: {state.reason}")
    surface = cloth_surface(obs, state, flatten)
    why = ""
    for margin in spread.hang_margins:
        plan = plan_spread_at(state, (a_xy, b_xy), expected_size, spread, flatten, surface, margin)
        record: dict[str, Any] = {
            "grasp": tuple(float(v) for v in plan.actions[0].grasp)
            + tuple(float(v) for v in plan.actions[1].grasp),
            "place": tuple(float(v) for v in plan.actions[0].release)
            + tuple(float(v) for v in plan.actions[1].release),
        }
        if not plan.palm_clear:
            return record | {"infeasible": "the palm would press into the heap at a grasp"}
        try:
            outcomes = execute_together(cell, [(0, plan.actions[0]), (1, plan.actions[1])])
        except (UnreachableTargetError, ArmsWouldCollideError) as exc:
            why = f"hung {margin * 1000:.0f} mm clear: {exc}"
            if failed_segment(exc) in MARGIN_FREE_SEGMENTS:
                break  # the way to the grasps fails at any margin
            continue
        cell.park()
        cell.wait(flatten.settle_time)
        return record | {
            "grasp_success": bool(outcomes[0]["carried"]),
            "grasp_reason": "; ".join(o["grasp_reason"] for o in outcomes),
        }
    return record | {"infeasible": f"the arms cannot make this spread ({why})"}


def fold_carry_action(
    state: ClothState,
    obs: Observation,
    pick_xy: np.ndarray,
    place_xy: np.ndarray,
    stack_height: float,
    place_lift: float,
) -> FoldAction:
    """The fold carry from `pick_xy` to `place_xy` (world, m) on the frame seen (`obs`, seen as
    `state`): grasped `stack_height` over the perceived table, so the jaws close under every
    layer there, let go `place_lift` above the higher of the grasp and the surface seen at the
    place point (the layer it is laid on); its fold line the carry's mirror line."""
    if not state.detected:
        raise FoldbotError(f"the cell's camera sees no cloth: {state.reason}")
    grasp = np.array([pick_xy[0], pick_xy[1], table_z(state.table_plane, pick_xy) + stack_height])
    under = surface_height(
        obs, np.array([place_xy[0], place_xy[1], grasp[2]]), 2, state.table_plane
    )
    place_z = max(float(grasp[2]), -np.inf if under is None else under)
    place = np.array([place_xy[0], place_xy[1], place_z + place_lift])
    direction = place[:2] - grasp[:2]
    middle = (place[:2] + grasp[:2]) / 2
    return FoldAction(
        grasp=grasp,
        place=place,
        fold_line=(float(middle[0]), float(middle[1]), float(-direction[1]), float(direction[0])),
        label="fold carry",
    )


def fold_carry(
    cell: SimCell,
    state: ClothState,
    obs: Observation,
    pick_xy: np.ndarray,
    place_xy: np.ndarray,
    stack_height: float,
    place_lift: float,
    settle_time: float,
) -> dict[str, Any]:
    """Carry the cloth at `pick_xy` over to `place_xy` (world, m) with the cell's arm as a fold
    carries a folded stack's corner (fold_carry_action), over the half-sine arc; then park and
    settle `settle_time`. Planned on the frame the policy was shown; perception only. An
    unreachable carry moves nothing and says why."""
    action = fold_carry_action(state, obs, pick_xy, place_xy, stack_height, place_lift)
    return carry_one(cell, action, settle_time)


NO_CARRY = 0.01
"""A pair's carry shorter than this (m, pick to place) is no carry: that arm stays parked."""


def fold_pair(
    cell: SimCell,
    state: ClothState,
    obs: Observation,
    picks: np.ndarray,
    places: np.ndarray,
    stack_height: float,
    place_lift: float,
    settle_time: float,
) -> dict[str, Any]:
    """Two fold carries at once in the two-arm cell, picks[i] to places[i] (world, m; 2×2), as
    fold_carry_action shapes each: both arms on one clock, each on its grasp's side of the cell
    (assign_arms; the other way round where their motions would meet). A carry shorter than
    NO_CARRY is none: the other runs alone, with the arm on its side; none at all moves nothing.
    A missed grasp lets both go (nothing is carried by one arm of a pair); an unreachable pair
    moves nothing and says why. Then park and settle."""
    picks = np.asarray(picks, dtype=float).reshape(2, 2)
    places = np.asarray(places, dtype=float).reshape(2, 2)
    actions = [
        fold_carry_action(state, obs, p, q, stack_height, place_lift)
        for p, q in zip(picks, places, strict=True)
        if np.linalg.norm(q - p) >= NO_CARRY
    ]
    record: dict[str, Any] = {
        "grasp": tuple(float(v) for a in actions for v in a.grasp),
        "place": tuple(float(v) for a in actions for v in a.place),
    }
    if not actions:
        return record | {"infeasible": f"no carry: both are shorter than {NO_CARRY * 100:g} cm"}
    if len(actions) == 1:
        cell.use_arm(cell.arm_for(actions[0].grasp))
        try:
            outcomes = [execute_action(cell, actions[0])]
        except UnreachableTargetError as exc:
            return record | {"infeasible": str(exc)}
    else:
        arms = assign_arms(cell.arm_for, tuple(actions))
        try:
            try:
                outcomes = execute_together(cell, list(zip(arms, actions, strict=True)))
            except ArmsWouldCollideError:
                outcomes = execute_together(cell, list(zip(arms[::-1], actions, strict=True)))
        except (UnreachableTargetError, ArmsWouldCollideError) as exc:
            return record | {"infeasible": f"the arms cannot make this pair of carries: {exc}"}
    cell.park()
    cell.wait(settle_time)
    return record | {
        "grasp_success": all(bool(o["grasp_success"]) for o in outcomes),
        "grasp_reason": "; ".join(str(o["grasp_reason"]) for o in outcomes),
    }


PRIMITIVES = ("pick_and_place", "spread", "fold", "fold_pair")
"""What one step does: one arm's pick-and-place (a flattening pull), two arms' spread, one arm's
fold carry, or two arms' fold carries at once."""


def _diverge_at(sim_time: float):
    """Fault injection: a world step hook that raises the divergence monitor's error once the
    simulated clock passes `sim_time` (s), to exercise the reporting path."""

    def hook(world: SimWorld) -> None:
        if world.sim_time >= sim_time:
            raise SimulationDivergedError(f"injected divergence at {world.sim_time:.3f} s")

    return hook


def _serve(conn: Connection) -> None:
    """The child: take ("episode", EpisodeConfig, fault, goal), build the cell, settle the towel
    and crumple it where the episode starts crumpled (the episode's seed), reply with the first
    frame, then run each ("step", primitive, p, q) (PRIMITIVES: pick at p and place at q, spread
    from p and q, or carry a fold from p to q) until ("close",) or the parent goes away. The
    pulls' and spreads' settings are the episode's flatten options. `fault`: None, or the
    simulated seconds into the first step at which a divergence is injected. `goal`: None, or
    the towel recipe each outcome's `fold` scores the cloth against (its fold lines planned on
    the settled towel's true corners, recipe_fold_lines)."""
    try:
        _kind, episode, fault, goal = conn.recv()
        pulls, spreads = flatten_configs(episode.flatten_options, episode.sim.layout)
        with SimWorld(episode.sim) as world:
            parts = build_sim_cell(episode, world)
            try:
                settle(world, parts.cloth)
                cell = episode_cell(episode, parts)
                size = (parts.spec.width, parts.spec.height)  # the item, as the suites tell it
                if episode.start == "crumpled":
                    crumple_start(episode, world, parts.cloth)
                faces, area = parts.mesh.faces, parts.mesh.area
                initial = parts.oracle.cloth_vertices()
                lines = None
                if goal is not None:
                    corners = true_start_keypoints(episode, parts.mesh, initial)
                    if corners is None:
                        raise ConfigError(f"a fold goal ({goal}) needs a flat towel to start")
                    lines = recipe_fold_lines(goal, corners)

                seen: list = []  # the frame last sent, (state, obs): the next step plans on it

                def outcome(t0: float, **step: Any) -> StepOutcome:
                    seen[:] = cell.observe()
                    now = parts.oracle.cloth_vertices()
                    cover = metrics.coverage(now, faces, area)
                    fold = None
                    if lines is not None:
                        fold = score_episode(initial, now, faces, lines, parts.cloth.thickness)
                    return StepOutcome(
                        seen[1], cover, sim_seconds=world.sim_time - t0, fold=fold, **step
                    )

                conn.send(("ok", outcome(world.sim_time)))
                if fault is not None:
                    world.add_step_hook(_diverge_at(world.sim_time + fault))
                while True:
                    message = conn.recv()
                    if message[0] == "close":
                        break
                    _kind, primitive, p, q = message
                    t0 = world.sim_time
                    if primitive == "spread":
                        step = spread_at(cell, *seen, p, q, pulls, spreads, size)
                    elif primitive in ("fold", "fold_pair"):
                        carry = fold_carry if primitive == "fold" else fold_pair
                        step = carry(
                            cell,
                            *seen,
                            p,
                            q,
                            episode.motion.stack_grasp_height,
                            episode.motion.place_lift,
                            pulls.settle_time,
                        )
                    else:
                        step = pick_and_place(cell, *seen, p, q, pulls)
                    conn.send(("ok", outcome(t0, **step)))
            finally:
                parts.model_world.close()
    except SimulationDivergedError as exc:
        conn.send(("diverged", str(exc)))
    except (EOFError, BrokenPipeError):  # the parent went away
        pass
    except FoldbotError as exc:
        conn.send(("failed", f"{type(exc).__name__}: {exc}"))
    except Exception as exc:  # a bug: its traceback goes to the parent
        conn.send(("error", f"{type(exc).__name__}: {exc}", traceback.format_exc()))
    finally:
        conn.close()


def serve_socket(fd: int) -> None:
    """The child's entry point: serve the episode over the socket inherited as `fd`."""
    _serve(Connection(fd))


class EpisodeProcess:
    """A towel episode running in a fresh child process: `first` is the frame it starts on;
    `step` runs one step (PRIMITIVES); `close` ends it. With a `goal` recipe each outcome also
    scores the fold (StepOutcome.fold). Raises EpisodeDiverged when the cloth blows up,
    EpisodeFailed for another foldbot error in the child, RuntimeError (with the child's
    traceback) for anything else."""

    def __init__(
        self,
        episode: EpisodeConfig,
        fault_diverge_s: float | None = None,
        goal: str | None = None,
    ) -> None:
        ours, theirs = socket.socketpair()
        with theirs:  # errors come back over the socket
            self._process = fork_server.start(_ENTRY, theirs.fileno())
        self._conn = Connection(ours.detach())
        self._conn.send(("episode", episode, fault_diverge_s, goal))
        self.first: StepOutcome = self._reply("reset")

    def step(self, primitive: str, p: np.ndarray, q: np.ndarray) -> StepOutcome:
        """Run one step: `primitive` (PRIMITIVES) from table points p and q (world, m; a pair's
        two picks and two places, 2×2 each)."""
        if primitive not in PRIMITIVES:
            raise ConfigError(f"unknown primitive {primitive!r}; allowed: {', '.join(PRIMITIVES)}")
        with contextlib.suppress(OSError):  # a child gone: the reply says so
            self._conn.send(("step", primitive, np.asarray(p, float), np.asarray(q, float)))
        return self._reply("step")

    def _reply(self, what: str) -> StepOutcome:
        if not self._conn.poll(REPLY_TIMEOUT_S):
            self.close()
            raise FoldbotError(f"the episode's {what} took longer than {REPLY_TIMEOUT_S:.0f} s")
        try:
            reply = self._conn.recv()
        except EOFError:
            self._process.ended(5.0)
            code = self._process.exit_code
            said = "" if code is None else f" (exit code {code})"
            raise FoldbotError(f"the episode's process ended during its {what}{said}") from None
        if reply[0] == "ok":
            return reply[1]
        self.close()
        if reply[0] == "diverged":
            raise EpisodeDiverged(reply[1])
        if reply[0] == "failed":
            raise EpisodeFailed(reply[1])
        raise RuntimeError(f"the episode's {what} failed: {reply[1]}\n{reply[2]}")

    @property
    def alive(self) -> bool:
        return not self._process.ended()

    def close(self) -> None:
        """End the child (politely, then by force) and release the socket; safe to call twice."""
        if self.alive and not self._conn.closed:
            with contextlib.suppress(OSError):
                self._conn.send(("close",))
            if not self._process.ended(10.0):
                self._process.kill()
                self._process.ended(5.0)
        self._conn.close()
        self._process.close()
