"""Run a baseline policy on a towel environment over seeds and report how many towels it
flattened or folded.

    python -m foldbot.envs.evaluate --policy pulls --seeds 0-19 --workers 2 --out runs/env/pulls.json
    python -m foldbot.envs.evaluate --env spread --policy spreads --seeds 0-19 --workers 2
    python -m foldbot.envs.evaluate --env fold --recipe quarter --seeds 0-19 --workers 2

Each seed is the suite's towel (`--suite`, default the environment's: towel_crumpled for
TowelFlatten, towel_crumpled_two_arms for TowelSpread, towel_loop for TowelFold,
towel_two_arms for TowelFoldPair); a towel counts
as flattened when the coverage reaches the environment's goal (0.9) within its steps (6), issue
6's target, and as folded when the fold meets the benchmark's success rule within its steps (6).
Prints a per-seed table and the success rate with its 95 % interval, and writes them as JSON.

`--record DIR` also keeps every episode's transitions for learning, one file per seed
(DIR/towel_flatten-sNNNN.npz, or towel_spread-…, towel_fold-…, towel_fold_pair-…; written whole
or not at all;
`read_episode` loads one). A seed already recorded there is not run again, so an interrupted
recording resumes.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from foldbot.bench.suite import parse_seeds
from foldbot.bench.summary import success_interval
from foldbot.envs.policies import PullPolicy, RandomPolicy, RecipePolicy, SpreadPolicy
from foldbot.envs.towel_flatten import TowelFlattenEnv, TowelSpreadEnv
from foldbot.envs.towel_fold import TowelFoldEnv, TowelFoldPairEnv
from foldbot.envs.towel_task import TowelTaskConfig, TowelTaskEnv
from foldbot.errors import FoldbotError
from foldbot.planning.recipes import RECIPES

ENVS = {
    "flatten": TowelFlattenEnv,
    "spread": TowelSpreadEnv,
    "fold": TowelFoldEnv,
    "fold_pair": TowelFoldPairEnv,
}
"""The environments by name: TowelFlatten (one arm, pick-and-place), TowelSpread (two arms),
TowelFold (one arm, fold carries), TowelFoldPair (two arms, two carries at once)."""
POLICIES = {
    "pulls": ("flatten",),
    "spreads": ("spread",),
    "recipe": ("fold", "fold_pair"),
    "random": tuple(ENVS),
}
"""Baselines by name, with the environments each drives: the one-arm flattening pulls, the
two-arm spreads, the recipe's carries, or uniform random actions."""
BASELINES = {"flatten": "pulls", "spread": "spreads", "fold": "recipe", "fold_pair": "recipe"}
"""Each environment's default policy."""
MEASURES = {
    "flatten": "coverage",
    "spread": "coverage",
    "fold": "fold_error_mm",
    "fold_pair": "fold_error_mm",
}
"""What each environment's rows follow step by step (an info key)."""
DONE = {"flatten": "flattened", "spread": "flattened", "fold": "folded", "fold_pair": "folded"}
"""What a success is called in each environment's summary."""


def make_policy(name: str, env: TowelTaskEnv, seed: int):
    """The baseline `name` (POLICIES) for `env`."""
    if name == "pulls":
        return PullPolicy(env)
    if name == "spreads":
        return SpreadPolicy(env)
    if name == "recipe":
        return RecipePolicy(env)
    return RandomPolicy(env, seed)


RECORD_NAME = "towel_{env}-s{seed:04d}.npz"
"""An episode's file under --record DIR (env: flatten, spread or fold)."""


