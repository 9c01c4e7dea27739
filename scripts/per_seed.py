"""Run a measurement script once per seed, each in a fresh interpreter: Bullet's soft body is
deterministic only as the first simulation in a process. The probes in this folder share it:
each, called with `--one SEED`, prints one JSON line for that seed."""

from __future__ import annotations

import json
import subprocess
import sys


def run_each_seed(script: str, seeds: list[int], args: list[str]) -> list[dict]:
    """`python script --one SEED *args` for each seed; print each seed's JSON row as it comes and
    return them all. A child that printed no JSON gives {"seed": SEED, "error": its stderr's end}."""
    rows = []
    for seed in seeds:
        res = subprocess.run(
            [sys.executable, script, "--one", str(seed), *args],
            capture_output=True,
            text=True,
            check=False,
        )
        line = res.stdout.strip().splitlines()[-1] if res.stdout.strip() else ""
        row = (
            json.loads(line) if line.startswith("{") else {"seed": seed, "error": res.stderr[-300:]}
        )
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows
