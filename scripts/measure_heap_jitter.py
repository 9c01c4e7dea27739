"""Measure how restless a crumpled towel is at rest: the physics probe behind the heap
table in docs/experiments.md.

For each seed of the `towel_crumpled` suite: build its cell (arm parked at home, untouched), settle
the flat towel and step it 1 s more (the flat baseline), crumple it (sim.crumple), then step 4 s;
each step's fastest cloth vertex (m/s, from positions) and the deepest vertex under the table top
are recorded. A cloth at rest shows only the table contact's one-step gravity bounce
(≈ 2·g·dt ≈ 0.05 m/s at 1/360 s), as the flat baseline does. Physics
overrides (`--set cloth.damping_stiffness=0.5`, `--set sim.time_step=0.0020833`,
`--set engine.numSolverIterations=150`, `--set load.repulsionStiffness=2`) try Bullet's knobs.
Each seed runs in its own process (Bullet's soft body is deterministic only as the first
simulation in a process); one JSON line per seed on stdout.

    .venv/bin/python scripts/measure_heap_jitter.py --seeds 0-7 [--set KEY=VALUE ...]
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from foldbot.bench.suite import parse_seeds

sys.path.insert(0, str(Path(__file__).resolve().parent))
from per_seed import run_each_seed

REST_SECONDS = 4.0
GROUPS = ("cloth", "sim", "engine", "load")


def parse_overrides(items: list[str]) -> dict[str, dict[str, float]]:
    """`group.name=value` strings → {group: {name: value}}; groups: cloth, sim, engine, load."""
    out: dict[str, dict[str, float]] = {g: {} for g in GROUPS}
    for item in items:
        key, sep, value = item.partition("=")
        group, dot, name = key.partition(".")
        if not sep or not dot or group not in GROUPS or not name:
            raise SystemExit(
                f"--set {item!r}: expected GROUP.NAME=VALUE with GROUP one of {', '.join(GROUPS)}"
            )
        try:
            out[group][name] = float(value)
        except ValueError:
            raise SystemExit(f"--set {item!r}: {value!r} is not a number") from None
    return out


def measure(seed: int, over: dict[str, dict[str, float]]) -> dict:
    """One seed's rest figures (runs in the calling process)."""
    import pybullet as p

    from foldbot.bench.suite import load_suite
    from foldbot.pipeline import build_sim_cell
    from foldbot.sim.cloth import settle
    from foldbot.sim.crumple import crumple
    from foldbot.sim.world import SimWorld

    if over["load"]:  # extra loadSoftBody arguments, for this process only
        load = p.loadSoftBody

        def load_with(*args, **kwargs):
            return load(*args, **{**kwargs, **over["load"]})

        p.loadSoftBody = load_with
    spec = next(e for e in load_suite("towel_crumpled").episodes if e.seed == seed)
    cfg = spec.to_config()
    cfg = dataclasses.replace(
        cfg,
        cloth=dataclasses.replace(cfg.cloth, **over["cloth"]),
        sim=dataclasses.replace(cfg.sim, **over["sim"]),
    )
    out: dict = {"seed": seed}
    try:
        with SimWorld(cfg.sim) as world:
            if over["engine"]:
                engine = {k: (int(v) if v.is_integer() else v) for k, v in over["engine"].items()}
                p.setPhysicsEngineParameter(physicsClientId=world.client, **engine)
            parts = build_sim_cell(cfg, world)
            parts.model_world.close()
            settle(world, parts.cloth)
            flat = _top_speeds(world, parts.cloth, 1.0)[0]
            crumple(world, parts.cloth, np.random.default_rng([seed, 2]))
            s, deepest = _top_speeds(world, parts.cloth, REST_SECONDS)
            out.update(
                flat_p95_speed=float(np.percentile(flat, 95)),
                median_speed=float(np.median(s)),
                p95_speed=float(np.percentile(s, 95)),
                max_speed=float(s.max()),
                deepest_under_table_mm=1000.0 * deepest,
            )
    except Exception as exc:  # a diverged cloth is a result here, not a crash
        out["error"] = f"{type(exc).__name__}: {exc}"[:200]
    return out


def _top_speeds(world, cloth, seconds: float) -> tuple[np.ndarray, float]:
    """Step `seconds`: each step's fastest vertex speed (m/s) and the deepest vertex under the
    table top over them (m)."""
    prev = cloth.sim_vertices()
    speeds, deepest = [], 0.0
    for _ in range(round(seconds / world.time_step)):
        world.step()
        v = cloth.sim_vertices()
        speeds.append(float(np.linalg.norm(v - prev, axis=1).max()) / world.time_step)
        deepest = max(deepest, world.layout.table_height - float(v[:, 2].min()))
        prev = v
    return np.asarray(speeds), deepest


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--seeds", default="0-7", help="seeds: '0-7', '0,3,5' or one seed (default 0-7)"
    )
    ap.add_argument("--set", action="append", default=[], metavar="GROUP.NAME=VALUE")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # child process: one seed
    args = ap.parse_args()
    over = parse_overrides(args.set)
    if args.one is not None:
        print(json.dumps(measure(args.one, over)), flush=True)
        return 0
    extra = [arg for item in args.set for arg in ("--set", item)]
    rows = run_each_seed(__file__, parse_seeds(args.seeds), extra)
    ok = [r for r in rows if "error" not in r]
    if ok:
        med = np.median([r["median_speed"] for r in ok])
        deep = max(r["deepest_under_table_mm"] for r in ok)
        print(
            f"# {len(rows)} seeds, {len(rows) - len(ok)} diverged; median of per-seed median "
            f"top vertex speed {med:.3f} m/s; deepest vertex {deep:.1f} mm under the table top",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
