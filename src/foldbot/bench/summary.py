"""The field's metrics over a benchmark run: per group (garment × recipe × perception × loop),
overall, and side by side for the comparison axes (vision vs oracle, closed vs open loop).

Every figure comes from the episodes' records (result.json, or the error that ended an episode):
- success rate: successes / all episodes; an episode that ended in an error counts as a failure.
  With its 95 % Wilson score interval (`success_interval`): over 20 towels, 55 % is 34–74 %.
  Where towels were folded several times (replicates), at the effective number of episodes
  (`clustered_success_interval`): folds of one towel are not independent draws.
- the mean of each figure with its 95 % Student-t interval (`mean_interval`); a comparison adds
  the paired difference of the fold error (same towel both ways), with its interval.
- fold error (mm), SoftGym normalized performance (first fold) and coverage: over scored episodes.
- the fold error a physically perfect fold, lying flat, scores under metrics.md's layer rule.
- actions and retries per episode; simulated robot seconds per fold (one fold = one episode's
  whole recipe); wall seconds per episode; simulation speed = Σ simulated s / Σ wall s.
- failures grouped by cause (`failure_cause`).
- where towels were folded several times: how often each succeeds, and the fold error's spread
  within a towel against between towels (`replicate_stats`).
"""

from __future__ import annotations

import itertools
import math
import numbers
import re
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import numpy as np

from foldbot.bench.suite import Suite
from foldbot.verdict import lowest_stage_iou, perceived_verdict

CAUSES = (
    "fold inaccurate",
    "grasp failed",
    "diverged",
    "unreachable",
    "no cloth found",
    "cloth out of view",
    "planning failed",
    "perception failed",
    "timeout",
    "crashed",
)
"""Failure causes, most benign first. 'fold inaccurate': scored, every grasp held, but below the
success thresholds (normalized ≥ 0.8 and fold error ≤ 0.05·√area); 'grasp failed': scored, an
action ended without holding the cloth. The others ended the episode before it could be scored."""

COMPARISONS = (("perception", "vision", "oracle"), ("loop", "closed", "open"))
"""(axis, a, b): compared wherever a suite runs both values."""

REFERENCE_FIGURES = (
    ("FabricFlowNet", "square towel, one-step folds", "4.26 mm mean particle error"),
    ("FabricFlowNet", "square towel, multi-step folds", "23.74 mm mean particle error"),
    ("FabricFlowNet", "rectangular towel, one-step / multi-step", "4.25 mm / 16.79 mm"),
    ("FabricFlowNet", "T-shirt, one-step / multi-step", "24.46 mm / 45.97 mm"),
    ("FlingBot", "flattening, unseen cloths", "> 80 % coverage within 3 actions"),
    ("Deformable Ravens", "cloth-flat", "success = coverage ≥ 0.85 within 10 actions"),
    ("SpeedFolding (real robot)", "T-shirts", "93 % success, < 120 s per fold"),
)
"""The field's figures (shared/notes/metrics.md), reported beside ours."""


def failure_cause(record: dict) -> str | None:
    """Why an episode did not succeed (one of CAUSES, or 'other error (Type)'); None if it did."""
    if "result" in record:
        r = record["result"]
        if r.get("success"):
            return None
        if any(not a.get("grasp_success", True) for a in r.get("actions", [])):
            return "grasp failed"
        return "fold inaccurate"
    kind, msg = record.get("error_type", ""), record.get("error", "")
    by_type = {
        "SimulationDivergedError": "diverged",
        "UnreachableTargetError": "unreachable",
        "PerceptionError": "perception failed",
        "Timeout": "timeout",
        "Crashed": "crashed",
    }
    if kind in by_type:
        return by_type[kind]
    if "no cloth found" in msg:
        return "no cloth found"
    if "beyond the camera's view" in msg:
        return "cloth out of view"
    if "degenerate corner quad" in msg or "open loop: the outline" in msg:
        return "planning failed"
    return f"other error ({kind or 'unknown'})"


