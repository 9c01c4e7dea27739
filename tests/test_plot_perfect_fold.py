"""scripts/plot_perfect_fold.py on an episode folder written to disk: the picture and its figure."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_metrics import LEFT_IN, RIGHT_IN, grid

from foldbot.metrics import perfect_fold_error_mm

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "plot_perfect_fold.py"


def _episode(folder: Path) -> float:
    verts, faces = grid()
    folder.mkdir()
    np.savez(folder / "cloth.npz", faces=faces, initial=verts, final=verts, thickness=0.002)
    result = {"garment": "towel", "recipe": "sides", "seed": 0, "fold_error_mm": 12.0}
    (folder / "result.json").write_text(json.dumps({**result, "fold_lines": [LEFT_IN, RIGHT_IN]}))
    return perfect_fold_error_mm(verts, faces, [LEFT_IN, RIGHT_IN], 0.002)


def test_plot_perfect_fold_writes_the_picture(tmp_path: Path) -> None:
    perfect = _episode(tmp_path / "ep")
    out = tmp_path / "pics" / "perfect.png"
    run = subprocess.run(
        [sys.executable, str(SCRIPT), str(tmp_path / "ep"), "--out", str(out)],
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"perfect fold {perfect:.1f} mm, episode 12.0 mm" in run.stdout


@pytest.mark.parametrize(
    ("folder", "out", "match"),
    [("nothing", "x.png", "not an episode"), ("ep", "x.jpg", "must name a .png")],
)
def test_plot_perfect_fold_refuses_bad_arguments(
    tmp_path: Path, folder: str, out: str, match: str
) -> None:
    _episode(tmp_path / "ep")
    run = subprocess.run(
        [sys.executable, str(SCRIPT), str(tmp_path / folder), "--out", str(tmp_path / out)],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 2 and match in run.stderr
    assert not (tmp_path / out).exists()
