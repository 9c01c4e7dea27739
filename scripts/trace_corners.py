"""Trace a fold's carried corners through time: every `--every` s of simulated time, each corner
of the towel that the recipe carries, measured against its goal: how far past it along its carry
(negative: short of it), how far aside, how high above the table, and the arm's TCP height. Ground
truth, for diagnosis only: the episode runs exactly as in the benchmark (vision, closed loop); the
simulator is only read. What it showed: a flap folded at one corner on a stack falls back over its
crease by itself, seconds after the jaws open (docs/experiments.md, One arm's far third falls back
by itself).

One episode of a suite, in this process; a table on stdout (one row per sample and corner),
optionally all samples as CSV, and a line per corner saying when it came within `--near` of its
goal and whether it fell back more than `--back` afterwards.

    .venv/bin/python scripts/trace_corners.py --suite towel_loop --recipe thirds --seed 1
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import csv
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Sample:
    """The carried corners and the TCP at one instant of the episode."""

    t: float
    """Simulated time (s)."""
    label: str
    """The pick-and-place running then (its FoldAction label)."""
    corners: np.ndarray
    """K×3 positions of the towel's corner vertices (world, m)."""
    tcp_z: float
    """TCP height (m, world)."""


def corner_rows(
    initial: np.ndarray, goal: np.ndarray, ids: list[int], samples: list[Sample], table_z: float
) -> list[dict]:
    """Per sample and carried corner (one whose goal lies away from where it started): its offset
    from its goal along the carry, start to goal (`past_mm`, negative: short of it), across it
    (`aside_mm`) and its height above the table (`z_mm`), with the sample's time, action and TCP
    height above the table (`tcp_mm`)."""
    rows = []
    for k, vid in enumerate(ids):
        carry = goal[vid, :2] - initial[vid, :2]
        if np.linalg.norm(carry) < 1e-6:
            continue  # a staying corner
        along = carry / np.linalg.norm(carry)
        across = np.array([-along[1], along[0]])
        for s in samples:
            off = s.corners[k, :2] - goal[vid, :2]
            rows.append(
                {
                    "t": round(s.t, 3),
                    "action": s.label,
                    "vertex": vid,
                    "past_mm": round(1000 * float(off @ along), 1),
                    "aside_mm": round(1000 * float(off @ across), 1),
                    "z_mm": round(1000 * (float(s.corners[k, 2]) - table_z), 1),
                    "tcp_mm": round(1000 * (s.tcp_z - table_z), 1),
                }
            )
    return rows


def fell_back(rows: list[dict], vertex: int, near: float, back: float) -> str:
    """One line on a corner: when it first came within `near` (m) of its goal, and whether it later
    fell back more than `back` (m) short of it (where and when), or where it ended."""
    mine = [r for r in rows if r["vertex"] == vertex]
    reach = next((r for r in mine if np.hypot(r["past_mm"], r["aside_mm"]) <= 1000 * near), None)
    if reach is None:
        best = min(mine, key=lambda r: np.hypot(r["past_mm"], r["aside_mm"]))
        return (
            f"vertex {vertex}: never within {1000 * near:.0f} mm of its goal (closest "
            f"{np.hypot(best['past_mm'], best['aside_mm']):.0f} mm at t = {best['t']:.2f} s)"
        )
    said = f"vertex {vertex}: within {1000 * near:.0f} mm of its goal at t = {reach['t']:.2f} s"
    later = [r for r in mine if r["t"] > reach["t"]]
    fall = next((r for r in later if r["past_mm"] < -1000 * back), None)
    if fall is not None:
        return (
            f"{said} ({reach['action']}), then {-fall['past_mm']:.0f} mm short of it at "
            f"t = {fall['t']:.2f} s ({fall['action']}, TCP {fall['tcp_mm']:.0f} mm up)"
        )
    end = mine[-1]
    return f"{said}; at the end {end['past_mm']:+.0f} mm past, {end['aside_mm']:+.0f} aside"