def evidence_path(record: dict) -> str:
    """Where, relative to the benchmark folder, to look at an episode: its folder when scored;
    what it recorded up to its error (`<id>.failed/`) when kept; else its error record."""
    if "result" in record:
        return f"episodes/{record['id']}"
    if record.get("failed_dir"):
        return f"episodes/{record['failed_dir']}"
    return f"episodes/{record['id']}.error.json"


def _finite(values: list[Any]) -> np.ndarray:
    a = np.array([v for v in values if v is not None], dtype=float)
    return a[np.isfinite(a)]


CONFIDENCE = 0.95
"""The level of every interval the summary gives."""


def success_interval(successes: int, n: int) -> list[float] | None:
    """The Wilson score interval (CONFIDENCE) of a success rate `successes / n`: unlike the
    normal approximation it stays within [0, 1] and is not empty at 0 % or 100 %; None for n = 0."""
    if n <= 0:
        return None
    if not 0 <= successes <= n:
        raise ValueError(f"successes = {successes} must lie in [0, n = {n}]")
    return _wilson(successes / n, float(n))


def clustered_success_interval(outcomes_by_towel: list[list[bool]]) -> list[float] | None:
    """Wilson's interval for a success rate over towels each folded one or more times (suite
    replicates), whose folds of one towel are not independent draws: the interval is taken at
    the effective number of episodes, n / deff (Kish), the design effect deff estimated from how
    much the towels' success counts scatter beyond what independent episodes would, and held
    between 1 (as independent as separate towels) and n / towels (each towel one draw). Where
    every episode succeeded, or none did, nothing tells the two apart and each towel counts
    once. Equals `success_interval` when every towel was folded once; None without episodes."""
    sizes = np.array([len(o) for o in outcomes_by_towel if o], dtype=float)
    wins = np.array([sum(bool(x) for x in o) for o in outcomes_by_towel if o], dtype=float)
    n, k = float(sizes.sum()), sizes.size
    if k == 0:
        return None
    p = float(wins.sum()) / n
    most = n / k
    if k < 2 or p in (0.0, 1.0):
        deff = most
    else:
        between = k / (k - 1) * float(np.sum((wins - p * sizes) ** 2)) / (n * n)
        deff = min(max(between / (p * (1.0 - p) / n), 1.0), most)
    return _wilson(p, n / deff)


def _wilson(p: float, n: float) -> list[float]:
    """Wilson's score interval (CONFIDENCE) of a proportion p observed over n (maybe effective,
    so not an integer) draws."""
    from scipy import stats as scipy_stats  # here: importing it costs every foldbot command 0.8 s

    z = float(scipy_stats.norm.ppf(0.5 + CONFIDENCE / 2))
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return [max(0.0, centre - half), min(1.0, centre + half)]


def mean_interval(values: Any) -> list[float] | None:
    """The Student-t interval (CONFIDENCE) of the mean of the finite values; None for fewer than
    two. It says how far a mean over these towels may lie from the mean over many more."""
    a = _finite(list(values))
    if a.size < 2:
        return None
    from scipy import stats as scipy_stats

    half = float(scipy_stats.t.ppf(0.5 + CONFIDENCE / 2, a.size - 1)) * a.std(ddof=1)
    half /= math.sqrt(a.size)
    return [float(a.mean() - half), float(a.mean() + half)]


def stats(values: list[Any]) -> dict[str, Any] | None:
    """mean (with its 95 % interval, `mean_ci95`, None for one value), median, p95, min, max of
    the finite values; None when there are none."""
    a = _finite(values)
    if a.size == 0:
        return None
    return {
        "mean": float(a.mean()),
        "mean_ci95": mean_interval(a),
        "median": float(np.median(a)),
        "p95": float(np.percentile(a, 95)),
        "min": float(a.min()),
        "max": float(a.max()),
    }


