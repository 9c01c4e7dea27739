import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.garments.towel import TowelSpec, make_towel


def test_square_towel_grid_and_corners():
    mesh = make_towel(TowelSpec(0.3, 0.3, 16))
    assert mesh.vertices.shape == (256, 3)
    assert mesh.faces.shape == (2 * 15 * 15, 3)
    assert mesh.area == pytest.approx(0.09, rel=1e-9)
    corners = {k: mesh.vertices[i, :2] for k, i in mesh.keypoints.items()}
    assert np.allclose(corners["corner_00"], [-0.15, -0.15])
    assert np.allclose(corners["corner_11"], [0.15, 0.15])
    assert np.allclose(corners["corner_10"], [0.15, -0.15])
    assert np.allclose(corners["corner_01"], [-0.15, 0.15])


def test_rectangular_towel_keeps_spacing_square():
    spec = TowelSpec(0.4, 0.2, 21)
    rows, cols = spec.grid_shape
    assert cols == 21 and rows == 11
    mesh = make_towel(spec)
    assert mesh.edge_length == pytest.approx(0.02 * (2 + np.sqrt(2)) / 3, rel=0.05)


@pytest.mark.parametrize(
    ("width", "height", "resolution", "shape"),
    [
        (0.30, 0.30, 16, (17, 17)),  # 15 edges → the nearest even count, 16, ties up
        (0.30, 0.30, 15, (15, 15)),
        (0.45, 0.25, 17, (9, 17)),  # 8.9 edges → 8
        (0.40, 0.20, 21, (11, 21)),
        (0.30, 0.05, 8, (5, 9)),  # never fewer than 5
    ],
)
def test_odd_grid_puts_vertex_rows_on_both_midlines(width, height, resolution, shape):
    spec = TowelSpec(width, height, resolution, odd_grid=True)
    assert spec.grid_shape == shape
    v = make_towel(spec).vertices
    # A half fold's line is a row of vertices in either direction, the fold line of a mass-spring
    # mesh's crease; without odd_grid an even count puts it between two rows.
    assert np.sum(np.isclose(v[:, 0], 0.0, atol=1e-12)) == shape[0]
    assert np.sum(np.isclose(v[:, 1], 0.0, atol=1e-12)) == shape[1]
    even = make_towel(TowelSpec(0.30, 0.30, 16)).vertices
    assert not np.any(np.isclose(even[:, 0], 0.0, atol=1e-6))


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"width": 0.0}, "width"),
        ({"height": -0.3}, "height"),
        ({"width": float("nan")}, "width"),
        ({"resolution": 2}, "resolution"),
        ({"resolution": 400}, "resolution"),
        ({"resolution": 10.5}, "resolution"),
        ({"odd_grid": "yes"}, "odd_grid"),
        ({"max_vertices": 24}, "max_vertices must be an integer in \\[25, 1600\\], got 24"),
        ({"max_vertices": 143.0}, "max_vertices"),
        ({"max_vertices": True}, "max_vertices"),
    ],
)
def test_bad_towel_specs_name_the_value(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        TowelSpec(**kwargs)


@pytest.mark.parametrize(
    ("width", "height", "max_vertices", "shape"),
    [
        (0.30, 0.30, None, (13, 13)),  # no bound: 13 along the longer side
        (0.30, 0.30, 143, (11, 11)),  # a square towel: fewer along its sides
        (0.45, 0.35, 143, (11, 13)),  # already within the bound: unchanged
        (0.45, 0.25, 143, (7, 13)),
        (0.30, 0.30, 25, (5, 5)),  # the coarsest odd grid
    ],
)
def test_max_vertices_bounds_the_grid(width, height, max_vertices, shape):
    spec = TowelSpec(width, height, resolution=13, odd_grid=True, max_vertices=max_vertices)
    assert spec.grid_shape == shape
    mesh = make_towel(spec)
    assert len(mesh.vertices) == shape[0] * shape[1]
    if max_vertices is None:
        return
    assert len(mesh.vertices) <= max_vertices
    # Where the bound coarsened the grid, it is the finest within it: the next resolution up
    # (a finer grid) would exceed it.
    unbounded = TowelSpec(width, height, resolution=13, odd_grid=True).grid_shape
    if shape != unbounded:
        for resolution in range(max(shape) + 1, 14):
            finer = TowelSpec(width, height, resolution=resolution, odd_grid=True).grid_shape
            assert finer == shape or np.prod(finer) > max_vertices
