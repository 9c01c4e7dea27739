"""scripts/plot_speed_frontier.py on run folders whose summary.json holds the bench's own group
figures (bench.summary.group_stats): the picture, and bad arguments refused."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from foldbot.bench.summary import group_stats

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "plot_speed_frontier.py"


def _run(folder: Path, speed: float) -> dict:
    """A run folder with one half-fold group: three episodes, one success, at `speed` × real
    time (mean fold error 13 mm, median 5); the group as summary.json holds it."""
    records = [
        {"id": f"towel-half-vision-closed-s000{i}",
         "result": {"success": ok, "fold_error_mm": err, "normalized_performance": 0.9,
                    "sim_seconds": speed * 10.0, "wall_seconds": 10.0, "actions": []}}
        for i, (ok, err) in enumerate([(True, 4.0), (False, 30.0), (False, 5.0)])
    ]  # fmt: skip
    group = {"recipe": "half", **group_stats(records)}
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"groups": [group]}))
    return json.loads((folder / "summary.json").read_text())["groups"][0]


def _points(stdout: str) -> list[tuple[str, str, float, float, float]]:
    """The script's "point:" lines as (label, recipe, speed, success rate, fold error mm)."""
    found = re.findall(
        r"^point: (.+) (\w+): speed (\S+), success (\S+), fold error (\S+) mm$", stdout, re.M
    )
    return [(lab, rec, float(v), float(r), float(e)) for lab, rec, v, r, e in found]


def test_plot_speed_frontier_writes_the_picture(tmp_path: Path) -> None:
    """The PNG, with one point per run's group at the summary's simulation speed, success rate
    and mean fold error (the script's "point:" lines), each under its run's label."""
    slow, fast = _run(tmp_path / "slow", 0.5), _run(tmp_path / "fast", 1.2)
    out = tmp_path / "frontier.png"
    args = [f"{tmp_path / 'slow'}=17 vertices", str(tmp_path / "fast"), "--out", str(out)]
    run = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # One point per group, at the summary's speed, success rate and mean fold error.
    assert slow["sim_speed"] == pytest.approx(0.5) and fast["sim_speed"] == pytest.approx(1.2)
    assert slow["success_rate"] == fast["success_rate"] == pytest.approx(1 / 3)
    assert slow["fold_error_mm"]["mean"] == pytest.approx(13.0)
    expected = [
        (label, "half", g["sim_speed"], g["success_rate"], g["fold_error_mm"]["mean"])
        for label, g in (("17 vertices", slow), (str(tmp_path / "fast"), fast))
    ]
    points = _points(run.stdout)
    assert [p[:2] for p in points] == [e[:2] for e in expected]
    assert [x for p in points for x in p[2:]] == pytest.approx(
        [x for e in expected for x in e[2:]], rel=1e-5
    )
    assert "not plotted" not in run.stderr


def test_plot_speed_frontier_names_what_it_cannot_plot_and_refuses_an_empty_picture(
    tmp_path: Path,
) -> None:
    """A group without `sim_speed` (a summary whose key was renamed) is named, not plotted;
    with no point left, nothing is written and the script fails."""
    _run(tmp_path / "fast", 1.2)
    renamed = tmp_path / "renamed"
    _run(renamed, 0.5)
    summary = json.loads((renamed / "summary.json").read_text())
    summary["groups"][0]["simulation_speed"] = summary["groups"][0].pop("sim_speed")
    (renamed / "summary.json").write_text(json.dumps(summary))
    out = tmp_path / "frontier.png"
    run = subprocess.run(
        [sys.executable, str(SCRIPT), str(renamed), str(tmp_path / "fast"), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert f"{renamed}: group 'half' has no sim_speed; not plotted" in run.stderr
    assert [p[0] for p in _points(run.stdout)] == [str(tmp_path / "fast")]
    out.unlink()
    run = subprocess.run(
        [sys.executable, str(SCRIPT), str(renamed), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 1 and "nothing to plot, nothing written" in run.stderr
    assert _points(run.stdout) == [] and not out.exists()


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
