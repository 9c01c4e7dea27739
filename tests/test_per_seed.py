"""scripts/per_seed.py: each seed in its own interpreter, rows in the seeds' order, a child that
printed no JSON reported with its stderr."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "per_seed.py"
spec = importlib.util.spec_from_file_location("per_seed", SCRIPT)
per_seed = importlib.util.module_from_spec(spec)
sys.modules["per_seed"] = per_seed
spec.loader.exec_module(per_seed)

PROBE = """
import json, os, sys
seed = int(sys.argv[sys.argv.index("--one") + 1])
if seed == 3:
    sys.exit("seed 3 fell over")
print("warming up")
print(json.dumps({"seed": seed, "pid": os.getpid(), "extra": sys.argv[3:]}))
"""


def test_each_seed_runs_in_its_own_process_in_order(tmp_path, capsys):
    probe = tmp_path / "probe.py"
    probe.write_text(PROBE)
    rows = per_seed.run_each_seed(str(probe), [5, 3, 1], ["--flag", "x"], workers=2)
    assert [r["seed"] for r in rows] == [5, 3, 1]
    assert rows[0]["extra"] == ["--flag", "x"]
    assert rows[0]["pid"] != rows[2]["pid"]
    assert "seed 3 fell over" in rows[1]["error"]
    assert capsys.readouterr().out.count("\n") == 3  # one JSON line per seed, as it came
    with pytest.raises(SystemExit, match="--workers must be ≥ 1, got 0"):
        per_seed.run_each_seed(str(probe), [1], [], workers=0)
