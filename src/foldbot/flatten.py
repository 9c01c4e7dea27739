"""The closed flattening loop — observe → stop at the target coverage, else plan a pull → execute
→ park → re-observe — written once against `cell.FoldCell`, from perception only.

The robot knows the item's nominal flat size (the task names the towel), never the cloth's state:
perceived coverage is the perceived top-view area over that expected area.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from foldbot import metrics
from foldbot.carry import (
    execute_action,
    execute_together,
    line_points,
    missed_grasps,
    pair_attempt,
)
from foldbot.cell import FoldCell
from foldbot.errors import (
    ArmsWouldCollideError,
    FoldbotError,
    UnreachableTargetError,
    add_facts,
    failed_segment,
    require,
)
from foldbot.perception.overlay import contact_sheet, draw_overlay
from foldbot.perception.state import ClothState
from foldbot.planning.flatten import (
    ExpectedOutline,
    FlattenConfig,
    Pull,
    cloth_surface,
    expected_outline_world,
    perceived_coverage,
    plan_pulls,
)
from foldbot.planning.spread import (
    MARGIN_FREE_SEGMENTS,
    SpreadConfig,
    SpreadPlan,
    corner_pairs,
    plan_spread,
)
from foldbot.types import Observation


@dataclass
class FlattenRecord:
    """What a flattening run did, for result.json: one entry per pull, and where it ended."""

    actions: list[dict] = field(default_factory=list)
    """Per pull: label, target, grasp, place, fold_line, grasp_success, grasp_reason,
    grasped_vertices, retries, attempts (grasp point and outcome of each try), coverage_before,
    coverage_after (perceived), shortfall_m, palm_clear, skipped_unreachable, sim_seconds,
    wall_seconds."""
    initial_coverage: float = 0.0
    """Perceived coverage before the first pull."""
    final_coverage: float = 0.0
    """Perceived coverage after the last pull."""
    reached: bool = False
    """True when the perceived coverage reached the target."""
    final_state: ClothState | None = None
    final_obs: Observation | None = None
    overlays: list[np.ndarray] = field(default_factory=list)
    """Per pull, the view it was planned from with its grasp, place and expected rectangle
    drawn; then the view it ended on."""
    captions: list[str] = field(default_factory=list)
    """One line per overlay: the pull and the perceived coverage it went from and to."""

    def sheet(self) -> np.ndarray | None:
        """The overlays tiled into one picture (flatten.png), or None before any observation."""
        return contact_sheet(self.overlays, self.captions) if self.overlays else None

    def finish(
        self,
        coverage: float,
        target: float,
        state: ClothState,
        obs: Observation,
        expected: np.ndarray | None = None,
    ) -> FlattenRecord:
        """End the run at perceived `coverage` (against `target`) on the view `obs` / `state`,
        pictured last (with the `expected` outline where the run had one); returns self."""
        self.final_coverage = coverage
        self.reached = coverage >= target
        self.overlays.append(draw_overlay(obs, state, expected_outline=expected))
        self.captions.append(
            f"end: {coverage:.2f}"
            + (" (target reached)" if self.reached else f" (target {target:.2f})")
        )
        self.final_state, self.final_obs = state, obs
        return self

    @property
    def actions_made(self) -> int:
        """Pulls or spreads that moved the arm (those skipped as unreachable left out)."""
        return sum(not a.get("skipped_unreachable", False) for a in self.actions)

    def perceived_entry(self, max_actions: int, policy: str = "vision") -> dict[str, Any]:
        """What the camera says of the flattening: the actions, the perceived coverages and
        whether the target was reached; all a cell without ground truth can record. `policy`
        names what planned the pulls ("vision", or "oracle")."""
        return {
            "policy": policy,
            "actions": self.actions_made,
            "max_actions": max_actions,
            "perceived_coverage_start": self.initial_coverage,
            "perceived_coverage_end": self.final_coverage,
            "reached_target": self.reached,
            "pulls": self.actions,
        }

    def result_entry(
        self, coverage_start: float, coverage_end: float, max_actions: int, policy: str = "vision"
    ) -> dict[str, Any]:
        """result.json's "flatten" entry: perceived_entry's, with the success and the two
        coverages, GROUND TRUTH (metrics only), measured by the caller before and after
        flattening."""
        n = self.actions_made
        return {
            "success": bool(metrics.flatten_success(coverage_end) and n <= max_actions),
            "coverage_start": coverage_start,
            "coverage_end": coverage_end,
        } | self.perceived_entry(max_actions, policy)


PullOracle = Callable[[ClothState, FlattenConfig], tuple[np.ndarray, list[Pull]]]
"""Plans pulls from ground truth instead of perception: (the outline it aims for as world points,
the pulls, best first); see sim.flatten_oracle."""


def run_flatten(
    cfg: FlattenConfig,
    cell: FoldCell,
    expected_size: tuple[float, float],
    log: Callable[[str], None] = print,
    oracle: PullOracle | None = None,
    record: FlattenRecord | None = None,
    spread: SpreadConfig | None = None,
) -> FlattenRecord:
    """Flatten the cloth on `cell` with pick-and-place pulls until its perceived coverage of
    the item's expected `(width, height)` (m) reaches `cfg.target_coverage` (on to
    `cfg.finish_coverage` where that is higher: finishing pulls), or `cfg.max_actions`. The
    pulls are planned from perception, or by `oracle` (ground truth, for comparison). A two-arm
    cell spreads the towel instead (run_spreads, by `spread` or SpreadConfig's defaults; the
    oracle still pulls).
    Fills and returns `record` (a new one if None), so a caller holding it keeps the pulls made
    before an error; the pull an error stopped gets its overlay, captioned with the error."""
    rec = FlattenRecord() if record is None else record
    if oracle is None and cell.arms == 2:
        return run_spreads(cfg, spread or SpreadConfig(), cell, expected_size, log, rec)
    width, height = (float(v) for v in expected_size)
    area = width * height
    cell.park()
    state, obs = cell.observe()
    if not state.detected:
        raise FoldbotError(f"no cloth found to flatten: {state.reason}")
    coverage = rec.initial_coverage = perceived_coverage(state, area)
    log(f"flatten: perceived coverage {coverage:.2f} (target {cfg.target_coverage:.2f})")
    yaw, expected = None, None
    stop = _Stop(cfg, log)
    missed: list[np.ndarray] = []  # where earlier pulls' every try missed (world xy, m)
    while len(rec.actions) < cfg.max_actions and not stop.reached(coverage):
        if oracle is not None:
            expected, pulls = oracle(state, cfg)
        else:
            fit, pulls, expected = pulls_from_view(cfg, state, obs, (width, height), yaw)
            if cfg.keep_yaw:
                yaw = fit.yaw
        if not pulls:
            log("flatten: no point of the expected outline is short enough to pull")
            break
        pulls = away_from_misses(pulls, missed, cfg.missed_radius, log)
        before = coverage
        state, obs, coverage = _pull_step(
            cfg, cell, state, obs, pulls, expected, coverage, area, rec, log
        )
        if not rec.actions[-1]["grasp_success"]:
            missed += [np.asarray(a["grasp"][:2], dtype=float) for a in rec.actions[-1]["attempts"]]
        stop.pulled(before, coverage)
    return rec.finish(coverage, cfg.target_coverage, state, obs, expected)


def away_from_misses(
    pulls: list[Pull], missed: list[np.ndarray], radius: float, log: Callable[[str], None]
) -> list[Pull]:
    """`pulls` with those whose grasp lies within `radius` (m) of a `missed` spot (world xy)
    moved after the others, in their order; all of them where every pull lies near one."""
    if not missed or radius <= 0.0:
        return pulls
    spots = np.asarray(missed, dtype=float)

    def near(pull: Pull) -> bool:
        gap = np.linalg.norm(spots - np.asarray(pull.action.grasp[:2], dtype=float), axis=1)
        return bool(gap.min() <= radius)

    away = [p for p in pulls if not near(p)]
    if away and away[0] is not pulls[0]:
        log(
            f"  {pulls[0].action.label}: its grasp lies within {radius * 1000:.0f} mm of where "
            f"a pull missed; {away[0].action.label} first"
        )
    return away + [p for p in pulls if near(p)]


@dataclass
class _Stop:
    """When flattening stops: at the target coverage, or where `cfg.finish_coverage` is higher,
    on to it by finishing pulls, until one of them takes the coverage back under the target
    (a pull that made things worse is not repeated until the actions run out)."""

    cfg: FlattenConfig
    log: Callable[[str], None]
    finishing: bool = True

    def reached(self, coverage: float) -> bool:
        """Whether flattening stops at perceived `coverage` (logs a finishing pull's start)."""
        if coverage < self.cfg.target_coverage:
            return False
        if not self.finishing or coverage >= self.cfg.stop_coverage:
            return True
        self.log(f"  coverage {coverage:.2f} is under {self.cfg.stop_coverage:.2f}: finishing")
        return False

    def pulled(self, before: float, after: float) -> None:
        """Note a pull that took the perceived coverage from `before` to `after`."""
        if self.finishing and before >= self.cfg.target_coverage > after:
            self.finishing = False
            self.log("  the finishing pull lost the target: no more finishing pulls")


def pulls_from_view(
    cfg: FlattenConfig,
    state: ClothState,
    obs: Observation,
    expected_size: tuple[float, float],
    yaw: float | None = None,
) -> tuple[ExpectedOutline, list[Pull], np.ndarray]:
    """The pulls planned from one view of the cloth (plan_pulls on the heap's surface as the
    depth shows it; `yaw`: the rectangle's kept from an earlier pull, None: fitted afresh): the
    fitted rectangle, the pulls in the order they are tried, and the outline they aim at
    (world)."""
    width, height = expected_size
    surface = cloth_surface(obs, state, cfg)
    fit, pulls = plan_pulls(state, width, height, cfg, surface, yaw)
    return fit, pulls, expected_outline_world(fit, state.table_plane)


def stops_at(cfg: FlattenConfig, coverage: float) -> bool:
    """Whether flattening would make no pull at all from a perceived `coverage` (its first
    stop test, finishing pulls included)."""
    return _Stop(cfg, lambda _line: None).reached(coverage)


def flatten_pictured(
    cfg: FlattenConfig,
    cell: FoldCell,
    expected_size: tuple[float, float],
    write_image: Callable[[str, np.ndarray], object],
    log: Callable[[str], None] = print,
    oracle: PullOracle | None = None,
    spread: SpreadConfig | None = None,
    record: FlattenRecord | None = None,
) -> FlattenRecord:
    """run_flatten, then its pictures: overlay_flattened.png, the view it ended on, and
    flatten.png, each pull over the view it was planned from, then the view it ended on; after
    an error, flatten.png with the pulls up to it (the episode's `DIR.failed/` keeps it), then
    the error. Fills and returns `record` (a new one if None)."""
    record = FlattenRecord() if record is None else record
    try:
        run_flatten(cfg, cell, expected_size, log, oracle, record, spread)
    except Exception:
        sheet = record.sheet()
        if sheet is not None:
            with contextlib.suppress(Exception):  # the error itself is what must surface
                write_image("flatten.png", sheet)
        raise
    if record.final_obs is not None and record.final_state is not None:
        write_image("overlay_flattened.png", draw_overlay(record.final_obs, record.final_state))
    sheet = record.sheet()
    if sheet is not None:
        write_image("flatten.png", sheet)
    return record


def flatten_and_score(
    cell: FoldCell,
    expected_size: tuple[float, float],
    crumpled: np.ndarray,
    ground_truth: Callable[[], np.ndarray],
    faces: np.ndarray,
    flat_area: float,
    write_image: Callable[[str, np.ndarray], object],
    log: Callable[[str], None] = print,
    oracle: PullOracle | None = None,
    cfg: FlattenConfig | None = None,
    spread: SpreadConfig | None = None,
) -> tuple[dict[str, Any], np.ndarray]:
    """Flatten a crumpled cloth on `cell` (flatten_pictured, by `cfg` and `spread` or their
    defaults: the episode's flatten options, foldbot.flatten_options) and score it,
    in process or over ROS alike. `crumpled` (the cloth's vertices now) and `ground_truth` (read
    after flattening) are GROUND TRUTH, for the coverages only; `oracle` plans the pulls from
    ground truth instead of perception (the entry's "policy"). Returns result.json's "flatten"
    entry and the flattened cloth's vertices."""
    start = metrics.coverage(crumpled, faces, flat_area)
    # Ground truth, for the record only: a simulated cloth that has passed through itself is
    # tangled, which a real one never is and no flattening undoes (docs/experiments.md).
    crossings = metrics.self_crossings(crumpled, faces)
    log(
        f"crumpled: coverage {start:.2f}"
        + (f", passed through itself ({crossings} edges cross it)" if crossings else "")
        + "; flattening…"
    )
    cfg = FlattenConfig() if cfg is None else cfg
    record = FlattenRecord()
    try:
        flatten_pictured(cfg, cell, expected_size, write_image, log, oracle, spread, record)
    except Exception as exc:
        add_facts(
            exc,
            flatten={
                "success": False,
                "actions": record.actions_made,
                "coverage_start": start,
                "self_crossings_start": crossings,
                "ended_in_error": True,
            },
        )
        raise
    flattened = ground_truth()
    end = metrics.coverage(flattened, faces, flat_area)
    entry = record.result_entry(
        start, end, cfg.max_actions, "vision" if oracle is None else "oracle"
    )
    entry["self_crossings_start"] = crossings
    entry["self_crossings_end"] = metrics.self_crossings(flattened, faces)
    log(
        f"flattened: coverage {start:.2f} → {end:.2f} in {entry['actions']} actions"
        + (
            f"; the simulated cloth has passed through itself ({entry['self_crossings_end']} "
            "edges cross it)"
            if entry["self_crossings_end"]
            else ""
        )
    )
    return entry, flattened


def _pull_step(
    cfg: FlattenConfig,
    cell: FoldCell,
    state: ClothState,
    obs: Observation,
    pulls: list[Pull],
    expected: np.ndarray | None,
    coverage: float,
    area: float,
    rec: FlattenRecord,
    log: Callable[[str], None],
) -> tuple[ClothState, Observation, float]:
    """One flattening pull (the first reachable of `pulls`, _execute_pull), then park, settle
    and re-observe; recorded in `rec` with its picture (after an error too, captioned with it).
    Returns the state, observation and perceived coverage (of `area`) it ends on."""
    t_sim, t_wall = cell.sim_time, time.perf_counter()
    try:
        pull, outcome, attempts, skipped = _execute_pull(cfg, cell, state, pulls, expected, log)
        action = pull.action
        cell.park()
        cell.wait(cfg.settle_time)
        new_state, new_obs = cell.observe()
    except Exception as exc:  # diverged, unreachable …: the picture shows what was tried
        planned = pulls[0].action
        rec.overlays.append(
            draw_overlay(
                obs,
                state,
                grasp_points=[planned.grasp],
                place_points=[planned.place],
                expected_outline=expected,
            )
        )
        rec.captions.append(
            f"{len(rec.actions) + 1}: {planned.label} {coverage:.2f} -> "
            f"stopped ({type(exc).__name__})"
        )
        raise
    after = perceived_coverage(new_state, area)
    log(
        f"flatten {len(rec.actions) + 1}: {action.label} "
        f"({pull.shortfall * 1000:.0f} mm short) → coverage {coverage:.2f} → {after:.2f}"
        + ("" if outcome["grasp_success"] else f", grasp failed: {outcome['grasp_reason']}")
    )
    rec.actions.append(
        pull_entry(pull, outcome, attempts, skipped, coverage, after)
        | {"sim_seconds": cell.sim_time - t_sim, "wall_seconds": time.perf_counter() - t_wall}
    )
    rec.overlays.append(
        draw_overlay(
            obs,
            state,
            grasp_points=[attempts[-1]["grasp"]],
            place_points=[action.place],
            expected_outline=expected,
        )
    )
    rec.captions.append(
        f"{len(rec.actions)}: {action.label} {coverage:.2f} -> {after:.2f}"
        + ("" if outcome["grasp_success"] else " (missed)")
    )
    if not new_state.detected:
        raise FoldbotError(
            f"the cloth was lost after flattening pull {len(rec.actions)} "
            f"({action.label}): {new_state.reason}"
        )
    return new_state, new_obs, after


def pull_entry(
    pull: Pull, outcome: dict, attempts: list[dict], skipped: int, before: float, after: float
) -> dict[str, Any]:
    """A pull's FlattenRecord entry (without its times): what was planned, the grasp tried
    last, its outcome and the perceived coverage it went from and to."""
    return {
        "kind": "flatten_pull",
        **dataclasses.replace(pull.action, grasp=np.asarray(attempts[-1]["grasp"])).as_dict(),
        "target": pull.target,
        "shortfall_m": pull.shortfall,
        "palm_clear": pull.palm_ok,
        "grasp_success": outcome["grasp_success"],
        "grasp_reason": outcome["grasp_reason"],
        "grasped_vertices": outcome["grasped_vertices"],
        "max_tracking_error_m": outcome["max_tracking_error"],
        "retries": len(attempts) - 1,
        "attempts": attempts,
        "skipped_unreachable": skipped,
        "coverage_before": before,
        "coverage_after": after,
    }


def _execute_pull(
    cfg: FlattenConfig,
    cell: FoldCell,
    state: ClothState,
    pulls: list[Pull],
    expected: np.ndarray,
    log: Callable[[str], None],
) -> tuple[Pull, dict, list[dict], int]:
    """Run the first reachable pull; after a failed grasp (the jaws closed between the mesh's
    cloth points or beside the cloth) retry up to `cfg.retries` times, each `cfg.retry_step`
    further inside the cloth. Returns the pull, its outcome, the attempts and how many pulls
    were skipped as unreachable."""
    skipped = 0
    for pull in pulls:
        action, attempts = pull.action, []
        inward = action.grasp[:2] - action.place[:2]
        inward = inward / max(float(np.linalg.norm(inward)), 1e-9)
        try:
            while True:
                cell.show(
                    state,
                    grasp_points=[action.grasp],
                    place_points=[action.place],
                    fold_line=line_points(action.fold_line, cell.table_height),
                    expected_outline=expected,
                )
                outcome = execute_action(cell, action)
                attempts.append(
                    {
                        "grasp": [float(v) for v in action.grasp],
                        "grasp_success": outcome["grasp_success"],
                        "grasp_reason": outcome["grasp_reason"],
                    }
                )
                if outcome["grasp_success"] or len(attempts) > cfg.retries:
                    return pull, outcome, attempts, skipped
                log(f"  grasp failed ({outcome['grasp_reason']}); retrying further in")
                grasp = action.grasp + np.r_[inward * cfg.retry_step, 0.0]
                action = dataclasses.replace(action, grasp=grasp)
        except UnreachableTargetError as exc:
            if attempts:
                raise
            skipped += 1  # planned before anything moved: try the next target
            log(f"  {action.label} unreachable ({exc}); next target")
    raise UnreachableTargetError(f"every flattening pull ({len(pulls)}) is out of the arm's reach")


def run_spreads(
    cfg: FlattenConfig,
    spread: SpreadConfig,
    cell: FoldCell,
    expected_size: tuple[float, float],
    log: Callable[[str], None] = print,
    record: FlattenRecord | None = None,
) -> FlattenRecord:
    """Flatten the towel on a two-arm `cell` by spreads (planning.spread: two adjacent perceived
    corners lifted, spread, hung and laid) until its perceived coverage of the expected
    `(width, height)` (m) reaches `cfg.target_coverage`, or `cfg.max_actions` spreads. Fills and
    returns `record` as run_flatten does; each spread's entry has kind "flatten_spread", and
    where no spread is feasible the action is one pull (kind "flatten_pull"). Pulls by one arm
    also go on past the target up to `cfg.finish_coverage` (finishing pulls), and replace the
    spread from `spread.pull_from` up, where those are set."""
    require(cell.arms == 2, f"a spread needs a two-arm cell, this one has {cell.arms}")
    width, height = (float(v) for v in expected_size)
    area = width * height
    rec = FlattenRecord() if record is None else record
    cell.park()
    state, obs = cell.observe()
    if not state.detected:
        raise FoldbotError(f"no cloth found to flatten: {state.reason}")
    coverage = rec.initial_coverage = perceived_coverage(state, area)
    log(f"flatten: perceived coverage {coverage:.2f} (target {cfg.target_coverage:.2f}), spreading")
    laid = None  # where the last spread that carried the towel let go
    missed_corners = None  # the corners whose grasps the last spread missed (its retry too)
    stop = _Stop(cfg, log)
    while len(rec.actions) < cfg.max_actions and not stop.reached(coverage):
        if coverage >= cfg.target_coverage:  # a finishing pull
            pulled = _pull_instead(cfg, cell, state, obs, expected_size, log, rec)
            if pulled is None:
                break
            before, (state, obs, coverage) = coverage, pulled
            stop.pulled(before, coverage)
            continue
        if spread.pull_from is not None and coverage >= spread.pull_from:
            log(f"  coverage {coverage:.2f} is {spread.pull_from:.2f} or more: a pull")
            pulled = _pull_instead(cfg, cell, state, obs, expected_size, log, rec)
            if pulled is not None:
                state, obs, coverage = pulled
                continue
        t_sim, t_wall = cell.sim_time, time.perf_counter()
        seen_state, seen_obs = state, obs
        attempts: list[dict] = []
        plan, tried = None, []
        # An injected fault (tests) misaims the first action only.
        this = spread if not rec.actions else dataclasses.replace(spread, fault_grasp_offset=0.0)
        try:
            for attempt in range(cfg.retries + 1):
                inset = this.grasp_inset + attempt * cfg.retry_step
                done = _spread_once(
                    cfg, dataclasses.replace(this, grasp_inset=inset), cell, state, obs,
                    expected_size, log, laid, tried, missed_corners,
                )  # fmt: skip
                if done is None:
                    break
                plan, outcomes = done
                attempts.append(pair_attempt(plan.actions, outcomes) | _tool_record(plan))
                cell.park()
                cell.wait(cfg.settle_time)
                state, obs = cell.observe()
                if outcomes[0]["carried"] or not state.detected:
                    break
                log(
                    f"  grasp failed ({missed_grasps(plan.actions, outcomes)}); "
                    "both arms let go, re-observed"
                )
        except Exception as exc:  # diverged, unreachable …: the picture shows what was tried
            shown = tried[-1].actions if tried else ()
            rec.overlays.append(
                draw_overlay(
                    seen_obs,
                    seen_state,
                    grasp_points=[a.grasp for a in shown] or None,
                    place_points=[a.release for a in shown] or None,
                )
            )
            rec.captions.append(
                f"{len(rec.actions) + 1}: spread {coverage:.2f} -> stopped ({type(exc).__name__})"
            )
            raise
        if plan is None:  # not one spread feasible: one pull instead, by the arm beside it
            log("  no spread is feasible here; one pull instead")
            pulled = _pull_instead(cfg, cell, state, obs, expected_size, log, rec)
            if pulled is None:
                raise FoldbotError(
                    "no spread is feasible and no point of the outline is short to pull"
                )
            state, obs, coverage = pulled
            continue
        after = perceived_coverage(state, area) if state.detected else 0.0
        if outcomes[0]["carried"]:
            laid, missed_corners = np.array([a.release for a in plan.actions]), None
        else:
            missed_corners = seen_state.keypoint_array(plan.corners)
        log(
            f"flatten {len(rec.actions) + 1}: spread {' + '.join(plan.corners)} "
            f"({plan.width * 1000:.0f} mm apart, hung {plan.margin * 1000:.0f} mm clear"
            + (
                f", tools tilted {math.degrees(plan.actions[0].tilt):.0f}°"
                if plan.actions[0].tilt
                else ""
            )
            + ") "
            f"→ coverage {coverage:.2f} → {after:.2f}"
            + ("" if outcomes[0]["carried"] else ", grasp failed")
        )
        rec.actions.append(
            {
                "kind": "flatten_spread",
                "label": "spread " + " + ".join(plan.corners),
                "arms": [a.as_dict() for a in plan.actions],
                "spread_width_m": plan.width,
                "hang_m": plan.hang,
                "hang_margin_m": plan.margin,
                "grasp_success": bool(outcomes[0]["carried"]),
                "grasp_reason": "; ".join(o["grasp_reason"] for o in outcomes),
                "grasped_vertices": [o["grasped_vertices"] for o in outcomes],
                "max_tracking_error_m": max(o["max_tracking_error"] for o in outcomes),
                "retries": len(attempts) - 1,
                "attempts": attempts,
                "plans_tried": len(tried),
                "coverage_before": coverage,
                "coverage_after": after,
                "sim_seconds": cell.sim_time - t_sim,
                "wall_seconds": time.perf_counter() - t_wall,
            }
        )
        rec.overlays.append(
            draw_overlay(
                seen_obs,
                seen_state,
                grasp_points=[a.grasp for a in plan.actions],
                place_points=[a.release for a in plan.actions],
            )
        )
        rec.captions.append(
            f"{len(rec.actions)}: spread {coverage:.2f} -> {after:.2f}"
            + ("" if outcomes[0]["carried"] else " (missed)")
        )
        coverage = after
        if not state.detected:
            raise FoldbotError(
                f"the cloth was lost after flattening spread {len(rec.actions)}: {state.reason}"
            )
    return rec.finish(coverage, cfg.target_coverage, state, obs)


def _spread_once(
    cfg: FlattenConfig,
    spread: SpreadConfig,
    cell: FoldCell,
    state: ClothState,
    obs: Observation,
    expected_size: tuple[float, float],
    log: Callable[[str], None],
    laid: np.ndarray | None = None,
    tried: list[SpreadPlan] | None = None,
    missed: np.ndarray | None = None,
) -> tuple[SpreadPlan, list[dict]] | None:
    """Plan a spread on the observation and run it (carry.execute_together: both arms planned
    before anything moves, on one clock; a missed grasp lets both go), holding the towel as
    high as the arms reach: the surest pair of corners whose grasps keep the palm clear of the
    heap, at each of `spread.hang_margins` in turn, then the next pair, until one is feasible
    (a pair on one side of the cell can bring the arms together); where none is, gripper
    down, every pair again with the tools tilted apart (`spread.grasp_tilt`). `laid`: where the last
    spread let go (corner_pairs ranks that edge late), `missed`: the corners whose grasps the last
    spread missed (ranked last); each plan tried is appended to `tried`
    (the picture after an error shows the last). None when no pair is feasible at any margin
    or tilt (nothing moved; the log names why each was not)."""
    surface = cloth_surface(obs, state, cfg)
    pairs = [
        pair
        for pair in corner_pairs(state, laid, missed=missed)
        if plan_spread(state, expected_size, spread, cfg, surface, pair=pair).palm_clear
    ]
    if not pairs:
        log("  every pair of corners lies where the palm would press into the heap")
    lean = spread.grasp_lean
    for tilt in (0.0, spread.grasp_tilt) if spread.grasp_tilt else (0.0,):
        for pair in pairs:
            for margin in spread.hang_margins:
                plan = plan_spread(
                    state, expected_size, spread, cfg, surface, margin, pair, tilt, lean
                )
                if not plan.palm_clear:  # a lean lowers the palm's edge (spread._palm_heap)
                    log(
                        f"  {' + '.join(pair)}: the palm, tools tilted {math.degrees(tilt):.0f}°, "
                        "would press into the heap"
                    )
                    break
                cell.show(
                    state,
                    grasp_points=[a.grasp for a in plan.actions],
                    place_points=[a.release for a in plan.actions],
                )
                if tried is not None:
                    tried.append(plan)
                try:
                    return plan, execute_together(
                        cell, [(0, plan.actions[0]), (1, plan.actions[1])]
                    )
                except (UnreachableTargetError, ArmsWouldCollideError) as exc:
                    tilted = f", tools tilted {math.degrees(tilt):.0f}°" if tilt else ""
                    log(
                        f"  spread infeasible ({' + '.join(pair)} hung {margin * 1000:.0f} mm "
                        f"clear{tilted}: {exc})"
                    )
                    if failed_segment(exc) in MARGIN_FREE_SEGMENTS:
                        break  # the way to the corners fails at any margin: next pair
    return None


def _tool_record(plan: SpreadPlan) -> dict:
    """How a spread's tools were held at its grasps, for result.json: the +y arm's tilt (rad; 0
    gripper down) and, tilted, each arm's lean heading (rad about z from +x)."""
    tilt = plan.actions[0].tilt
    headings = {"tool_headings_rad": [a.tilt_heading for a in plan.actions]} if tilt else {}
    return {"tool_tilt_rad": tilt} | headings


def _pull_instead(
    cfg: FlattenConfig,
    cell: FoldCell,
    state: ClothState,
    obs: Observation,
    expected_size: tuple[float, float],
    log: Callable[[str], None],
    rec: FlattenRecord,
) -> tuple[ClothState, Observation, float] | None:
    """One flattening pull by the arm on the grasp's side (run_flatten's _pull_step), recorded
    in `rec` as one of the flattening actions; returns the state, observation and perceived
    coverage it ends on, or None where no point of the expected outline is short enough to pull
    (logged; nothing moved)."""
    width, height = (float(v) for v in expected_size)
    _fit, pulls, expected = pulls_from_view(cfg, state, obs, (width, height))
    if not pulls:
        log("  no point of the expected outline is short enough to pull")
        return None
    area = width * height
    coverage = perceived_coverage(state, area)
    return _pull_step(cfg, cell, state, obs, pulls, expected, coverage, area, rec, log)
