"""scripts/flatten_table.py on a bench folder written to disk: one row per towel, the divergence's
stage and segment read from its error record."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "flatten_table.py"
EPISODE = "towel-half-vision-closed-crumpled-s{:04d}"


def _bench_folder(root: Path) -> Path:
    episodes = root / "episodes"
    (episodes / EPISODE.format(1)).mkdir(parents=True)
    missed = [{"grasp_success": [False, True]}, {"grasp_success": [False, False]}]  # and a retry
    spread = {
        "coverage_before": 0.4,
        "coverage_after": 0.41,
        "grasp_success": False,
        "attempts": missed,
    }
    carried = {
        "coverage_before": 0.41,
        "coverage_after": 0.97,
        "grasp_success": True,
        "attempts": [{"grasp_success": [True, True]}],
    }
    result = {
        "fold_error_mm": 7.25,
        "success": True,
        "flatten": {"success": True, "coverage_start": 0.38, "coverage_end": 0.99,
                    "pulls": [spread, carried]},
    }  # fmt: skip
    (episodes / EPISODE.format(1) / "result.json").write_text(json.dumps(result))
    diverged = {
        "id": EPISODE.format(2),
        "error_type": "SimulationDivergedError",
        "error": "cloth simulation diverged: … (in segment come_down, 0.14 s in)",
        "log_tail": ["crumpled: coverage 0.43; flattening…", "flatten 1: spread … → 0.22 → 0.32"],
    }
    (episodes / f"{EPISODE.format(2)}.error.json").write_text(json.dumps(diverged))
    in_fold = {**diverged, "error": "cloth simulation diverged: a vertex lies 1.3 m out"}
    in_fold["log_tail"] = [*diverged["log_tail"], "flattened: coverage 0.40 → 0.91 in 1 actions"]
    (episodes / f"{EPISODE.format(3)}.error.json").write_text(json.dumps(in_fold))
    (episodes / f"{EPISODE.format(3)}.failed").mkdir()  # the failed episode's pictures: skipped
    crumpling = {
        **in_fold,
        "log_tail": ["settling the cloth (176 vertices)…", "crumpling the towel…"],
    }
    (episodes / f"{EPISODE.format(4)}.error.json").write_text(json.dumps(crumpling))
    return root


def test_one_row_per_towel_and_the_counts(tmp_path: Path) -> None:
    run = subprocess.run(
        [sys.executable, str(SCRIPT), str(_bench_folder(tmp_path / "run"))],
        capture_output=True,
        text=True,
        check=True,
    )
    rows = [
        line for line in run.stdout.splitlines() if line.startswith("| ") and "seed" not in line
    ]
    assert len(rows) == 4
    assert rows[0].startswith("| 1 | flattened | 0.38 → 0.99 | 0.40→0.41x 0.41→0.97 | 2 | 7.2 mm ✓")
    assert "| 2 | diverged while flattening (in come_down) after 1 actions |" in rows[1]
    assert "| 3 | diverged in the fold (outside a segment) after 1 actions |" in rows[2]
    assert "| 4 | diverged while crumpling (outside a segment) after 0 actions |" in rows[3]
    assert "4 episodes: flattened 1, diverged 3, neither 0, other errors 0; folds succeeded 1" in (
        run.stdout
    )


def test_a_folder_that_is_not_a_bench_run_is_named(tmp_path: Path) -> None:
    run = subprocess.run(
        [sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True, text=True
    )
    assert run.returncode != 0
    assert f"{tmp_path} holds no episodes/ folder" in run.stderr