def write_episode(path: Path, steps: dict[str, list], row: dict[str, Any]) -> None:
    """Save one episode's transitions as an .npz, atomically (a hidden file renamed into
    place): `rgb`, `depth` (T+1 frames: the reset's, then one after each step), `action` (T × 4, or T × 8 for a pair),
    `reward`, `coverage` (T+1; a fold's also `fold_error_mm`, T+1), `grasp_success` (T; False
    where no grasp was tried), `terminated`, `truncated` (T), and `seed`, `suite_seed`, `env`,
    `policy`, `suite`, `stopped` (the policy saw nothing left to do before the episode ended)."""
    tmp = path.with_name(f".{path.name}.partial-{os.getpid()}")
    more = {}
    if "fold_error_mm" in steps:
        more["fold_error_mm"] = np.asarray(steps["fold_error_mm"], np.float32)
    with tmp.open("wb") as f:
        np.savez_compressed(
            f,
            rgb=np.stack(steps["rgb"]),
            depth=np.stack(steps["depth"]),
            action=np.asarray(steps["action"], np.float32).reshape(
                -1, ENVS[row["env"]].ACTION_SIZE
            ),
            reward=np.asarray(steps["reward"], np.float32),
            coverage=np.asarray(steps["coverage"], np.float32),
            grasp_success=np.asarray(steps["grasp_success"], bool),
            terminated=np.asarray(steps["terminated"], bool),
            truncated=np.asarray(steps["truncated"], bool),
            seed=row["seed"],
            suite_seed=row["suite_seed"],
            env=row["env"],
            policy=row["policy"],
            suite=row["suite"],
            stopped=row["stopped"],
            **more,
        )
    tmp.replace(path)


def read_episode(path: Path) -> dict[str, np.ndarray]:
    """One recorded episode (write_episode's arrays) as a dict of arrays."""
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def run_seed(
    config: TowelTaskConfig,
    policy_name: str,
    seed: int,
    record: Path | None = None,
    env_name: str = "flatten",
) -> dict[str, Any]:
    """One episode of `policy_name` on the towel of `seed` in the environment `env_name`
    (ENVS): its measure (MEASURES: coverage, or fold error) after each step; with `record`, its
    transitions saved there (write_episode)."""
    env = ENVS[env_name](config)
    measure = MEASURES[env_name]
    try:
        policy = make_policy(policy_name, env, seed)
        wall = time.perf_counter()
        obs, info = env.reset(seed=seed)
        steps: dict[str, list] = {
            "rgb": [obs["rgb"]],
            "depth": [obs["depth"]],
            "coverage": [info["coverage"]],
            measure: [info[measure]],
            **{k: [] for k in ("action", "reward", "grasp_success", "terminated", "truncated")},
        }
        row: dict[str, Any] = {
            "seed": seed,
            "suite_seed": info["seed"],
            "skipped_seeds": sorted(info["skipped_seeds"]),
            f"{measure}_start": info[measure],
            "infeasible": 0,
            "diverged": None,
            "failed": None,
            "stopped": False,
        }
        done = False
        while not done:
            action = policy(info)
            if action is None:  # the policy sees nothing left to do
                row["stopped"] = True
                break
            obs, reward, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            if info.get("diverged") or info.get("failed"):
                row["diverged"] = info.get("diverged")
                row["failed"] = info.get("failed")
                break
            for key, value in (
                ("rgb", obs["rgb"]),
                ("depth", obs["depth"]),
                ("coverage", info["coverage"]),
                *(() if measure == "coverage" else ((measure, info[measure]),)),
                ("action", action),
                ("reward", reward),
                ("grasp_success", bool(info["grasp_success"])),
                ("terminated", terminated),
                ("truncated", truncated),
            ):
                steps[key].append(value)
            row["infeasible"] += info["infeasible"] is not None
        row[measure] = steps[measure][1:]
        row["grasps_held"] = sum(steps["grasp_success"])
        row["success"] = bool(info["is_success"]) and not (row["diverged"] or row["failed"])
        row["steps"] = info["steps"]
        row["wall_seconds"] = time.perf_counter() - wall
        if record is not None and not (row["diverged"] or row["failed"]):  # not data
            row |= {"env": env_name, "policy": policy_name, "suite": config.suite}
            write_episode(record / RECORD_NAME.format(env=env_name, seed=seed), steps, row)
        return row
    finally:
        env.close()


def summary(rows: list[dict[str, Any]], done: str = "flattened") -> dict[str, Any]:
    """Towels flattened (or folded: `done`) over all seeds, with the 95 % Wilson interval."""
    n, ok = len(rows), sum(r["success"] for r in rows)
    return {
        "episodes": n,
        done: ok,
        "success_rate": ok / n if n else None,
        "interval_95": success_interval(ok, n),
        "diverged": sum(r["diverged"] is not None for r in rows),
        "failed": sum(r.get("failed") is not None for r in rows),
    }