def _mean(values: list[Any]) -> float | None:
    a = _finite(values)
    return float(a.mean()) if a.size else None


_REPLICATE_SUFFIX = re.compile(r"-r\d+$")


def towel_of(episode_id: str) -> str:
    """An episode id without its replicate suffix (EpisodeSpec.id): the seed's cloth it folded."""
    return _REPLICATE_SUFFIX.sub("", episode_id)


def by_towel(records: list[dict], outcome: Callable[[dict], bool]) -> list[list[bool]]:
    """Each towel's outcomes (`towel_of` the record's id), in the order the towels first appear."""
    grouped: dict[str, list[bool]] = defaultdict(list)
    for r in records:
        grouped[towel_of(r.get("id", ""))].append(outcome(r))
    return list(grouped.values())


def result_value(record: dict, key: str) -> Any:
    """The record's result value at `key`, a dotted path into nested tables ("flatten.actions");
    None where any part is missing."""
    value: Any = record.get("result", {})
    for part in key.split("."):
        value = value.get(part) if isinstance(value, dict) else None
    return value


def values_by_towel(records: list[dict], key: str) -> list[np.ndarray]:
    """Each towel's finite values of result `key` (result_value; `towel_of` the record's id),
    towels with none left out."""
    grouped: dict[str, list[float]] = defaultdict(list)
    for r in records:
        v = result_value(r, key)
        if isinstance(v, numbers.Real) and math.isfinite(v):
            grouped[towel_of(r.get("id", ""))].append(float(v))
    return [np.asarray(v) for v in grouped.values()]


def towel_mean_interval(records: list[dict], key: str) -> list[float] | None:
    """The mean's interval over the towels rather than the episodes: each seed's cloth counts
    once, with the mean of its replicates (replicates of one towel are not independent draws)."""
    return mean_interval([float(v.mean()) for v in values_by_towel(records, key)])


def towel_stats(records: list[dict], key: str) -> dict[str, Any] | None:
    """stats() of result `key` over the episodes, with the mean's interval taken over the towels
    where some towel was folded more than once (towel_mean_interval)."""
    figure = stats([result_value(r, key) for r in records])
    if figure is not None and len({towel_of(r.get("id", "")) for r in records}) < len(records):
        figure["mean_ci95"] = towel_mean_interval(records, key)
    return figure


def replicate_stats(records: list[dict]) -> dict[str, Any] | None:
    """Where some towel was folded more than once (suite replicates): how the towels' outcomes
    repeat, and the fold error's spread within a towel (pooled SD of each towel's scored folds)
    against the SD of the towels' means. A spread within as large as between says a fold's
    outcome is chaotic: one fold of a towel tells little of what that towel folds to. None
    where every towel was folded once."""
    outcomes = by_towel(records, lambda r: bool(r.get("result", {}).get("success")))
    if all(len(o) == 1 for o in outcomes):
        return None
    scored = values_by_towel(records, "fold_error_mm")
    dof = sum(v.size - 1 for v in scored)
    within = (
        math.sqrt(sum(float(((v - v.mean()) ** 2).sum()) for v in scored) / dof) if dof else None
    )
    means = [float(v.mean()) for v in scored]
    return {
        "towels": len(outcomes),
        "folds_per_towel": max(len(o) for o in outcomes),
        "towels_always_succeeding": sum(all(o) for o in outcomes),
        "towels_never_succeeding": sum(not any(o) for o in outcomes),
        "fold_error_mm_sd_within_towel": within,
        "fold_error_mm_sd_of_towel_means": float(np.std(means, ddof=1)) if len(means) > 1 else None,
    }