def trace_episode(suite: str, recipe: str, seed: int, every: float) -> tuple[list[dict], dict]:
    """Run one suite episode, sampling its corners every `every` s; (rows, result.json)."""
    import foldbot.carry as carry
    import foldbot.loop as loop
    from foldbot import metrics
    from foldbot.bench.suite import load_suite
    from foldbot.pipeline import run_episode

    spec = next(
        (e for e in load_suite(suite).episodes if e.recipe == recipe and e.seed == seed), None
    )
    if spec is None:
        raise SystemExit(f"no {recipe} episode with seed {seed} in suite {suite}")
    samples: list[Sample] = []
    seen: dict = {}
    execute, together = carry.execute_action, carry.execute_together

    def start(cell, label: str) -> None:
        """Name the action under way; on the first, hook the sampler into the world."""
        cloth = cell.executor.grasp.cloth
        seen["label"] = label
        if "ids" not in seen:
            seen["initial"] = cloth.sim_vertices().copy()
            # The mesh names its corner vertices (sim_vertices is in mesh order).
            seen["ids"] = [i for n, i in cloth.mesh.keypoints.items() if n.startswith("corner")]
            stride = max(1, round(every / cell.world.time_step))

            def sample(world) -> None:
                if world.steps % stride == 0:
                    v = cloth.sim_vertices()
                    tcp = float(cell.robot.tcp_pose()[0][2])  # the active arm's
                    samples.append(Sample(world.sim_time, seen["label"], v[seen["ids"]], tcp))

            cell.world.add_step_hook(sample)
            seen["table_z"] = cell.table_height

    def traced(cell, action):
        start(cell, action.label)
        return execute(cell, action)

    def traced_pair(cell, pairs):  # two arms carrying a pair at once: one label, joined
        start(cell, "+".join(a.label for _, a in pairs))
        return together(cell, pairs)

    # The towel loop's one-arm carries (loop) and the as-planned ones (carry), and the pairs.
    loop.execute_action = carry.execute_action = traced
    carry.execute_together = traced_pair
    out = Path(tempfile.mkdtemp(prefix="trace_corners_")) / "episode"
    result = run_episode(spec.to_config(), out, log=lambda _msg: None)
    goal = metrics.fold_goal(seen["initial"], result["fold_lines"], 0.0)[0]
    rows = corner_rows(seen["initial"], goal, seen["ids"], samples, seen["table_z"])
    return rows, result


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--suite", default="towel_loop", help="suite name or .toml (towel_loop)")
    ap.add_argument("--recipe", default="thirds", help="the episode's recipe (thirds)")
    ap.add_argument("--seed", type=int, default=1, help="the episode's seed (1)")
    ap.add_argument("--every", type=float, default=0.1, help="sampling interval, s (0.1)")
    ap.add_argument("--since", type=float, default=0.0, help="print samples from this time, s")
    ap.add_argument("--near", type=float, default=0.01, help="'laid' within this of the goal, m")
    ap.add_argument("--back", type=float, default=0.05, help="'fell back' this short of it, m")
    ap.add_argument("--csv", type=Path, help="write every sample here too")
    args = ap.parse_args()
    if not args.every > 0:
        raise SystemExit(f"--every must be > 0 s, got {args.every}")
    rows, result = trace_episode(args.suite, args.recipe, args.seed, args.every)
    for r in rows:
        if r["t"] >= args.since:
            print(
                f"t {r['t']:7.2f}  {r['action']:18s} vertex {r['vertex']:4d}  past {r['past_mm']:7.1f}"
                f"  aside {r['aside_mm']:6.1f}  z {r['z_mm']:5.1f}  TCP {r['tcp_mm']:6.1f} mm"
            )
    if args.csv:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with args.csv.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["t"])
            writer.writeheader()
            writer.writerows(rows)
    for vid in dict.fromkeys(r["vertex"] for r in rows):
        print(fell_back(rows, vid, args.near, args.back), file=sys.stderr)
    print(f"# fold error {result['fold_error_mm']:.1f} mm", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