def table(rows: list[dict[str, Any]], measure: str = "coverage", done: str = "flattened") -> str:
    """A Markdown row per seed: the measure (MEASURES) at the start and after each step, grasps
    held, success."""
    what, form = ("coverage", "{:.2f}") if measure == "coverage" else ("fold error (mm)", "{:.1f}")
    lines = [
        f"| seed | start | {what} after each step | grasps held | {done} |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        seed = str(r["seed"]) + (
            f" (ran {r['suite_seed']})" if r["suite_seed"] != r["seed"] else ""
        )
        steps = " → ".join(form.format(c) for c in r[measure]) or "–"
        if r["diverged"] or r.get("failed"):
            steps += " → diverged" if r["diverged"] else " → failed"
        held = f"{r['grasps_held']} of {r['steps']}"
        lines.append(
            f"| {seed} | {form.format(r[f'{measure}_start'])} | {steps} | {held} | "
            f"{'yes' if r['success'] else 'no'} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m foldbot.envs.evaluate",
        description="Run a baseline policy on foldbot/TowelFlatten-v0, TowelSpread-v0 or "
        "TowelFold-v0 over seeds.",
    )
    parser.add_argument(
        "--env",
        choices=tuple(ENVS),
        default="flatten",
        help="flatten (one arm, the default), spread (two arms), fold (one arm) or fold_pair "
        "(two arms)",
    )
    parser.add_argument(
        "--policy",
        choices=tuple(POLICIES),
        default=None,
        help="pulls (flatten), spreads (spread), recipe (fold, fold_pair) or random; default: the "
        "environment's baseline",
    )
    parser.add_argument(
        "--recipe",
        choices=RECIPES,
        default=None,
        help="--env fold or fold_pair: the recipe whose goal the towel is folded to (default half)",
    )
    parser.add_argument("--seeds", default="0-9", help="e.g. 0-19 or 1,4,7 (default 0-9)")
    parser.add_argument("--suite", default=None, help="default: the environment's")
    parser.add_argument(
        "--resolution", type=int, default=None, help="vertices along the longer side"
    )
    parser.add_argument("--workers", type=int, default=1, help="episodes at once (default 1)")
    parser.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    parser.add_argument(
        "--record", type=Path, default=None, help="keep each episode's transitions in this folder"
    )
    args = parser.parse_args(argv)
    env_cls = ENVS[args.env]
    policy = args.policy or BASELINES[args.env]
    measure, done_word = MEASURES[args.env], DONE[args.env]
    try:
        if args.env not in POLICIES[policy]:
            raise FoldbotError(
                f"policy {policy!r} drives {' or '.join(POLICIES[policy])}, not --env {args.env}"
            )
        if args.recipe is not None and args.env not in ("fold", "fold_pair"):
            raise FoldbotError(
                f"--recipe is TowelFold's (--env fold or fold_pair), not --env {args.env}'s"
            )
        seeds = parse_seeds(args.seeds)
        fields: dict[str, Any] = {} if args.suite is None else {"suite": args.suite}
        if args.recipe is not None:
            fields["recipe"] = args.recipe
        config = env_cls.CONFIG(resolution=args.resolution, **fields)
        env_cls(config).close()  # the suite and settings, checked before any episode
        if args.workers < 1:
            raise FoldbotError(f"--workers must be ≥ 1, got {args.workers}")
    except FoldbotError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.record is not None:
        args.record.mkdir(parents=True, exist_ok=True)
        done = [
            s for s in seeds if (args.record / RECORD_NAME.format(env=args.env, seed=s)).exists()
        ]
        if done:
            print(f"{len(done)} seeds already recorded in {args.record}: not run again")
        seeds = [s for s in seeds if s not in done]
    with ThreadPoolExecutor(args.workers) as pool:
        futures = [pool.submit(run_seed, config, policy, s, args.record, args.env) for s in seeds]
        rows = [f.result() for f in tqdm(futures, desc=policy, unit="towel")]
    result = {
        "env": args.env,
        "policy": policy,
        "suite": config.suite,
        **({"recipe": config.recipe} if isinstance(config, TowelFoldEnv.CONFIG) else {}),
        **summary(rows, done_word),
        "rows": rows,
    }
    print(table(rows, measure, done_word))
    lo, hi = result["interval_95"] or (0.0, 0.0)
    print(
        f"{policy}: {done_word} {result[done_word]} of {result['episodes']} "
        f"(95 % interval {lo:.0%}–{hi:.0%}), diverged {result['diverged']}, "
        f"failed otherwise {result['failed']}"
    )
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
