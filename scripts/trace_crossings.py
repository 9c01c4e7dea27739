"""Trace when a fold passes the simulated cloth through itself: during which action and motion
segment (approach, descend, carry, lower, retreat, park…, or the jaws' closing or opening at a
segment's end) its first self-crossings appear, what the
grippers held then, and between which of the fold's goal layers the crossings lie (the layers as
metrics.fold_goal numbers them: 0 the cloth no fold moves, a stage's flap the next numbers, the
last fold's top layer the highest), and whether they touch the held mesh points' neighbourhood
(the grip). Ground truth, for diagnosis only: the fold itself runs exactly as in the benchmark
(vision, closed loop); the simulator is only read, every `--every` physics steps.

Each episode runs in its own process (Bullet's soft body is deterministic only as the first
simulation in a process); one JSON line per episode goes to stdout, a summary to stderr: in which
segment each tangled episode's crossings first appeared, and how many first crossings touched
the grip.

    .venv/bin/python scripts/trace_crossings.py --suite towel_two_arms --recipe quarter --seeds 0-9
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from foldbot.bench.suite import parse_seeds

sys.path.insert(0, str(Path(__file__).resolve().parent))
from per_seed import run_each_seed


def neighbourhood(vertices: set[int], faces: np.ndarray) -> set[int]:
    """`vertices` and every mesh vertex sharing a triangle with one of them (their 1-ring)."""
    if not vertices:
        return set()
    touching = np.isin(faces, list(vertices)).any(axis=1)
    return set(np.unique(faces[touching]).tolist()) | set(vertices)


def layer_pairs(pairs: np.ndarray, faces: np.ndarray, layers: np.ndarray) -> dict[str, int]:
    """Crossings counted by the goal layers they join: "e/t" for an edge of layer e through a
    triangle of layer t (a vertex-mixed edge or triangle counts as its highest layer)."""
    out: Counter = Counter()
    for a, b, t in pairs:
        edge = max(int(layers[a]), int(layers[b]))
        tri = int(layers[faces[t]].max())
        out[f"{edge}/{tri}"] += 1
    return dict(sorted(out.items()))


def touches(pairs: np.ndarray, faces: np.ndarray, ring: set[int]) -> int:
    """How many crossings have their edge or their triangle in `ring` (a held point's 1-ring)."""
    return sum(1 for a, b, t in pairs if a in ring or b in ring or ring & set(faces[t].tolist()))


def first_rise(samples: list[dict]) -> dict | None:
    """The first sample whose crossing count exceeds the one before it (from 0 at the start),
    or None where the cloth never passed through itself."""
    before = 0
    for s in samples:
        if s["crossings"] > before:
            return s
        before = s["crossings"]
    return None


def trace_episode(suite: str, recipe: str, seed: int, every: int) -> dict:
    """Run one episode with the step sampler (in the calling process); its crossings' story."""
    import foldbot.carry as carry
    import foldbot.control.executor as executor
    import foldbot.loop as loop
    import foldbot.pipeline as pipeline
    import foldbot.sim.grasp as grasp
    from foldbot import metrics
    from foldbot.bench.suite import load_suite
    from foldbot.pipeline import run_episode

    spec = next(
        (e for e in load_suite(suite).episodes if e.recipe == recipe and e.seed == seed), None
    )
    if spec is None:
        return {"recipe": recipe, "seed": seed, "error": f"no {recipe} seed {seed} in {suite}"}
    now: dict = {"action": None, "segment": None, "cell": None, "t0": 0.0}
    samples: list[dict] = []

    def sample(world) -> None:
        cell = now["cell"]
        if cell is None or world.steps % every:
            return
        cloth = cell.executors[0].grasp.cloth
        held = sorted({int(v) for e in cell.executors for v in e.grasp.held})
        pairs = metrics.self_crossing_pairs(cloth.sim_vertices(), cloth.mesh.faces)
        samples.append(
            {
                "t": round(world.sim_time, 3),
                "action": now["action"],
                "segment": now["segment"],
                "since_action_s": round(world.sim_time - now["t0"], 3),
                "held": held,
                "crossings": len(pairs),
                "pairs": pairs,
            }
        )

    seen_lines: list[tuple[float, ...]] = []  # the fold lines of the actions run so far

    def watch(cell, label: str, action) -> None:
        if now["cell"] is None:
            cell.executors[0].world.add_step_hook(sample)
        now.update(cell=cell, action=label, segment=None, t0=cell.sim_time)
        line = tuple(float(v) for v in action.fold_line)
        if not seen_lines or seen_lines[-1] != line:
            seen_lines.append(line)

    start = executor.ArmExecutor.start

    def start_noting(self, segment):
        now["segment"] = getattr(segment, "segment", segment).name
        return start(self, segment)

    joint_moves = pipeline.move_joints_together

    def joint_moves_noting(pairs, name="joint_move"):
        now["segment"] = name  # parking the arms between actions
        return joint_moves(pairs, name)

    def jaws_noting(event: str, act):
        def run(self, *args, **kwargs):
            now["segment"] = f"{now['segment']}, jaws {event}"  # the settle after the segment
            return act(self, *args, **kwargs)

        return run

    execute, together = carry.execute_action, carry.execute_together

    def traced(cell, action):
        watch(cell, action.label, action)
        return execute(cell, action)

    def traced_pair(cell, pairs):
        watch(cell, "+".join(a.label for _, a in pairs), pairs[0][1])
        return together(cell, pairs)

    executor.ArmExecutor.start = start_noting
    pipeline.move_joints_together = joint_moves_noting
    grasp.ClothGrasp.close = jaws_noting("closing", grasp.ClothGrasp.close)
    grasp.ClothGrasp.open = jaws_noting("opening", grasp.ClothGrasp.open)
    loop.execute_action = carry.execute_action = traced
    carry.execute_together = traced_pair
    out = Path(tempfile.mkdtemp(prefix="trace_crossings_")) / "episode"
    error = None
    try:
        result = run_episode(spec.to_config(), out, log=lambda _msg: None)
        lines, cloth = result["fold_lines"], np.load(out / "cloth.npz")
        initial, faces, thickness = cloth["initial"], cloth["faces"], cloth["thickness"]
    except Exception as exc:  # a diverged cloth is a result here, not a crash
        error = f"{exc}"[:200]
        lines, result = seen_lines, None
    if not samples:
        return {"recipe": recipe, "seed": seed, "error": error or "no action was traced"}
    if result is None:
        # No cloth.npz: the goal layers from the cloth as spawned flat and the lines traced.
        cloth = now["cell"].executors[0].grasp.cloth
        initial, faces, thickness = (
            cloth.spawn_vertices,
            np.asarray(cloth.mesh.faces),
            cloth.thickness,
        )
    layers = (
        metrics.fold_goal(initial, lines, thickness)[1]
        if lines
        else np.zeros(len(initial), dtype=np.int64)
    )
    actions = []
    for label in dict.fromkeys(s["action"] for s in samples):
        mine = [s for s in samples if s["action"] == label]
        actions.append(
            {"action": label, "crossings_start": mine[0]["crossings"], "end": mine[-1]["crossings"]}
        )
    rise = first_rise(samples)
    first = None
    if rise is not None:
        ring = neighbourhood(set(rise["held"]), faces)
        first = {
            "action": rise["action"],
            "segment": rise["segment"],
            "since_action_s": rise["since_action_s"],
            "held": rise["held"],
            "held_layers": [int(layers[v]) for v in rise["held"]],
            "crossings": rise["crossings"],
            "layers": layer_pairs(rise["pairs"], faces, layers),
            "at_the_grip": touches(rise["pairs"], faces, ring),
        }
    last = samples[-1]
    row = {
        "recipe": recipe,
        "seed": seed,
        "actions": actions,
        "first": first,
        "end": {
            "crossings": last["crossings"],
            "layers": layer_pairs(last["pairs"], faces, layers),
        },
    }
    if result is not None:
        row.update(
            fold_error_mm=round(result["fold_error_mm"], 1),
            success=bool(result["success"]),
            self_crossings=result.get("self_crossings"),
        )
    if error:
        row["error"] = error
    return row


def summary(rows: list[dict]) -> list[str]:
    """Lines for stderr: how many episodes passed through themselves (and how many of them ended
    so: a crossing can come apart again), in which segment their crossings first appeared, and
    how many of those first crossings touched the grip."""
    traced = [r for r in rows if "actions" in r]
    tangled = [r for r in traced if r.get("first")]
    ended = sum(1 for r in tangled if r.get("end", {}).get("crossings", 0) > 0)
    lines = [
        f"# {len(tangled)} of {len(traced)} traced episodes passed through themselves at some "
        f"moment, {ended} ended so"
    ]
    where = Counter(r["first"]["segment"] for r in tangled)
    for segment, n in where.most_common():
        grip = sum(
            1
            for r in tangled
            if r["first"]["segment"] == segment and r["first"]["at_the_grip"] and r["first"]["held"]
        )
        lines.append(f"  first in '{segment}': {n} (holding, at the grip: {grip})")
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--suite", default="towel_two_arms", help="suite name or .toml (towel_two_arms)"
    )
    ap.add_argument("--recipe", default="quarter", help="recipe to trace (quarter)")
    ap.add_argument("--seeds", default="0-9", help="'0-9', '0,3,5' or one seed (0-9)")
    ap.add_argument("--every", type=int, default=12, help="physics steps between samples (12)")
    ap.add_argument("--workers", type=int, default=2, help="episodes at once (2)")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # child process: one seed
    args = ap.parse_args()
    if args.every < 1:
        raise SystemExit(f"--every must be ≥ 1 step, got {args.every}")
    if args.one is not None:
        row = trace_episode(args.suite, args.recipe, args.one, args.every)
        print(json.dumps(row), flush=True)
        return 0
    rows = run_each_seed(
        __file__,
        parse_seeds(args.seeds),
        ["--suite", args.suite, "--recipe", args.recipe, "--every", str(args.every)],
        args.workers,
    )
    for line in summary(rows):
        print(line, file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
