"""Measure crumple → flatten on seeded towels: ground-truth coverage after every pull.

For each seed: the towel_full towel (sides 25–45 cm drawn from the seed), settled flat, crumpled
(sim.crumple), then flattened by `foldbot.flatten.run_flatten` with vision perception. Ground truth
(metrics.coverage, 2 mm raster) is read only here, for scoring. Each seed runs in a fresh process
(Bullet's soft-body solver keeps process-global random state), one at a time; results are
appended to a JSON-lines file so an interrupted run resumes.

    .venv/bin/python scripts/measure_flatten.py --seeds 0 20 --out runs/flatten.jsonl
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import contextlib
import dataclasses
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from foldbot import metrics
from foldbot.flatten import run_flatten
from foldbot.garments.towel import TowelSpec
from foldbot.perception.estimator import VisionEstimator
from foldbot.pipeline import EpisodeConfig, SimCell, build_sim_cell, seeded_towel
from foldbot.planning.flatten import FlattenConfig, plan_pulls
from foldbot.planning.motion import MotionConfig
from foldbot.sim.cloth import settle
from foldbot.sim.crumple import CrumpleConfig, crumple
from foldbot.sim.oracle import OracleEstimator
from foldbot.sim.world import SimWorld


def crumple_rng(seed: int) -> np.random.Generator:
    """The crumple's random stream of an episode seed (separate from pose and size)."""
    return np.random.default_rng([seed, 2])


class _MeasuredCell(SimCell):
    """SimCell that also records GROUND-TRUTH coverage at every observation (scoring only)."""

    def __init__(
        self, *args, flat_area: float, faces: np.ndarray, oracle, frames=None, plan=None, **kw
    ):
        super().__init__(*args, **kw)
        self.flat_area, self.faces, self.oracle = flat_area, faces, oracle
        self.true_coverage: list[float] = []
        self.frames = frames
        self.plan = plan

    def observe(self):
        state, obs = super().observe()
        v = self.oracle.cloth_vertices()
        self.true_coverage.append(metrics.coverage(v, self.faces, self.flat_area))
        if self.frames is not None:
            self.frames.append(_debug_frame(obs, state, self.plan, self.true_coverage[-1]))
        return state, obs


def _debug_frame(obs, state, plan, true_cov: float) -> np.ndarray:
    """The perception overlay plus the fitted expected outline and the planned pull."""
    import cv2

    from foldbot.perception.geometry import project_points
    from foldbot.perception.overlay import draw_overlay

    if not state.detected:
        return obs.rgb
    img = draw_overlay(obs, state)
    try:
        fit, pulls = plan(state)
    except Exception:
        return img
    z = float(np.asarray(state.outline_world)[:, 2].mean())
    rect = np.c_[fit.corners, np.full(4, z)]
    uv, _ = project_points(rect, obs.intrinsics, obs.T_world_camera)
    cv2.polylines(img, [np.round(uv).astype(np.int32)], True, (255, 255, 0), 1, cv2.LINE_AA)
    for pl in pulls[:1]:
        pts, _ = project_points(
            np.array([pl.action.grasp, pl.action.place]), obs.intrinsics, obs.T_world_camera
        )
        a, b = (tuple(int(v) for v in np.round(q)) for q in pts)
        cv2.arrowedLine(img, a, b, (255, 0, 0), 2, cv2.LINE_AA, tipLength=0.15)
    cv2.putText(
        img,
        f"true {true_cov:.2f}",
        (10, 470),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.6,
        (255, 255, 255),
        1,
        cv2.LINE_AA,
    )
    return img


def run_seed(
    seed: int,
    resolution: int,
    perception: str,
    flatten: FlattenConfig,
    crumple_cfg: CrumpleConfig,
    motion: MotionConfig | None = None,
    frames_dir: Path | None = None,
    time_step: float | None = None,
) -> dict:
    """One crumple + flatten episode; its per-pull record with ground-truth coverage."""
    cfg = EpisodeConfig(
        seed=seed,
        towel=TowelSpec(resolution=resolution),
        towel_size_range=(0.25, 0.45),
        perception=perception,
        video_fps=0.0,
    )
    if time_step is not None:
        cfg = dataclasses.replace(cfg, sim=dataclasses.replace(cfg.sim, time_step=time_step))
    towel = seeded_towel(cfg)
    wall0 = time.perf_counter()
    with SimWorld(cfg.sim) as world, contextlib.ExitStack() as stack:
        parts = build_sim_cell(cfg, world)
        stack.callback(parts.model_world.close)
        settle(world, parts.cloth)
        flat = parts.oracle.cloth_vertices()
        area = metrics.flat_area(flat, parts.mesh.faces)
        t_crumple = time.perf_counter()
        crumpled = crumple(world, parts.cloth, crumple_rng(seed), crumple_cfg)
        t_crumple = time.perf_counter() - t_crumple
        estimator = VisionEstimator() if perception == "vision" else OracleEstimator(parts.oracle)
        frames = [] if frames_dir is not None else None
        cell = _MeasuredCell(
            world,
            parts.robot,
            parts.executor,
            parts.camera,
            estimator,
            motion or cfg.motion,
            flat_area=area,
            faces=parts.mesh.faces,
            oracle=parts.oracle,
            frames=frames,
            plan=lambda st: plan_pulls(st, towel.width, towel.height, flatten),
        )
        t_flat = time.perf_counter()
        try:
            rec = run_flatten(flatten, cell, (towel.width, towel.height), log=lambda s: None)
        finally:
            if frames is not None:
                import imageio.v3 as iio

                frames_dir.mkdir(parents=True, exist_ok=True)
                for k, frame in enumerate(frames):
                    iio.imwrite(frames_dir / f"seed{seed:03d}_{k}.png", frame)
        t_flat = time.perf_counter() - t_flat
    true = cell.true_coverage
    reached = next((k for k, c in enumerate(true) if c >= 0.9), None)
    return {
        "seed": seed,
        "towel": [towel.width, towel.height],
        "resolution": resolution,
        "time_step": cfg.sim.time_step,
        "perception": perception,
        "crumple": {"pinches": list(crumpled.pinches), "recentred": crumpled.recentred},
        "true_coverage": true,
        "perceived_coverage": [rec.initial_coverage] + [a["coverage_after"] for a in rec.actions],
        "actions": [
            {k: a[k] for k in ("label", "grasp", "place", "grasp_success", "shortfall_m")}
            | {"sim_seconds": a["sim_seconds"], "wall_seconds": a["wall_seconds"]}
            for a in rec.actions
        ],
        "n_actions": len(rec.actions),
        "actions_to_0.9": reached,
        "success": reached is not None and reached <= flatten.max_actions,
        "final_success": true[-1] >= 0.9,
        "crumple_wall_seconds": t_crumple,
        "flatten_wall_seconds": t_flat,
        "wall_seconds": time.perf_counter() - wall0,
    }


