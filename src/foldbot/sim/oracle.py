"""GROUND TRUTH from the simulator — for metrics, tests and comparison with perception only.

Nothing that would run on a real robot (planning, control, the closed loop) may read these values:
they are the simulator's internal cloth state and segmentation buffer. The `OracleEstimator`
returns the same `ClothState` a vision estimator does, computed from this ground truth, so the
two can be compared field by field (and planning can be tested without perception errors).
Corner labels use the same pure rule as vision (`foldbot.perception.keypoints.label_corners`).
"""

from __future__ import annotations

import cv2
import numpy as np

from foldbot import metrics
from foldbot.errors import ConfigError
from foldbot.perception.keypoints import CORNER_LABELS, label_corners, max_area_quad
from foldbot.perception.state import ClothState
from foldbot.sim.camera import RGBDCamera
from foldbot.sim.cloth import SoftCloth
from foldbot.types import Observation

CORNER_SOURCES = ("mesh", "outline")
"""OracleEstimator corner sources: the mesh's corner vertices, or the top-view outline's corners."""


class GroundTruthOracle:
    """Read-only access to the simulated cloth's true state (and, with a camera, its true mask)."""

    def __init__(self, cloth: SoftCloth, camera: RGBDCamera | None = None) -> None:
        self.cloth = cloth
        self.camera = camera

    def cloth_vertices(self) -> np.ndarray:
        """GROUND TRUTH current vertex positions (V×3, world, m) in mesh order."""
        return self.cloth.sim_vertices()

    def cloth_faces(self) -> np.ndarray:
        """Triangles (F×3 vertex indices) of the cloth mesh."""
        return self.cloth.mesh.faces.copy()

    def cloth_mask(self) -> np.ndarray:
        """GROUND TRUTH H×W bool mask of the cloth's visible pixels (segmentation buffer)."""
        if self.camera is None:
            raise ConfigError("cloth_mask needs the oracle to be built with a camera")
        return self.camera.render_segmentation() == self.cloth.body_id

    def corner_positions(self) -> dict[str, np.ndarray]:
        """GROUND TRUTH current world xyz (m) of the mesh's corner keypoints, by mesh name."""
        v = self.cloth_vertices()
        return {
            name: v[i].copy()
            for name, i in self.cloth.mesh.keypoints.items()
            if name.startswith("corner")
        }

    def keypoint_positions(self, names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
        """GROUND TRUTH current world xyz (m) of the mesh's named keypoints (a garment's neck,
        sleeves, …), all of them or those in `names` (ConfigError for a name the mesh lacks)."""
        kp = self.cloth.mesh.keypoints
        names = tuple(kp) if names is None else names
        missing = [n for n in names if n not in kp]
        if missing:
            raise ConfigError(f"the cloth mesh has no keypoints {missing}; it has {sorted(kp)}")
        v = self.cloth_vertices()
        return {name: v[kp[name]].copy() for name in names}

    def labelled_corners(self) -> dict[str, np.ndarray]:
        """GROUND TRUTH mesh corners named by the shared labelling rule (near_left, …)."""
        corners = self.corner_positions()
        if len(corners) != 4:
            raise ConfigError(f"labelled corners need a 4-corner garment, got {len(corners)}")
        pts = np.array(list(corners.values()))
        return {label: pts[i] for label, i in label_corners(pts).items()}

    def outline_corners(self) -> dict[str, np.ndarray]:
        """GROUND TRUTH corners of the cloth's top-view outline, labelled by the shared rule.

        The outline is the convex hull of the vertices in the table plane, reduced to its
        maximum-area quadrilateral (the same reduction vision uses); each corner is a vertex, at
        the height of the highest vertex within 1 cm of it (the top layer of a folded cloth). For
        a flat towel these are its mesh corners; for a folded one, what a camera can see.
        """
        v = self.cloth_vertices()
        hull_idx = cv2.convexHull(v[:, :2].astype(np.float32), returnPoints=False).reshape(-1)
        quad_idx = hull_idx[max_area_quad(v[hull_idx, :2])]
        pts = v[quad_idx].copy()
        for k, i in enumerate(quad_idx):
            near = np.linalg.norm(v[:, :2] - v[i, :2], axis=1) < 0.01
            pts[k, 2] = v[near, 2].max()
        return {label: pts[i] for label, i in label_corners(pts).items()}

    def coverage_m2(self) -> float:
        """GROUND TRUTH top-view area (m²) of the union of the cloth's triangles (2 mm raster)."""
        return metrics.coverage(self.cloth_vertices(), self.cloth.mesh.faces, flat_area=1.0)


class OracleEstimator:
    """A ClothState from GROUND TRUTH (named as such): the reference vision is compared with."""

    def __init__(self, oracle: GroundTruthOracle, corners: str = "mesh") -> None:
        if corners not in CORNER_SOURCES:
            raise ConfigError(f"corners must be one of {CORNER_SOURCES}, got {corners!r}")
        self.oracle = oracle
        self.corners = corners

    def estimate(self, obs: Observation | None = None) -> ClothState:
        """The cloth's true state; `obs` only supplies the stamp (the mask needs a camera)."""
        o = self.oracle
        v = o.cloth_vertices()
        table_z = float(o.cloth.table_height)
        kp = o.labelled_corners() if self.corners == "mesh" else o.outline_corners()
        keypoints = {name: (kp[name], 1.0) for name in CORNER_LABELS}
        hull_idx = cv2.convexHull(v[:, :2].astype(np.float32), returnPoints=False).reshape(-1)
        p5, p95 = np.percentile(v[:, 2] - table_z, [5.0, 95.0])
        mask = o.cloth_mask() if o.camera is not None else np.zeros((0, 0), bool)
        return ClothState(
            detected=True,
            reason="ground truth",
            keypoints=keypoints,
            mask=mask,
            coverage_m2=o.coverage_m2(),
            flatness=float(p95 - p5),
            outline_world=v[hull_idx].copy(),
            table_plane=np.array([0.0, 0.0, 1.0, -table_z]),
            stamp=float(obs.stamp) if obs is not None else 0.0,
        )
