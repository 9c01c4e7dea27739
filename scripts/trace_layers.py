"""Trace where a multi-stage fold's layers get their error: after every pick-and-place (a pair's
carry with two arms), each stage's flap (the vertices that stage folds) measured against its
goal, how far the action dragged the flaps laid before it, how far the staying cloth (the
vertices no fold so far moves) lies from where it lay flat, and the first fold's normalized
performance (the success measure) as it stands, and how many mesh edges pass through the
cloth's own triangles (metrics.self_crossings: a fold through itself); and the fold error and
the staying cloth's drift after the last action against the episode's end, which differ only by
what the cloth did after the arm let go (parking, the last look). Ground truth, for diagnosis only: the fold itself
runs exactly as in the benchmark (vision, closed loop); the simulator is only read between
actions.

For each chosen episode of a suite (each in its own process: Bullet's soft body is deterministic
only as the first simulation in a process) one JSON line goes to stdout; a summary per recipe
goes to stderr: each flap's error when its stage ended and when the episode ended, the drag that
the later stages put on it, and the staying cloth's drift.

    .venv/bin/python scripts/trace_layers.py --suite towel_loop --recipe thirds --seeds 0-19
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from foldbot.bench.suite import parse_seeds
from foldbot.metrics import FOLD_SUCCESS_MIN_NORMALIZED

sys.path.insert(0, str(Path(__file__).resolve().parent))
from per_seed import run_each_seed


def flap_masks(initial: np.ndarray, lines: list, thickness: float) -> list[np.ndarray]:
    """Per stage begun so far: the vertices that stage moves (its flap), from the goal's layers."""
    from foldbot import metrics

    masks, before = [], np.zeros(len(initial), dtype=np.int64)
    for k in range(len(lines)):
        layers = metrics.fold_goal(initial, lines[: k + 1], thickness)[1]
        masks.append(layers != before)
        before = layers
    return masks


def staying_drift_mm(vertices: np.ndarray, initial: np.ndarray, staying: np.ndarray) -> float:
    """Mean table-plane distance (mm) of the `staying` vertices (a mask: those no fold so far
    moves, goal layer 0) from where they lay flat; 0 where none stays."""
    if not staying.any():
        return 0.0
    return round(1000 * float(np.linalg.norm((vertices - initial)[staying, :2], axis=1).mean()), 1)


def trace_episode(suite: str, recipe: str, seed: int) -> dict:
    """Run one episode with the action tracer (in the calling process); its rows and result."""
    import foldbot.carry as carry
    import foldbot.loop as loop
    from foldbot import metrics
    from foldbot.bench.suite import load_suite
    from foldbot.pipeline import run_episode

    spec = next(
        (e for e in load_suite(suite).episodes if e.recipe == recipe and e.seed == seed), None
    )
    if spec is None:
        return {"recipe": recipe, "seed": seed, "error": f"no {recipe} seed {seed} in {suite}"}
    rows: list[dict] = []
    state: dict = {"lines": []}
    execute, together = carry.execute_action, carry.execute_together

    def record(cell, action, label: str, run):
        """Run one action (`run()`: its outcome and how many vertices the jaws held), then
        measure the cloth against the goal of the fold lines so far."""
        cloth = cell.executor.grasp.cloth
        before = cloth.sim_vertices()
        state.setdefault("initial", before.copy())
        line = tuple(float(v) for v in action.fold_line)
        if not state["lines"] or state["lines"][-1] != line:
            state["lines"].append(line)
        outcome, grasped = run()
        after = cloth.sim_vertices()
        initial, lines = state["initial"], [metrics.FoldLine(*ln) for ln in state["lines"]]
        thickness = cloth.thickness
        goal, layers = metrics.fold_goal(initial, lines, thickness)
        masks = flap_masks(initial, lines, thickness)
        moved = np.linalg.norm(after[:, :2] - before[:, :2], axis=1)
        err = np.linalg.norm(after[:, :2] - goal[:, :2], axis=1)
        first = metrics.softgym_performance(initial, after, lines[0], staying_reference=goal)
        rows.append(
            {
                "stage": len(lines) - 1,
                "label": label,
                "grasped": grasped,
                "flap_error_mm": [round(1000 * float(err[m].mean()), 1) for m in masks],
                "flap_moved_mm": [round(1000 * float(moved[m].mean()), 1) for m in masks],
                "first_fold_normalized": round(float(first.normalized), 3),
                "staying_drift_mm": staying_drift_mm(after, initial, layers == 0),
                "self_crossings": metrics.self_crossings(after, cloth.mesh.faces),
            }
        )
        state["last"] = after
        return outcome

    def traced(cell, action):
        def run():
            outcome = execute(cell, action)
            return outcome, len(outcome["grasped_vertices"])

        return record(cell, action, action.label, run)

    def traced_pair(cell, pairs):
        # Two arms carrying a stage's pair at once: one row, the labels joined.
        def run():
            outcomes = together(cell, pairs)
            return outcomes, sum(len(o["grasped_vertices"]) for o in outcomes)

        label = "+".join(a.label for _, a in pairs)
        return record(cell, pairs[0][1], label, run)

    # The towel loop's one-arm carries (loop) and the as-planned ones (carry), and the pairs.
    loop.execute_action = carry.execute_action = traced
    carry.execute_together = traced_pair
    out = Path(tempfile.mkdtemp(prefix="trace_layers_")) / "episode"
    try:
        result = run_episode(spec.to_config(), out, log=lambda _msg: None)
    except Exception as exc:  # a diverged cloth is a result here, not a crash
        return {"recipe": recipe, "seed": seed, "actions": rows, "error": f"{exc}"[:200]}
    cloth = np.load(out / "cloth.npz")
    goal, layers = metrics.fold_goal(cloth["initial"], result["fold_lines"], cloth["thickness"])
    staying = layers == 0

    def standing(vertices: np.ndarray) -> dict:
        return {
            "fold_error_mm": round(metrics.fold_error_mm(vertices, goal), 1),
            "staying_drift_mm": staying_drift_mm(vertices, cloth["initial"], staying),
            "self_crossings": metrics.self_crossings(vertices, cloth["faces"]),
        }

    return {
        "recipe": recipe,
        "seed": seed,
        "fold_error_mm": round(result["fold_error_mm"], 1),
        "normalized_performance": round(result["normalized_performance"], 3),
        "actions": rows,
        "after_last_action": standing(state["last"]) if "last" in state else None,
        "end": standing(cloth["final"]),
    }


