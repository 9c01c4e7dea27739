"""The ground-truth oracle and the OracleEstimator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.perception.keypoints import CORNER_LABELS, label_corners
from foldbot.perception.state import ClothState
from foldbot.sim.camera import CameraConfig, RGBDCamera
from foldbot.sim.cloth import ClothConfig, SoftCloth, settle
from foldbot.sim.oracle import GroundTruthOracle, OracleEstimator
from foldbot.sim.perception_scenes import folded_towel
from foldbot.sim.world import SimWorld


@pytest.fixture(scope="module")
def flat():
    """A 0.3 × 0.2 m towel (10 vertices per side), turned 30°, lying as spawned."""
    world = SimWorld()
    cloth = SoftCloth(
        world.client,
        make_towel(TowelSpec(0.3, 0.2, 10)),
        ClothConfig(),
        world.layout.table_height,
        (0.45, 0.05),
        math.radians(30),
    )
    world.step(1)  # a soft body is drawn only once the world has stepped
    camera = RGBDCamera(world.client, CameraConfig(width=160, height=120))
    yield world, cloth, camera
    world.close()


def test_vertices_faces_and_corners(flat) -> None:
    _, cloth, _ = flat
    oracle = GroundTruthOracle(cloth)
    v = oracle.cloth_vertices()
    assert v.shape == (len(cloth.mesh.vertices), 3)
    np.testing.assert_array_equal(oracle.cloth_faces(), cloth.mesh.faces)
    corners = oracle.corner_positions()
    assert set(corners) == {"corner_00", "corner_10", "corner_11", "corner_01"}
    np.testing.assert_allclose(corners["corner_00"], v[cloth.mesh.keypoints["corner_00"]])
    labelled = oracle.labelled_corners()
    assert tuple(labelled) == CORNER_LABELS
    pts = np.array(list(corners.values()))
    for name, i in label_corners(pts).items():
        np.testing.assert_allclose(labelled[name], pts[i])
    # near = smaller x, left = +y (seen from the robot)
    assert labelled["near_left"][0] < labelled["far_left"][0]
    assert labelled["near_left"][1] > labelled["near_right"][1]


def test_outline_corners_equal_mesh_corners_when_flat(flat) -> None:
    _, cloth, _ = flat
    oracle = GroundTruthOracle(cloth)
    mesh_c, outline_c = oracle.labelled_corners(), oracle.outline_corners()
    for name in CORNER_LABELS:
        np.testing.assert_allclose(outline_c[name], mesh_c[name], atol=1e-9)
    assert oracle.coverage_m2() == pytest.approx(0.3 * 0.2, rel=0.03)


def test_mask_needs_a_camera(flat) -> None:
    _, cloth, camera = flat
    with pytest.raises(ConfigError, match="camera"):
        GroundTruthOracle(cloth).cloth_mask()
    mask = GroundTruthOracle(cloth, camera).cloth_mask()
    assert mask.shape == (120, 160) and mask.dtype == bool and 300 < mask.sum() < 0.5 * mask.size


def test_oracle_estimator(flat) -> None:
    _, cloth, camera = flat
    state = OracleEstimator(GroundTruthOracle(cloth, camera)).estimate()
    assert isinstance(state, ClothState) and state.detected
    assert all(conf == 1.0 for _, conf in state.keypoints.values())
    assert state.mask.shape == (120, 160)
    assert state.coverage_m2 == pytest.approx(0.06, rel=0.03)
    assert state.flatness < 0.003
    np.testing.assert_allclose(state.table_plane, [0, 0, 1, -0.75])
    with pytest.raises(ConfigError, match="corners"):
        OracleEstimator(GroundTruthOracle(cloth), corners="guess")


def test_outline_corners_of_a_folded_towel() -> None:
    """Folded in half across x: the outline is 0.15 × 0.2 m; two corners are fold-line ends."""
    spec = TowelSpec(0.3, 0.2, 10)
    with SimWorld() as world:
        cloth = SoftCloth(
            world.client, folded_towel(spec, "x"), ClothConfig(), 0.75, (0.45, 0.0), 0.0
        )
        settle(world, cloth, max_time=0.5)
        oracle = GroundTruthOracle(cloth)
        outline = oracle.outline_corners()
        mesh = oracle.corner_positions()
        state = OracleEstimator(oracle, corners="outline").estimate()
    pts = np.array([outline[n] for n in CORNER_LABELS])
    assert np.ptp(pts[:, 0]) == pytest.approx(0.15, abs=0.02)
    assert np.ptp(pts[:, 1]) == pytest.approx(0.2, abs=0.02)
    # The two free corners of each stacked pair sit on top of each other.
    stacked = [np.linalg.norm(mesh[a][:2] - mesh[b][:2]) for a, b in
               (("corner_00", "corner_10"), ("corner_01", "corner_11"))]  # fmt: skip
    assert max(stacked) < 0.02
    assert state.coverage_m2 == pytest.approx(0.03, rel=0.15)
