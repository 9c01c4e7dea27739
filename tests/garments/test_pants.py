"""Pants: outline and mesh, keypoints where pants have them, validation, sampling."""

import math

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.garments.outline import MIN_ANGLE_DEG, mesh_boundary_loops, triangle_angles
from foldbot.garments.pants import PANTS_KEYPOINTS, PantsSpec, make_pants, pants_outline


def _kp(mesh) -> dict[str, np.ndarray]:
    return {name: mesh.vertices[i, :2] for name, i in mesh.keypoints.items()}


def test_default_pants_mesh_and_keypoints() -> None:
    spec = PantsSpec()
    mesh = make_pants(spec)
    assert 150 <= len(mesh.vertices) <= 300
    assert tuple(sorted(mesh.keypoints)) == tuple(sorted(PANTS_KEYPOINTS))
    assert math.degrees(triangle_angles(mesh.vertices, mesh.faces).min()) >= MIN_ANGLE_DEG
    (loop,) = mesh_boundary_loops(mesh.faces)
    assert set(mesh.keypoints.values()) <= set(loop)
    assert mesh.area == pytest.approx(pants_outline(spec).area, rel=1e-9)

    kp = _kp(mesh)
    for name in ("waist", "leg_outer", "leg_inner"):
        left, right = kp[f"left_{name}"], kp[f"right_{name}"]
        assert left[0] < 0 < right[0]
        np.testing.assert_allclose(left * [-1, 1], right, atol=1e-12)
    top, bottom = mesh.vertices[:, 1].max(), mesh.vertices[:, 1].min()
    assert kp["right_waist"] == pytest.approx([spec.waist_width / 2, top])
    assert kp["crotch"] == pytest.approx([0.0, top - spec.rise])
    assert kp["right_leg_inner"] == pytest.approx([spec.hem_gap / 2, bottom])
    assert kp["right_leg_outer"] == pytest.approx([spec.hem_gap / 2 + spec.leg_opening, bottom])
    assert top - bottom == pytest.approx(spec.length)
    # No cloth between the legs below the crotch.
    centroids = mesh.vertices[mesh.faces].mean(axis=1)
    between = (np.abs(centroids[:, 0]) < spec.hem_gap / 2 - 0.002) & (
        centroids[:, 1] < bottom + 0.02
    )
    assert not between.any()


def test_sampled_pants_are_childrens_sizes_and_valid_meshes() -> None:
    rng = np.random.default_rng(1)
    specs = [PantsSpec.sample(rng) for _ in range(300)]
    assert max(s.length for s in specs) <= 0.45
    assert max(max(s.hip_width, s.hem_gap + 2 * s.leg_opening) for s in specs) <= 0.35
    for spec in specs[:25]:
        mesh = make_pants(spec)
        assert 150 <= len(mesh.vertices) <= 300
        assert np.ptp(mesh.vertices[:, :2], axis=0).max() <= 0.5


def test_sampling_is_deterministic() -> None:
    a = PantsSpec.sample(np.random.default_rng(3))
    assert a == PantsSpec.sample(np.random.default_rng(3))
    assert a != PantsSpec.sample(np.random.default_rng(4))
    assert a.hip_width >= a.waist_width


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"waist_width": 0.0}, r"waist_width must be in \[0.12, 0.6\] m, got 0.0"),
        ({"length": float("inf")}, "length"),
        ({"hip_width": 0.2}, "hip_width must be ≥ waist_width"),
        ({"rise": 0.35}, "rise"),
        ({"leg_opening": 0.25}, "leg_opening"),
        ({"hem_gap": 0.22}, "hem_gap"),
        ({"edge_length": 0.2}, "edge_length"),
    ],
)
def test_bad_specs_name_the_value(kwargs, needle) -> None:
    with pytest.raises(ConfigError, match=needle):
        PantsSpec(**kwargs)
