"""scripts/measure_two_grippers.py's pin: which cloth a still second hand holds by a fold line."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
from test_metrics import grid

from foldbot.metrics import FoldLine

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "measure_two_grippers.py"
spec = importlib.util.spec_from_file_location("measure_two_grippers", SCRIPT)
measure_two_grippers = importlib.util.module_from_spec(spec)
sys.modules["measure_two_grippers"] = measure_two_grippers
spec.loader.exec_module(measure_two_grippers)

LINE = FoldLine(0.0, 0.0, 0.0, 1.0)  # along y through the origin: x < 0 moves, x > 0 stays


def test_the_pin_holds_the_staying_cloth_its_offset_inside_the_line_halfway_along_it():
    verts, _ = grid(11, 0.3)  # 3 cm apart
    pinned = measure_two_grippers.pin_vertices(verts, LINE, 0.06, 0.012)
    assert np.allclose(verts[pinned], [[0.06, 0.0, 0.0]])


def test_a_strip_pin_holds_every_layer_along_the_line():
    verts, _ = grid(11, 0.3)
    stack = np.vstack([verts, verts + [0.0, 0.0, 0.01]])  # a second layer right above
    pinned = measure_two_grippers.pin_vertices(stack, LINE, 0.06, 0.012, length=0.07)
    held = stack[pinned]
    assert len(pinned) == 6  # y = -0.03, 0, 0.03 on both layers
    assert np.allclose(held[:, 0], 0.06) and set(np.round(held[:, 1], 3)) == {-0.03, 0.0, 0.03}
    assert set(np.round(held[:, 2], 3)) == {0.0, 0.01}


def test_the_pin_never_holds_the_moving_side():
    verts, _ = grid(11, 0.3)
    pinned = measure_two_grippers.pin_vertices(verts, LINE, 0.0, 0.05)  # reaches over the line
    assert (verts[pinned, 0] > 0).all()
