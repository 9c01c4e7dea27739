"""Measure how well vision reads a crumpled towel's coverage: perceived against true, per seed.

For each seed of a crumpled suite (default `towel_crumpled_two_arms`): build its cell, settle the
towel, crumple it with the episode's own seeded draw (`pipeline.crumple_start`), put every arm in
the suite's park pose (set, not driven: the heap is not disturbed), take one RGB-D frame and
estimate it with `VisionEstimator`. Perceived coverage = the estimate's top-view area / the flat
towel's area (what flattening stops on); true coverage from the mesh (GROUND TRUTH, for this
measurement only). Each seed runs in its own process (Bullet's soft body is deterministic only as
the first simulation in a process); one JSON line per seed, then the summary.

    .venv/bin/python scripts/measure_heap_coverage.py --seeds 0-19 [--suite NAME] [--save DIR]

`--save DIR` writes each frame's overlay (perceived outline and corners) as DIR/sNN.png.
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from foldbot.bench.suite import parse_seeds

sys.path.insert(0, str(Path(__file__).resolve().parent))
from per_seed import run_each_seed


def measure(suite: str, seed: int, save: Path | None) -> dict:
    """One seed's perceived and true coverage after crumpling (runs in the calling process)."""
    from foldbot import metrics
    from foldbot.bench.suite import load_suite
    from foldbot.perception.estimator import VisionEstimator
    from foldbot.pipeline import build_sim_cell, crumple_start
    from foldbot.sim.cloth import settle
    from foldbot.sim.world import SimWorld

    loaded = load_suite(suite)
    spec = next((e for e in loaded.episodes if e.seed == seed), None)
    if spec is None:
        return {"seed": seed, "error": f"suite {suite!r} has no episode with seed {seed}"}
    cfg = spec.to_config()
    if cfg.start != "crumpled":
        return {"seed": seed, "error": f"suite {suite!r} starts {cfg.start!r}, not crumpled"}
    out: dict = {"seed": seed}
    try:
        with SimWorld(cfg.sim) as world:
            parts = build_sim_cell(cfg, world)
            parts.model_world.close()
            settle(world, parts.cloth)
            crumple_start(cfg, world, parts.cloth)
            for ex in (parts.executor, *parts.more_executors):
                robot = ex.robot
                robot.reset_joints(
                    robot.out_of_view_q if cfg.park == "out_of_view" else robot.home_q
                )
            obs = parts.camera.observe(parts.robot.joint_positions(), stamp=world.sim_time)
            state = VisionEstimator().estimate(obs)
            mesh = parts.mesh
            truth = metrics.coverage(parts.oracle.cloth_vertices(), mesh.faces, flat_area=mesh.area)
            out.update(
                coverage=float(truth),
                perceived=float(state.coverage_m2 / mesh.area) if state.detected else 0.0,
                detected=bool(state.detected),
                cue=state.reason,
            )
            if save is not None:
                import imageio.v3 as iio

                from foldbot.perception.overlay import draw_overlay

                save.mkdir(parents=True, exist_ok=True)
                iio.imwrite(save / f"s{seed:02d}.png", draw_overlay(obs, state))
    except Exception as exc:  # a diverged crumple is a result here, not a crash
        out["error"] = f"{type(exc).__name__}: {exc}"[:200]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0-19", help="seeds: '0-19', '0,3,5' or one (default 0-19)")
    ap.add_argument("--suite", default="towel_crumpled_two_arms", help="a crumpled-start suite")
    ap.add_argument("--save", type=Path, help="write each frame's overlay here")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # child process: one seed
    args = ap.parse_args()
    if args.one is not None:
        print(json.dumps(measure(args.suite, args.one, args.save)), flush=True)
        return 0
    extra = ["--suite", args.suite] + ([] if args.save is None else ["--save", str(args.save)])
    rows = run_each_seed(__file__, parse_seeds(args.seeds), extra)
    ok = [r for r in rows if "error" not in r]
    if not ok:
        print("no seed measured", file=sys.stderr)
        return 1
    err = np.array([r["perceived"] - r["coverage"] for r in ok])
    print(
        f"{len(ok)} crumpled towels ({len(rows) - len(ok)} failed): perceived − true coverage "
        f"mean {err.mean():+.3f}, mean |error| {np.abs(err).mean():.3f}, "
        f"max |error| {np.abs(err).max():.3f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