def group_stats(records: list[dict]) -> dict[str, Any]:
    """Every summary figure over a list of records. Where some towel was folded more than once
    (suite replicates), every mean's interval is taken over the towels, and the success rate's
    at the effective number of episodes."""
    scored = [r["result"] for r in records if "result" in r]
    n = len(records)
    successes = sum(bool(r.get("success")) for r in scored)
    sim = sum(r.get("sim_seconds") or 0.0 for r in scored)
    wall = sum(r.get("wall_seconds") or 0.0 for r in scored)
    causes: dict[str, list[str]] = defaultdict(list)
    evidence: dict[str, str] = {}
    for rec in records:
        cause = failure_cause(rec)
        if cause is not None:
            causes[cause].append(rec["id"])
            evidence[rec["id"]] = evidence_path(rec)
    order = {c: i for i, c in enumerate(CAUSES)}
    failures = dict(sorted(causes.items(), key=lambda kv: (order.get(kv[0], len(order)), kv[0])))
    towels = {towel_of(r.get("id", "")) for r in records}
    scored_stats = {
        key: towel_stats(records, key)
        for key in (
            "fold_error_mm",
            "perfect_fold_error_mm",
            "perfect_normalized",
            "normalized_performance",
            "coverage",
        )
    }
    return {
        "episodes": n,
        "scored": len(scored),
        "successes": successes,
        "success_rate": successes / n if n else None,
        "success_ci95": clustered_success_interval(
            by_towel(records, lambda r: bool(r.get("result", {}).get("success")))
        ),
        "towels": len(towels),
        **scored_stats,
        "actions_per_episode": _mean([len(r.get("actions", [])) for r in scored]),
        "retries_per_episode": _mean(
            [sum(a.get("retries", 0) for a in r.get("actions", [])) for r in scored]
        ),
        "sim_seconds_per_fold": _mean([r.get("sim_seconds") for r in scored]),
        "wall_seconds_per_episode": _mean([r.get("wall_seconds") for r in scored]),
        "sim_speed": sim / wall if wall > 0 else None,
        **episode_speeds(scored),
        "failures": {c: len(ids) for c, ids in failures.items()},
        "failed_episodes": failures,
        "failed_evidence": evidence,
        "through_itself": through_itself(scored),
        "flatten": flatten_stats(records),
        "replicates": replicate_stats(records),
        "first_frame_keypoints": first_frame_stats(scored),
        "verdict": verdict_stats(scored),
    }


def through_itself(results: list[dict]) -> dict[str, int] | None:
    """Of the scored folds that recorded it (result.json's `self_crossings`, ground truth): how
    many ended with the cloth through itself, and how many of those metrics.md's rule counts as
    successes all the same; None where none recorded it (runs before it was)."""
    known = [r for r in results if r.get("self_crossings") is not None]
    if not known:
        return None
    tangled = [r for r in known if r["self_crossings"] > 0]
    return {
        "recorded": len(known),
        "folds": len(tangled),
        "successes": sum(bool(r.get("success")) for r in tangled),
    }


def verdict_stats(results: list[dict]) -> dict[str, Any] | None:
    """The loop's own verdict (every stage's perceived mask matched its predicted outline,
    verdict.perceived_verdict: all a real cell has) against metrics.md's success (ground truth),
    over the scored folds whose stages were checked; with the lowest stage IoU of the successes
    and of the failures, to show how far apart the two lie. None where no fold was checked."""
    judged = [
        (verdict, bool(r.get("success")), lowest_stage_iou(r["stages"]))
        for r in results
        if (verdict := perceived_verdict(r.get("stages") or [])) is not None
    ]
    if not judged:
        return None

    def count(verdict: bool, success: bool) -> int:
        return sum(v == verdict and s == success for v, s, _ in judged)

    return {
        "judged": len(judged),
        "verified_succeeded": count(True, True),
        "verified_failed": count(True, False),
        "unverified_succeeded": count(False, True),
        "unverified_failed": count(False, False),
        "agreement": sum(v == s for v, s, _ in judged) / len(judged),
        "lowest_iou_successes": stats([iou for _, s, iou in judged if s]),
        "lowest_iou_failures": stats([iou for _, s, iou in judged if not s]),
    }


