"""scripts/trace_layers.py's measures on a hand-made quarter fold: each stage's flap, the staying
cloth's drift from where it lay flat, and each flap's error when its stage ended and at the end."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
from test_metrics import grid

from foldbot.metrics import fold_goal

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "trace_layers.py"
spec = importlib.util.spec_from_file_location("trace_layers", SCRIPT)
trace_layers = importlib.util.module_from_spec(spec)
sys.modules["trace_layers"] = trace_layers
spec.loader.exec_module(trace_layers)

# x < 0.01 moves onto x > 0.01, then y < 0.01 onto y > 0.01 (lines between the 5 × 5 grid's rows)
QUARTER = [[0.01, 0.0, 0.0, 1.0], [0.0, 0.01, -1.0, 0.0]]


def test_the_flaps_and_the_staying_cloth_of_a_quarter_fold():
    verts, _ = grid(5, 0.3)
    masks = trace_layers.flap_masks(verts, QUARTER, 0.01)
    assert [int(m.sum()) for m in masks] == [15, 15]  # 3 columns, then 3 of the 5 rows laid over
    staying = fold_goal(verts, QUARTER, 0.01)[1] == 0
    assert int(staying.sum()) == 4  # the 2 × 2 quarter no fold moves
    assert not (staying & (masks[0] | masks[1])).any()
    assert set(np.flatnonzero(staying)) == set(np.flatnonzero(~(masks[0] | masks[1])))


def test_the_staying_drift_is_the_mean_plane_distance_of_the_staying_cloth_from_its_start():
    verts, _ = grid(5, 0.3)
    staying = fold_goal(verts, QUARTER, 0.01)[1] == 0
    moved = verts.copy()
    moved[staying] += [0.03, 0.04, 0.02]  # 50 mm across the table, lifted 20 mm: height not counted
    moved[~staying] += [1.0, 0.0, 0.0]  # the flaps: not the staying cloth
    assert trace_layers.staying_drift_mm(moved, verts, staying) == pytest.approx(50.0)
    assert trace_layers.staying_drift_mm(verts, verts, staying) == 0.0
    assert trace_layers.staying_drift_mm(moved, verts, np.zeros(len(verts), bool)) == 0.0


def test_stage_ends_give_each_flap_when_its_stage_ended_and_at_the_end():
    row = {
        "actions": [
            {"stage": 0, "flap_error_mm": [30.0]},
            {"stage": 0, "flap_error_mm": [12.0]},
            {"stage": 1, "flap_error_mm": [20.0, 50.0]},
            {"stage": 1, "flap_error_mm": [25.0, 40.0]},
        ]
    }
    assert trace_layers.stage_ends(row) == [[12.0, 25.0], [40.0, 40.0]]
    assert trace_layers.stage_ends({**row, "error": "diverged"}) == []
