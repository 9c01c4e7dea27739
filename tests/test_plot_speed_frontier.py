"""scripts/plot_speed_frontier.py on run folders whose summary.json holds the bench's own group
figures (bench.summary.group_stats): the picture, and bad arguments refused."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from foldbot.bench.summary import group_stats

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "plot_speed_frontier.py"


def _run(folder: Path, speed: float) -> None:
    """A run folder with one half-fold group: two episodes, one success, at `speed` × real time."""
    records = [
        {"id": f"towel-half-vision-closed-s000{i}",
         "result": {"success": ok, "fold_error_mm": err, "normalized_performance": 0.9,
                    "sim_seconds": speed * 10.0, "wall_seconds": 10.0, "actions": []}}
        for i, (ok, err) in enumerate([(True, 4.0), (False, 30.0)])
    ]  # fmt: skip
    group = {"recipe": "half", **group_stats(records)}
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"groups": [group]}))


def test_plot_speed_frontier_writes_the_picture(tmp_path: Path) -> None:
    _run(tmp_path / "slow", 0.5)
    _run(tmp_path / "fast", 1.2)
    out = tmp_path / "frontier.png"
    args = [f"{tmp_path / 'slow'}=17 vertices", str(tmp_path / "fast"), "--out", str(out)]
    run = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("folder", "out", "match"),
    [("nothing", "x.png", "has no summary.json"), ("slow", "x.jpg", "must name a .png")],
)
def test_plot_speed_frontier_refuses_bad_arguments(
    tmp_path: Path, folder: str, out: str, match: str
) -> None:
    _run(tmp_path / "slow", 0.5)
    args = [str(tmp_path / folder), "--out", str(tmp_path / out)]
    run = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True)
    assert run.returncode != 0 and match in run.stderr
    assert not (tmp_path / out).exists()