def stage_ends(row: dict) -> list[list[float]]:
    """Per stage: its own flap's error (mm) after the stage's last action, and at the end."""
    acts = row.get("actions", [])
    if not acts or "error" in row:
        return []
    out = []
    for k in range(acts[-1]["stage"] + 1):
        last = [a for a in acts if a["stage"] == k][-1]
        out.append([last["flap_error_mm"][k], acts[-1]["flap_error_mm"][k]])
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--suite", default="towel_loop", help="suite name or .toml (towel_loop)")
    ap.add_argument("--recipe", default="thirds", help="recipe to trace (thirds)")
    ap.add_argument("--seeds", default="0-19", help="'0-19', '0,3,5' or one seed (0-19)")
    ap.add_argument("--workers", type=int, default=2, help="episodes at once (2)")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # child process: one seed
    args = ap.parse_args()
    if args.one is not None:
        print(json.dumps(trace_episode(args.suite, args.recipe, args.one)), flush=True)
        return 0
    rows = run_each_seed(
        __file__,
        parse_seeds(args.seeds),
        ["--suite", args.suite, "--recipe", args.recipe],
        args.workers,
    )
    ends = [stage_ends(r) for r in rows]
    ends = [e for e in ends if e]
    print(f"# {args.recipe}: {len(ends)} of {len(rows)} episodes scored", file=sys.stderr)
    for k in range(max((len(e) for e in ends), default=0)):
        pairs = np.array([e[k] for e in ends if len(e) > k])
        print(
            f"# stage {k + 1}'s flap: median error {np.median(pairs[:, 0]):.1f} mm when the stage "
            f"ended, {np.median(pairs[:, 1]):.1f} mm at the end "
            f"(grew in {int(np.sum(pairs[:, 1] > pairs[:, 0] + 2))} of {len(pairs)})",
            file=sys.stderr,
        )
    done = [r for r in rows if r.get("end") and r.get("after_last_action")]
    if done:
        last, end = (
            np.array([[r[k]["fold_error_mm"], r[k]["staying_drift_mm"]] for r in done])
            for k in ("after_last_action", "end")
        )
        print(
            f"# fold error: mean {last[:, 0].mean():.1f} mm after the last action, "
            f"{end[:, 0].mean():.1f} at the end; the staying cloth's drift from where it lay flat: "
            f"median {np.median(last[:, 1]):.1f} mm after the last action, "
            f"{np.median(end[:, 1]):.1f} at the end",
            file=sys.stderr,
        )
    nps = [
        [[a for a in r["actions"] if a["stage"] == 0][-1], r["actions"][-1]]
        for r in rows
        if "error" not in r and r.get("actions")
    ]
    if nps:
        bar = FOLD_SUCCESS_MIN_NORMALIZED
        first, last = (np.array([p[i]["first_fold_normalized"] for p in nps]) for i in (0, 1))
        print(
            f"# first fold's normalized performance: median {np.median(first):.3f} when stage 1 "
            f"ended ({int(np.sum(first >= bar))} of {len(nps)} at ≥ {bar}), "
            f"{np.median(last):.3f} at the end ({int(np.sum(last >= bar))} at ≥ {bar})",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