FIRST_FRAME_OFF_MM = 10.0
"""A first-frame keypoint further than this (mm) from the cloth's own is counted as off."""


def first_frame_stats(results: list[dict]) -> dict[str, Any] | None:
    """Perception where the benchmark's plans are made: every keypoint of the frame each flat
    start's first stage was planned from, against the cloth's own (result.json's
    `first_frame_keypoint_error_mm`), pooled; the episodes with a keypoint off by more than
    FIRST_FRAME_OFF_MM, and the keypoint with the largest mean error. None where no episode
    has the figure (crumpled starts, older results)."""
    seen = [e for r in results if (e := r.get("first_frame_keypoint_error_mm"))]
    if not seen:
        return None
    by_name: dict[str, list[float]] = defaultdict(list)
    for errors in seen:
        for name, mm in errors.items():
            by_name[name].append(mm)
    worst = max(by_name, key=lambda n: float(np.mean(by_name[n])))
    return {
        "episodes": len(seen),
        "error_mm": stats([mm for errors in seen for mm in errors.values()]),
        "episodes_off": sum(max(errors.values()) > FIRST_FRAME_OFF_MM for errors in seen),
        "worst": {
            "name": worst,
            "mean_mm": float(np.mean(by_name[worst])),
            "max_mm": float(np.max(by_name[worst])),
        },
    }


def episode_speeds(results: list[dict]) -> dict[str, Any]:
    """Each scored episode's simulation speed (simulated over wall seconds): their spread
    (`episode_speed`, stats) and how many ran slower than real time (`episodes_under_real_time`),
    the target being each episode at least real time, not the run on average."""
    speeds = [
        r["sim_seconds"] / r["wall_seconds"]
        for r in results
        if r.get("sim_seconds") is not None and (r.get("wall_seconds") or 0.0) > 0.0
    ]
    return {
        "episode_speed": stats(speeds),
        "episodes_under_real_time": sum(v < 1.0 for v in speeds) if speeds else None,
    }


def flatten_stats(records: list[dict]) -> dict[str, Any] | None:
    """Crumpled starts: flatten success (ground-truth coverage ≥ 0.9 within the action budget)
    over all such episodes (an episode that ended in an error before being scored counts as a
    failure), flatten actions, and coverage before / after; None when no episode was crumpled."""
    crumpled = [r for r in records if "-crumpled-s" in r["id"]]  # see EpisodeSpec.id
    if not crumpled:
        return None
    flat = [r["result"]["flatten"] for r in crumpled if "flatten" in r.get("result", {})]
    wins = sum(bool(f.get("success")) for f in flat)
    return {
        "episodes": len(crumpled),
        "successes": wins,
        "success_rate": wins / len(crumpled),
        "success_ci95": clustered_success_interval(
            by_towel(
                crumpled, lambda r: bool(r.get("result", {}).get("flatten", {}).get("success"))
            )
        ),
        "actions": towel_stats(crumpled, "flatten.actions"),
        "coverage_start": towel_stats(crumpled, "flatten.coverage_start"),
        "coverage_end": towel_stats(crumpled, "flatten.coverage_end"),
        **_tangled(flat),
        **_ended_in_error(crumpled),
    }


def _ended_in_error(crumpled: list[dict]) -> dict[str, int | None]:
    """Of the crumpled episodes that ended in an error: how many; of those whose record keeps
    the flattening (worker.run_spec's "facts"; runs before it did not), how many crumpled cloths
    had passed through themselves (ground truth) and how many had been flattened before the
    error (in the fold after it: still counted unflattened above, as the episode was not
    scored); None where no record kept it."""
    errors = [r for r in crumpled if "result" not in r]
    kept = [
        f
        for r in errors
        if "self_crossings_start" in (f := (r.get("facts") or {}).get("flatten") or {})
    ]
    if not kept:
        keys = ("errors_recorded", "errors_tangled_start", "errors_after_flattening")
        return {"errors": len(errors), **dict.fromkeys(keys)}
    return {
        "errors": len(errors),
        "errors_recorded": len(kept),
        "errors_tangled_start": sum(f["self_crossings_start"] > 0 for f in kept),
        "errors_after_flattening": sum(bool(f.get("success")) for f in kept),
    }


