"""T-shirts: outline and mesh, keypoints where a T-shirt has them, validation, sampling."""

import math

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.garments.outline import MIN_ANGLE_DEG, mesh_boundary_loops, triangle_angles
from foldbot.garments.tshirt import TSHIRT_KEYPOINTS, TShirtSpec, make_tshirt, tshirt_outline


def _kp(mesh) -> dict[str, np.ndarray]:
    return {name: mesh.vertices[i, :2] for name, i in mesh.keypoints.items()}


def test_default_tshirt_mesh_and_keypoints() -> None:
    spec = TShirtSpec()
    mesh = make_tshirt(spec)
    assert 150 <= len(mesh.vertices) <= 300
    assert tuple(sorted(mesh.keypoints)) == tuple(sorted(TSHIRT_KEYPOINTS))
    assert math.degrees(triangle_angles(mesh.vertices, mesh.faces).min()) >= MIN_ANGLE_DEG
    (loop,) = mesh_boundary_loops(mesh.faces)
    assert set(mesh.keypoints.values()) <= set(loop)  # every keypoint on the outline
    assert mesh.area == pytest.approx(tshirt_outline(spec).area, rel=0.01)

    kp = _kp(mesh)
    a = spec.body_width / 2
    # Mirror pairs: left is the −x side.
    for name in ("shoulder", "sleeve", "armpit", "hem"):
        left, right = kp[f"left_{name}"], kp[f"right_{name}"]
        assert left[0] < 0 < right[0]
        np.testing.assert_allclose(left * [-1, 1], right, atol=1e-12)
    assert kp["neck"][0] == pytest.approx(0.0, abs=1e-12)
    # Top (+y) to bottom: neck sides above the neck, shoulders, sleeves, armpits, hem.
    v = mesh.vertices[:, :2]
    assert kp["neck"][1] == pytest.approx(v[:, 1].max() - spec.neck_depth)
    assert kp["right_shoulder"][1] == pytest.approx(v[:, 1].max() - spec.shoulder_drop)
    assert kp["right_armpit"][1] == pytest.approx(kp["right_shoulder"][1] - spec.armhole_depth)
    assert kp["right_hem"][1] == pytest.approx(v[:, 1].min())
    for name in ("right_shoulder", "right_armpit", "right_hem"):
        assert kp[name][0] == pytest.approx(a)
    # The cuff middle is the outermost keypoint, half a cuff from the cuff's top corner.
    assert kp["right_sleeve"][0] > a + 0.02
    assert np.ptp(v[:, 0]) == pytest.approx(spec.span)


def test_sampled_tshirts_are_childrens_sizes_and_valid_meshes() -> None:
    rng = np.random.default_rng(1)
    specs = [TShirtSpec.sample(rng) for _ in range(300)]
    assert max(s.span for s in specs) <= 0.5
    assert max(s.body_length for s in specs) <= 0.42
    for spec in specs[:25]:
        mesh = make_tshirt(spec)  # raises on slivers, missing outline edges, pieces
        assert 150 <= len(mesh.vertices) <= 300
        assert np.ptp(mesh.vertices[:, :2], axis=0).max() <= 0.5


def test_sampling_is_deterministic() -> None:
    a = TShirtSpec.sample(np.random.default_rng(7))
    b = TShirtSpec.sample(np.random.default_rng(7))
    c = TShirtSpec.sample(np.random.default_rng(8))
    assert a == b and a != c
    np.testing.assert_array_equal(make_tshirt(a).vertices, make_tshirt(b).vertices)
    assert TShirtSpec.sample(np.random.default_rng(7), edge_length=0.04).edge_length == 0.04


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"body_width": 0.05}, "body_width must be in"),
        ({"body_length": float("nan")}, "body_length"),
        ({"sleeve_angle": 2.0}, r"sleeve_angle must be in \[0.0, 1.0\] rad, got 2.0"),
        ({"edge_length": 0.001}, "edge_length"),
        ({"neck_width": 0.25}, "neck_width"),
        ({"sleeve_length": 0.045, "sleeve_opening": 0.1}, "sleeve_length"),
        ({"armhole_depth": 0.06}, "armhole_depth"),
        ({"neck_depth": 0.14}, "neck_depth"),
        ({"body_width": "wide"}, "body_width"),
    ],
)
def test_bad_specs_name_the_value(kwargs, needle) -> None:
    with pytest.raises(ConfigError, match=needle):
        TShirtSpec(**kwargs)
