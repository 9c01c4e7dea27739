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
    ("kwargs", "needle"),
    [
        ({"width": 0.0}, "width"),
        ({"height": -0.3}, "height"),
        ({"width": float("nan")}, "width"),
        ({"resolution": 2}, "resolution"),
        ({"resolution": 400}, "resolution"),
        ({"resolution": 10.5}, "resolution"),
    ],
)
def test_bad_towel_specs_name_the_value(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        TowelSpec(**kwargs)