def _tangled(flat: list[dict]) -> dict[str, int | None]:
    """Of the finished flattenings that recorded it (metrics.self_crossings, ground truth): how
    many crumpled cloths had passed through themselves, how many flattened ones, and how many of
    the towels left unflattened had; None where none recorded it (runs before it was)."""
    known = [f for f in flat if "self_crossings_end" in f]
    if not known:
        keys = ("tangled_start", "tangled_end", "unflattened", "unflattened_tangled", "recorded")
        return dict.fromkeys(keys)
    return {
        "tangled_start": sum(f["self_crossings_start"] > 0 for f in known),
        "tangled_end": sum(f["self_crossings_end"] > 0 for f in known),
        "unflattened": sum(not f.get("success") for f in known),
        "unflattened_tangled": sum(
            not f.get("success") and f["self_crossings_end"] > 0 for f in known
        ),
        "recorded": len(known),
    }


def _pick(s: dict, key: str, sub: str | None = None) -> float | None:
    v = s.get(key)
    if sub is not None:
        v = None if v is None else v.get(sub)
    return v


def comparisons(suite: Suite, records: list[dict]) -> list[dict]:
    """Side by side on paired episodes (same garment, recipe, seed and other axis): vision vs
    oracle perception and closed vs open loop, per recipe and pooled over recipes ('all')."""
    specs = {s.id: s for s in suite.episodes}
    by_cell: dict[tuple, dict] = {}
    for rec in records:
        s = specs.get(rec["id"])
        if s is not None:
            by_cell[(s.garment, s.recipe, s.perception, s.loop, s.seed, s.replicate)] = rec
    rows = []
    for axis, a, b in COMPARISONS:
        if not {a, b} <= set(suite.axes[axis]):
            continue
        other = "loop" if axis == "perception" else "perception"
        for garment, other_value in itertools.product(suite.axes["garment"], suite.axes[other]):
            pooled: dict[str, list[dict]] = {a: [], b: []}
            for recipe in [*suite.axes["recipe"], "all"]:
                sides: dict[str, list[dict]] = {a: [], b: []}
                if recipe == "all":
                    sides = pooled
                else:
                    replicates = range(suite.axes.get("replicates", 1))
                    for seed, replicate in itertools.product(suite.axes["seeds"], replicates):
                        cells = {}
                        for value in (a, b):
                            key = {"perception": value, "loop": other_value}
                            if axis == "loop":
                                key = {"perception": other_value, "loop": value}
                            cells[value] = by_cell.get(
                                (garment, recipe, key["perception"], key["loop"], seed, replicate)
                            )
                        if cells[a] is not None and cells[b] is not None:
                            for value in (a, b):
                                sides[value].append(cells[value])
                                pooled[value].append(cells[value])
                if recipe == "all" and len(suite.axes["recipe"]) == 1:
                    continue
                sa, sb = group_stats(sides[a]), group_stats(sides[b])
                rows.append(
                    {
                        "axis": axis,
                        "a": a,
                        "b": b,
                        "garment": garment,
                        "recipe": recipe,
                        other: other_value,
                        "paired_episodes": len(sides[a]),
                        "success_rate": [sa["success_rate"], sb["success_rate"]],
                        "fold_error_mm_mean": [
                            _pick(sa, "fold_error_mm", "mean"),
                            _pick(sb, "fold_error_mm", "mean"),
                        ],
                        "fold_error_mm_median": [
                            _pick(sa, "fold_error_mm", "median"),
                            _pick(sb, "fold_error_mm", "median"),
                        ],
                        "normalized_performance_mean": [
                            _pick(sa, "normalized_performance", "mean"),
                            _pick(sb, "normalized_performance", "mean"),
                        ],
                        "retries_per_episode": [
                            sa["retries_per_episode"],
                            sb["retries_per_episode"],
                        ],
                        "fold_error_mm_paired_difference": paired_difference(
                            sides[a], sides[b], "fold_error_mm"
                        ),
                    }
                )
    return rows


