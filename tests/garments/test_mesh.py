"""A cloth mesh's measures and its OBJ file (what PyBullet's soft-body loader reads)."""

import numpy as np
import pytest

from foldbot.garments.mesh import ClothMesh

# A 0.2 × 0.1 m rectangle as two triangles.
SQUARE = ClothMesh(
    vertices=np.array([[0, 0, 0], [0.2, 0, 0], [0.2, 0.1, 0], [0, 0.1, 0]], dtype=float),
    faces=np.array([[0, 1, 2], [0, 2, 3]]),
    keypoints={"corner": 0},
)


def test_area_and_mean_edge_length():
    assert SQUARE.area == pytest.approx(0.02)
    diagonal = np.hypot(0.2, 0.1)
    # Each triangle's three edges, the diagonal counted twice.
    assert SQUARE.edge_length == pytest.approx((2 * 0.2 + 2 * 0.1 + 2 * diagonal) / 6)


def test_the_obj_file_holds_every_vertex_uv_and_face(tmp_path):
    path = SQUARE.write_obj(tmp_path / "cloth.obj")
    lines = path.read_text().splitlines()
    vs = [ln for ln in lines if ln.startswith("v ")]
    vts = [ln for ln in lines if ln.startswith("vt ")]
    fs = [ln for ln in lines if ln.startswith("f ")]
    assert len(vs) == len(vts) == 4 and len(fs) == 2
    assert vs[2] == "v 0.200000 0.100000 0.000000"
    assert vts[2] == "vt 1.000000 1.000000" and vts[0] == "vt 0.000000 0.000000"  # the bounds
    assert fs == ["f 1/1 2/2 3/3", "f 1/1 3/3 4/4"]  # 1-based, as OBJ counts
