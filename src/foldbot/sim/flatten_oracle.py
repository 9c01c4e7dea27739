"""Flattening pulls from GROUND TRUTH (named as such), the reference the vision policy is compared
with: corner pulling as in Seita et al.'s oracle. The flat towel is laid where it best matches the
cloth now (rigid, in the table plane), and the mesh corner farthest from its place there is
pulled onto it. It answers one question: how far would 6 pulls get with perfect knowledge of
where every corner is and where it belongs?"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from foldbot.errors import ConfigError
from foldbot.garments.mesh import ClothMesh
from foldbot.perception.state import ClothState
from foldbot.planning.flatten import FlattenConfig, Pull, pull_action, table_z
from foldbot.sim.oracle import GroundTruthOracle


def lay_flat(rest_xy: np.ndarray, now_xy: np.ndarray, cfg: FlattenConfig) -> np.ndarray:
    """The flat mesh (rest positions, N×2) moved rigidly onto the cloth now (N×2, least squares
    over every vertex: Kabsch), then shifted the least that keeps it `cfg.margin` inside the
    workspace (where it fits)."""
    rc, pc = rest_xy.mean(axis=0), now_xy.mean(axis=0)
    u, _s, vt = np.linalg.svd((rest_xy - rc).T @ (now_xy - pc))
    flip = np.diag([1.0, float(np.sign(np.linalg.det(vt.T @ u.T)))])
    laid = (rest_xy - rc) @ (vt.T @ flip @ u.T).T + pc
    x0, x1, y0, y1 = cfg.workspace
    m = cfg.margin
    lo = np.array([x0 + m, y0 + m]) - laid.min(axis=0)
    hi = np.array([x1 - m, y1 - m]) - laid.max(axis=0)
    return laid + np.clip(np.zeros(2), lo, np.maximum(lo, hi))


class CornerPullOracle:
    """Plans each flattening pull from the cloth's true vertices: the corners farthest from their
    place in the laid-flat towel first, each grasped where it is and placed just beyond its place."""

    def __init__(
        self,
        vertices_now: Callable[[], np.ndarray],
        rest_vertices: np.ndarray,
        corners: dict[str, int],
    ) -> None:
        rest = np.asarray(rest_vertices, dtype=float)
        if rest.ndim != 2 or rest.shape[1] < 2 or len(rest) < 3:
            raise ConfigError(f"rest vertices must be N×2 or N×3 with N ≥ 3, got {rest.shape}")
        bad = {n: i for n, i in corners.items() if not 0 <= int(i) < len(rest)}
        if not corners or bad:
            raise ConfigError(
                f"corners must name vertices 0..{len(rest) - 1}, got {corners!r}"
                + (f" (out of range: {bad})" if bad else "")
            )
        self.vertices_now = vertices_now
        self.rest_xy = rest[:, :2]
        self.corners = dict(corners)

    @classmethod
    def of(cls, oracle: GroundTruthOracle, mesh: ClothMesh) -> CornerPullOracle:
        """The oracle for the cloth `oracle` reads, whose flat mesh is `mesh`."""
        return cls(oracle.cloth_vertices, mesh.vertices, mesh.keypoints)

    def __call__(self, state: ClothState, cfg: FlattenConfig) -> tuple[np.ndarray, list[Pull]]:
        """The laid-flat towel's outline (its corners, 4×3 world points on the table) and every
        corner pull worth making (`cfg.min_pull` or farther from its place), farthest first."""
        now = np.asarray(self.vertices_now(), dtype=float)
        if now.shape != (len(self.rest_xy), 3):
            raise ConfigError(
                f"the cloth has {now.shape} vertices, the flat mesh {len(self.rest_xy)}×3"
            )
        laid = lay_flat(self.rest_xy, now[:, :2], cfg)
        outline = np.array(
            [[*laid[i], table_z(state.table_plane, laid[i])] for i in self.corners.values()]
        )
        pulls = []
        for name, i in self.corners.items():
            offset = laid[i] - now[i, :2]
            distance = float(np.linalg.norm(offset))
            if distance < cfg.min_pull:
                continue
            floor = table_z(state.table_plane, now[i, :2]) + cfg.grasp_height
            grasp = np.array([now[i, 0], now[i, 1], max(floor, now[i, 2])])
            place = laid[i] + offset / distance * cfg.overshoot
            action = pull_action(grasp, place, state.table_plane, cfg, f"oracle pull {name}")
            pulls.append(Pull(action, name, distance))
        pulls.sort(key=lambda p: -p.shortfall)
        return outline, pulls
