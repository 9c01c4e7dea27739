"""scripts/trace_corners.py's measures on a hand-made half fold: which corners are carried, their
offsets from their goals along and across the carry, and when one fell back."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
from test_metrics import grid

from foldbot.metrics import fold_goal

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "trace_corners.py"
spec = importlib.util.spec_from_file_location("trace_corners", SCRIPT)
trace_corners = importlib.util.module_from_spec(spec)
sys.modules["trace_corners"] = trace_corners  # its dataclass looks its module up there
spec.loader.exec_module(trace_corners)

TABLE_Z = 0.75
HALF = [0.0, 0.0, 0.0, 1.0]  # x < 0 moves onto x > 0


def test_a_carried_corner_is_measured_along_its_carry_and_a_fall_back_is_named():
    verts, _ = grid(5, 0.3, TABLE_Z)
    goal = fold_goal(verts, [HALF], 0.0)[0]
    ids = [0, 4, 20, 24]  # the 5 × 5 grid's corner vertices
    carried = [k for k, v in enumerate(ids) if verts[v, 0] < 0]
    assert len(carried) == 2

    def at(offsets):  # corner positions: the carried ones at goal + offset, the others at rest
        pos = verts[ids].copy()
        for k, off in zip(carried, offsets, strict=True):
            pos[k] = goal[ids[k]] + off
        return pos

    samples = [
        trace_corners.Sample(0.0, "far_left", verts[ids].copy(), TABLE_Z + 0.3),
        trace_corners.Sample(1.0, "far_left", at([[0.0, 0.004, 0.02], [-0.3, 0.0, 0.0]]), 0.78),
        trace_corners.Sample(2.0, "far_right", at([[-0.2, 0.0, 0.0], [0.0, 0.0, 0.02]]), 0.85),
    ]
    rows = trace_corners.corner_rows(verts, goal, ids, samples, TABLE_Z)
    assert {r["vertex"] for r in rows} == {ids[k] for k in carried}  # staying corners left out
    first = [r for r in rows if r["vertex"] == ids[carried[0]]]
    assert [r["past_mm"] for r in first] == pytest.approx([-300.0, 0.0, -200.0])
    assert abs(first[1]["aside_mm"]) == pytest.approx(4.0) and first[1]["z_mm"] == 20.0
    assert first[2]["tcp_mm"] == pytest.approx(100.0)
    line = trace_corners.fell_back(rows, ids[carried[0]], near=0.01, back=0.05)
    assert "within 10 mm of its goal at t = 1.00 s (far_left)" in line
    assert "then 200 mm short of it at t = 2.00 s (far_right, TCP 100 mm up)" in line
    stayed = trace_corners.fell_back(rows, ids[carried[1]], near=0.01, back=0.05)
    assert stayed.endswith("at the end +0 mm past, +0 aside")
    never = trace_corners.fell_back(rows[:1], ids[carried[0]], near=0.01, back=0.05)
    assert "never within 10 mm of its goal (closest 300 mm at t = 0.00 s)" in never
