"""Run a measurement script once per seed, each in a fresh interpreter: Bullet's soft body is
deterministic only as the first simulation in a process. The probes in this folder share it:
each, called with `--one SEED`, prints one JSON line for that seed."""

from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor


def run_one_seed(script: str, seed: int, args: list[str]) -> dict:
    """`python script --one SEED *args`: the JSON row it printed last, or {"seed": SEED,
    "error": its stderr's end} where it printed none."""
    res = subprocess.run(
        [sys.executable, script, "--one", str(seed), *args],
        capture_output=True,
        text=True,
        check=False,
    )
    line = res.stdout.strip().splitlines()[-1] if res.stdout.strip() else ""
    return json.loads(line) if line.startswith("{") else {"seed": seed, "error": res.stderr[-300:]}


def run_each_seed(script: str, seeds: list[int], args: list[str], workers: int = 1) -> list[dict]:
    """run_one_seed for each seed, `workers` at once; print each seed's JSON row as it comes (in
    the seeds' order) and return them all."""
    if workers < 1:
        raise SystemExit(f"--workers must be ≥ 1, got {workers}")
    rows = []
    with ThreadPoolExecutor(workers) as pool:
        for row in pool.map(lambda seed: run_one_seed(script, seed, args), seeds):
            rows.append(row)
            print(json.dumps(row), flush=True)
    return rows
