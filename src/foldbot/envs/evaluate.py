"""Run a baseline policy on TowelFlatten over seeds and report how many towels it flattened.

    python -m foldbot.envs.evaluate --policy pulls --seeds 0-19 --workers 2 --out runs/env/pulls.json

Each seed is the suite's towel (`--suite`, default towel_crumpled); a towel counts as flattened
when the coverage reaches the environment's goal (0.9) within its steps (6), issue 6's target.
Prints a per-seed table and the success rate with its 95 % interval, and writes them as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from tqdm import tqdm

from foldbot.bench.suite import parse_seeds
from foldbot.bench.summary import success_interval
from foldbot.envs.policies import PullPolicy, RandomPolicy
from foldbot.envs.towel_flatten import TowelFlattenConfig, TowelFlattenEnv
from foldbot.errors import FoldbotError

POLICIES = ("pulls", "random")
"""Baselines by name: the one-arm flattening pulls, or uniform random pick-and-place."""


def run_seed(config: TowelFlattenConfig, policy_name: str, seed: int) -> dict[str, Any]:
    """One episode of `policy_name` on the towel of `seed`: its coverage after each step."""
    env = TowelFlattenEnv(config)
    try:
        policy = PullPolicy(env) if policy_name == "pulls" else RandomPolicy(env, seed)
        wall = time.perf_counter()
        _obs, info = env.reset(seed=seed)
        row: dict[str, Any] = {
            "seed": seed,
            "suite_seed": info["seed"],
            "skipped_seeds": sorted(info["skipped_seeds"]),
            "coverage_start": info["coverage"],
            "coverage": [],
            "grasps_held": 0,
            "infeasible": 0,
            "diverged": None,
            "stopped": False,
        }
        done = False
        while not done:
            action = policy(info)
            if action is None:  # the policy sees nothing left to do
                row["stopped"] = True
                break
            _obs, _reward, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            if info.get("diverged"):
                row["diverged"] = info["diverged"]
                break
            row["coverage"].append(info["coverage"])
            row["grasps_held"] += bool(info["grasp_success"])
            row["infeasible"] += info["infeasible"] is not None
        row["success"] = bool(info["is_success"]) and row["diverged"] is None
        row["steps"] = info["steps"]
        row["wall_seconds"] = time.perf_counter() - wall
        return row
    finally:
        env.close()


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Flattened towels over all seeds, with the 95 % Wilson interval."""
    n, ok = len(rows), sum(r["success"] for r in rows)
    return {
        "episodes": n,
        "flattened": ok,
        "success_rate": ok / n if n else None,
        "interval_95": success_interval(ok, n),
        "diverged": sum(r["diverged"] is not None for r in rows),
    }


def table(rows: list[dict[str, Any]]) -> str:
    """A Markdown row per seed: start coverage, coverage after each step, grasps held."""
    lines = [
        "| seed | start | coverage after each step | grasps held | flattened |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        seed = str(r["seed"]) + (
            f" (ran {r['suite_seed']})" if r["suite_seed"] != r["seed"] else ""
        )
        steps = " → ".join(f"{c:.2f}" for c in r["coverage"]) or "–"
        if r["diverged"]:
            steps += " → diverged"
        held = f"{r['grasps_held']} of {r['steps']}"
        lines.append(
            f"| {seed} | {r['coverage_start']:.2f} | {steps} | {held} | "
            f"{'yes' if r['success'] else 'no'} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m foldbot.envs.evaluate",
        description="Run a baseline policy on foldbot/TowelFlatten-v0 over seeds.",
    )
    parser.add_argument("--policy", choices=POLICIES, default="pulls", help="default: pulls")
    parser.add_argument("--seeds", default="0-9", help="e.g. 0-19 or 1,4,7 (default 0-9)")
    parser.add_argument("--suite", default="towel_crumpled", help="default: towel_crumpled")
    parser.add_argument(
        "--resolution", type=int, default=None, help="vertices along the longer side"
    )
    parser.add_argument("--workers", type=int, default=1, help="episodes at once (default 1)")
    parser.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    args = parser.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        config = TowelFlattenConfig(suite=args.suite, resolution=args.resolution)
        TowelFlattenEnv(config).close()  # the suite and settings, checked before any episode
        if args.workers < 1:
            raise FoldbotError(f"--workers must be ≥ 1, got {args.workers}")
    except FoldbotError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with ThreadPoolExecutor(args.workers) as pool:
        futures = [pool.submit(run_seed, config, args.policy, s) for s in seeds]
        rows = [f.result() for f in tqdm(futures, desc=args.policy, unit="towel")]
    result = {"policy": args.policy, "suite": args.suite, **summary(rows), "rows": rows}
    print(table(rows))
    lo, hi = result["interval_95"] or (0.0, 0.0)
    print(
        f"{args.policy}: flattened {result['flattened']} of {result['episodes']} "
        f"(95 % interval {lo:.0%}–{hi:.0%}), diverged {result['diverged']}"
    )
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
