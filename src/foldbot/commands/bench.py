"""`foldbot bench`: run fold episodes over a range of seeds and summarise them.

Each episode is a `foldbot fold` run writing its own folder (DIR/seed_NNNN); finished episodes are
not run again, so an interrupted run resumes. The summary (DIR/summary.json and a table on stdout)
gives success rate, fold error, normalized performance, coverage and speed.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from tqdm import tqdm

from foldbot.commands.fold import add_recipe_and_perception
from foldbot.errors import ConfigError, FoldbotError, OutputError
from foldbot.io.episode import is_episode_dir
from foldbot.pipeline import EpisodeConfig, run_episode


def parse_seeds(text: str) -> list[int]:
    """'0-9' or '0,3,5' or '4' → sorted unique seeds."""
    seeds: set[int] = set()
    try:
        for part in text.split(","):
            if "-" in part:
                lo, hi = (int(v) for v in part.split("-", 1))
                if hi < lo:
                    raise ValueError
                seeds.update(range(lo, hi + 1))
            else:
                seeds.add(int(part))
    except ValueError:
        raise ConfigError(f"--seeds must look like '0-9' or '0,3,5', got {text!r}") from None
    if not seeds or min(seeds) < 0:
        raise ConfigError(f"--seeds must name seeds ≥ 0, got {text!r}")
    return sorted(seeds)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `foldbot bench`."""
    add_recipe_and_perception(parser)
    parser.add_argument("--seeds", default="0-9", help="seeds to run, e.g. 0-19 or 0,4,7")
    parser.add_argument(
        "--size-range",
        nargs=2,
        type=float,
        metavar=("LO", "HI"),
        default=None,
        help="draw each towel side from [LO, HI] m per seed (default: 0.30 m square)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=max(1, (os.cpu_count() or 1)),
        help="parallel episode processes (default: CPU count)",
    )
    parser.add_argument("--video-fps", type=float, default=0.0, help="video per episode (0 = off)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")


def _episode(cfg: EpisodeConfig, out: Path) -> dict:
    try:
        return run_episode(cfg, out, overwrite=True, log=lambda *_: None)
    except FoldbotError as exc:
        return {"seed": cfg.seed, "error": f"{type(exc).__name__}: {exc}"}


def summarise(results: list[dict]) -> dict:
    """Aggregate per-episode results (failed runs count as failures, not scored)."""
    scored = [r for r in results if "error" not in r]
    err = np.array([r["fold_error_mm"] for r in scored])
    perf = np.array([r["normalized_performance"] for r in scored])

    def stats(a: np.ndarray) -> dict:
        if a.size == 0:
            return {}
        return {
            "mean": float(a.mean()),
            "median": float(np.median(a)),
            "p95": float(np.percentile(a, 95)),
            "min": float(a.min()),
            "max": float(a.max()),
        }

    sim = sum(r["sim_seconds"] for r in scored)
    wall = sum(r["wall_seconds"] for r in scored)
    return {
        "episodes": len(results),
        "success_rate": sum(bool(r.get("success")) for r in results) / max(1, len(results)),
        "fold_error_mm": stats(err),
        "normalized_performance": stats(perf),
        "coverage_mean": float(np.mean([r["coverage"] for r in scored])) if scored else None,
        "sim_seconds_per_episode": sim / max(1, len(scored)),
        "wall_seconds_per_episode": wall / max(1, len(scored)),
        "sim_speed": sim / wall if wall > 0 else None,
        "errors": {str(r["seed"]): r["error"] for r in results if "error" in r},
    }


def run(args: argparse.Namespace) -> int:
    """Run the missing episodes, then summarise all of them."""
    seeds = parse_seeds(args.seeds)
    if args.workers < 1:
        raise ConfigError(f"--workers must be ≥ 1, got {args.workers}")
    out: Path = args.out
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create output folder {out}: {exc.strerror}") from exc
    todo, results = [], []
    for seed in seeds:
        ep = out / f"seed_{seed:04d}"
        if is_episode_dir(ep):
            results.append(json.loads((ep / "result.json").read_text()))
        else:
            cfg = EpisodeConfig(
                recipe=args.recipe,
                perception=args.perception,
                seed=seed,
                video_fps=args.video_fps,
                towel_size_range=None if args.size_range is None else tuple(args.size_range),
            )
            todo.append((cfg, ep))
    t0 = time.perf_counter()
    # One fresh process per episode: Bullet's soft-body solver keeps process-global random state,
    # so an episode is reproducible (same seed, same result) only as the first in its process.
    with ProcessPoolExecutor(max_workers=args.workers, max_tasks_per_child=1) as pool:
        futures = [pool.submit(_episode, cfg, ep) for cfg, ep in todo]
        for fut in tqdm(as_completed(futures), total=len(futures), desc="episodes", unit="ep"):
            results.append(fut.result())
    results.sort(key=lambda r: r["seed"])
    summary = {
        "recipe": args.recipe,
        "towel_size_range": args.size_range,
        "perception": args.perception,
        "seeds": seeds,
        "wall_seconds_total": time.perf_counter() - t0,
        **summarise(results),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    _print_table(summary)
    print(f"summary written to {out / 'summary.json'}")
    return 0


def _print_table(s: dict) -> None:
    e, p = s["fold_error_mm"], s["normalized_performance"]
    print(f"\n{s['recipe']} fold, {s['perception']} perception, {s['episodes']} episodes")
    print(f"  success rate            {100 * s['success_rate']:.0f} %")
    if e:
        print(
            f"  fold error (mm)         mean {e['mean']:.1f}  median {e['median']:.1f}  "
            f"p95 {e['p95']:.1f}  max {e['max']:.1f}"
        )
        print(
            f"  normalized performance  mean {p['mean']:.3f}  median {p['median']:.3f}  "
            f"min {p['min']:.3f}"
        )
        print(f"  coverage (mean)         {s['coverage_mean']:.2f}")
        print(
            f"  per episode             {s['sim_seconds_per_episode']:.1f} s simulated, "
            f"{s['wall_seconds_per_episode']:.1f} s wall (sim speed {s['sim_speed']:.2f}× real time)"
        )
    for seed, err in s["errors"].items():
        print(f"  seed {seed}: {err}")