def paired_difference(a: list[dict], b: list[dict], key: str) -> dict[str, Any] | None:
    """`key` of b minus a over the pairs (a[i], b[i]) scored both ways: the number of pairs, the
    mean difference and its 95 % interval (an interval clear of 0 is a difference these towels
    show; one across 0 is not), taken over the towels' mean differences where a towel was folded
    more than once (`difference_interval`). None when no pair was scored both ways."""
    diffs: list[tuple[str, float]] = []
    for i, (ra, rb) in enumerate(zip(a, b, strict=True)):
        va, vb = ra.get("result", {}).get(key), rb.get("result", {}).get(key)
        if va is not None and vb is not None and math.isfinite(va) and math.isfinite(vb):
            diffs.append((ra.get("id", f"#{i}"), float(vb) - float(va)))
    if not diffs:
        return None
    return {
        "pairs": len(diffs),
        "mean": float(np.mean([d for _, d in diffs])),
        "mean_ci95": difference_interval(diffs),
    }


def difference_interval(diffs: list[tuple[str, float]]) -> list[float] | None:
    """The mean paired difference's interval from (episode id, difference) pairs: over the
    pairs, or over the towels' mean differences where some towel was folded more than once
    (replicates of one towel are not independent draws)."""
    grouped: dict[str, list[float]] = defaultdict(list)
    for eid, d in diffs:
        grouped[towel_of(eid)].append(d)
    if len(grouped) == len(diffs):
        return mean_interval([d for _, d in diffs])
    return mean_interval([float(np.mean(v)) for v in grouped.values()])


def summarise(suite: Suite, records: list[dict]) -> dict[str, Any]:
    """The run's summary (summary.json): overall, per group, comparisons, per-episode lines."""
    specs = {s.id: s for s in suite.episodes}
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for rec in records:
        if rec["id"] in specs:
            groups[specs[rec["id"]].group].append(rec)
    group_rows = []
    for key in itertools.product(
        *(suite.axes[k] for k in ("garment", "recipe", "perception", "loop"))
    ):
        if key in groups:
            g = dict(zip(("garment", "recipe", "perception", "loop"), key, strict=True))
            group_rows.append({**g, **group_stats(groups[key])})
    episodes = []
    for rec in records:
        r = rec.get("result", {})
        episodes.append(
            {
                "id": rec["id"],
                "success": bool(r.get("success", False)),
                "fold_error_mm": r.get("fold_error_mm"),
                "normalized_performance": r.get("normalized_performance"),
                "cause": failure_cause(rec),
                **({"error": rec["error"].splitlines()[0]} if "error" in rec else {}),
            }
        )
    return {
        "suite": {
            **{k: v for k, v in suite.as_dict().items() if k != "episodes"},
            **({"loop_options": suite.loop_options} if suite.loop_options else {}),
            **({"robot": suite.robot} if suite.robot != "ur5" else {}),
            **({"cloth_options": suite.cloth_options} if suite.cloth_options else {}),
            **({"flatten_options": suite.flatten_options} if suite.flatten_options else {}),
        },
        "episodes_planned": len(suite.episodes),
        "episodes_finished": len(records),
        "complete": len(records) == len(suite.episodes),
        "overall": group_stats([r for r in records if r["id"] in specs]),
        "groups": group_rows,
        "comparisons": comparisons(suite, records),
        "reference_figures": [
            {"system": s, "case": c, "figure": f} for s, c, f in REFERENCE_FIGURES
        ],
        "episodes": episodes,
    }
