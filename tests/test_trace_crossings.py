"""scripts/trace_crossings.py's bookkeeping on a hand-made fold pushed through itself: the
crossings' goal layers, whether they touch a held point's neighbourhood, when they first rose,
and the summary of where they first appeared."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
from test_metrics import HALF, grid

from foldbot.metrics import fold_goal, self_crossing_pairs

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "trace_crossings.py"
spec = importlib.util.spec_from_file_location("trace_crossings", SCRIPT)
trace_crossings = importlib.util.module_from_spec(spec)
sys.modules["trace_crossings"] = trace_crossings
spec.loader.exec_module(trace_crossings)


def pushed_through() -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """A sheet folded in half with one vertex of the top layer pushed through the layer beneath:
    its vertices, faces, goal layers and the pushed vertex."""
    verts, faces = grid()
    half, layers = fold_goal(verts, [HALF], 0.002)
    top = np.flatnonzero(layers == 1)
    k = int(top[np.argmin(np.linalg.norm(half[top, :2] - [0.075, 0.0], axis=1))])
    through = half.copy()
    through[k, 2] = -0.01
    return through, faces, layers, k


def test_crossings_are_counted_by_the_goal_layers_they_join():
    verts, faces, layers, _k = pushed_through()
    pairs = self_crossing_pairs(verts, faces)
    counted = trace_crossings.layer_pairs(pairs, faces, layers)
    assert sum(counted.values()) == len(pairs) > 0
    assert set(counted) <= {"1/0", "0/1"}  # the flap through the cloth beneath, and back
    assert trace_crossings.layer_pairs(pairs[:0], faces, layers) == {}


def test_a_crossing_touches_the_grip_only_near_a_held_point():
    verts, faces, _layers, k = pushed_through()
    pairs = self_crossing_pairs(verts, faces)
    ring = trace_crossings.neighbourhood({k}, faces)
    assert k in ring and len(ring) > 1  # k and the vertices sharing a triangle with it
    assert trace_crossings.neighbourhood(set(), faces) == set()
    assert trace_crossings.touches(pairs, faces, ring) == len(pairs)
    far = int(np.argmax(np.linalg.norm(verts[:, :2] - verts[k, :2], axis=1)))
    assert trace_crossings.touches(pairs, faces, trace_crossings.neighbourhood({far}, faces)) == 0


def test_the_first_rise_is_the_first_sample_with_more_crossings_than_before():
    samples = [{"crossings": n, "t": t} for t, n in enumerate([0, 0, 3, 2, 5])]
    assert trace_crossings.first_rise(samples)["t"] == 2
    assert trace_crossings.first_rise([{"crossings": 0, "t": 0}]) is None
    assert trace_crossings.first_rise([]) is None


def test_the_summary_says_where_the_crossings_first_appeared():
    def row(segment: str | None, held: list[int], grip: int, end: int = 1) -> dict:
        first = None if segment is None else {"segment": segment, "held": held, "at_the_grip": grip}
        return {"actions": [{"action": "a"}], "first": first, "end": {"crossings": end}}

    rows = [row("carry", [4, 9], 3), row("carry", [4], 0, end=0), row("park", [], 2)]
    rows += [row(None, [], 0, end=0), {"error": "diverged"}]  # the last not traced: left out
    lines = trace_crossings.summary(rows)
    assert (
        lines[0] == "# 3 of 4 traced episodes passed through themselves at some moment, 2 ended so"
    )
    assert lines[1] == "  first in 'carry': 2 (holding, at the grip: 1)"
    assert lines[2] == "  first in 'park': 1 (holding, at the grip: 0)"