def summarise(rows: list[dict]) -> str:
    """Success share, actions and coverage distribution of measured seeds."""
    if not rows:
        return "no seeds"
    ok = [r for r in rows if r.get("success")]
    rows_ok = [r for r in rows if "true_coverage" in r]
    if not rows_ok:
        return f"seeds: {len(rows)}, all failed: {[(r['seed'], r.get('error')) for r in rows]}"
    start = np.array([r["true_coverage"][0] for r in rows if "true_coverage" in r])
    final = np.array([r["true_coverage"][-1] for r in rows if "true_coverage" in r])
    acts = [r["actions_to_0.9"] for r in ok]
    errors = [r for r in rows if "error" in r]
    lines = [
        f"seeds: {len(rows)}  success (true coverage ≥ 0.9 within 6 pulls): {len(ok)}/{len(rows)}"
        f" = {len(ok) / len(rows):.0%}",
        f"final true coverage ≥ 0.9 when the loop stopped: "
        f"{sum(bool(r.get('final_success')) for r in rows)}/{len(rows)}",
        f"pulls to 0.9 (successes): mean {np.mean(acts) if acts else float('nan'):.2f}, "
        f"max {max(acts) if acts else '-'}",
        f"true coverage crumpled: min {start.min():.2f} median {np.median(start):.2f} "
        f"max {start.max():.2f}",
        f"true coverage final:    min {final.min():.2f} median {np.median(final):.2f} "
        f"max {final.max():.2f}",
        f"wall per episode: mean {np.mean([r['wall_seconds'] for r in rows if 'wall_seconds' in r]):.0f} s",
    ]
    if errors:
        lines.append(f"errors: {[(r['seed'], r['error']) for r in errors]}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", nargs=2, type=int, default=[0, 20], metavar=("FIRST", "END"))
    ap.add_argument("--resolution", type=int, default=16)
    ap.add_argument("--perception", choices=("vision", "oracle"), default="vision")
    ap.add_argument("--out", type=Path, default=Path("runs/flatten.jsonl"))
    ap.add_argument("--frames", type=Path, default=None, help="save an overlay per observation")
    ap.add_argument("--flatten", default="{}", help="FlattenConfig overrides as JSON")
    ap.add_argument("--crumple", default="{}", help="CrumpleConfig overrides as JSON")
    ap.add_argument("--time-step", type=float, default=None, help="physics step (s)")
    ap.add_argument("--motion", default="{}", help="MotionConfig overrides for the pulls, JSON")
    ap.add_argument("--one", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)

    def cfg_of(cls, text):
        over = {k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(text).items()}
        return dataclasses.replace(cls(), **over)

    flatten, crumple_cfg = cfg_of(FlattenConfig, args.flatten), cfg_of(CrumpleConfig, args.crumple)
    motion = cfg_of(MotionConfig, args.motion)
    if args.one is not None:  # child process: one seed, JSON on stdout's last line
        try:
            row = run_seed(
                args.one,
                args.resolution,
                args.perception,
                flatten,
                crumple_cfg,
                motion,
                args.frames,
                args.time_step,
            )
        except Exception as exc:  # reported, not hidden
            import traceback

            row = {
                "seed": args.one,
                "error": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc()[-3000:],
            }
        print(json.dumps(row))
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    done = {}
    if args.out.exists():
        for line in args.out.read_text().splitlines():
            row = json.loads(line)
            done[row["seed"]] = row
    for seed in range(*args.seeds):
        if seed in done:
            continue
        cmd = [sys.executable, __file__, "--one", str(seed), "--resolution", str(args.resolution)]
        cmd += ["--perception", args.perception, "--flatten", args.flatten]
        cmd += ["--crumple", args.crumple, "--motion", args.motion]
        if args.time_step is not None:
            cmd += ["--time-step", str(args.time_step)]
        if args.frames is not None:
            cmd += ["--frames", str(args.frames)]
        out = subprocess.run(cmd, capture_output=True, text=True, check=False)
        lines = out.stdout.strip().splitlines()
        row = json.loads(lines[-1]) if lines else {"seed": seed, "error": out.stderr[-2000:]}
        done[seed] = row
        with args.out.open("a") as f:
            f.write(json.dumps(row) + "\n")
        cov = " ".join(f"{c:.2f}" for c in row.get("true_coverage", []))
        print(f"seed {seed}: {row.get('error') or cov}  ({row.get('wall_seconds', 0):.0f} s)")
    rows = [done[s] for s in range(*args.seeds) if s in done]
    print(summarise(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
