"""Camera geometry for perception: input checks, projection, back-projection, planes (SI units).

Everything works from an Observation's OpenCV intrinsics K and its `T_world_camera` (OpenCV camera
axes: x right, y down, z forward), never from a simulator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from foldbot.errors import PerceptionError
from foldbot.types import CameraIntrinsics, Observation


def check_intrinsics(intrinsics: CameraIntrinsics) -> np.ndarray:
    """Return K as a float 3×3 array; PerceptionError unless it is a valid pinhole matrix."""
    if not isinstance(intrinsics, CameraIntrinsics):
        raise PerceptionError(f"intrinsics must be a CameraIntrinsics, got {type(intrinsics)}")
    try:
        K = np.asarray(intrinsics.K, dtype=float)
    except (TypeError, ValueError):
        raise PerceptionError(
            f"intrinsics K must be a numeric 3×3 matrix, got {intrinsics.K!r}"
        ) from None
    if K.shape != (3, 3):
        raise PerceptionError(f"intrinsics K must be 3×3, got shape {K.shape}")
    if not np.all(np.isfinite(K)):
        raise PerceptionError("intrinsics K has non-finite entries")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise PerceptionError(
            f"intrinsics focal lengths must be > 0, got fx={K[0, 0]}, fy={K[1, 1]}"
        )
    if not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0.0:
        raise PerceptionError(
            f"intrinsics K must be [[fx,s,cx],[0,fy,cy],[0,0,1]], got {K.tolist()}"
        )
    w, h = intrinsics.width, intrinsics.height
    if not (
        isinstance(w, int | np.integer) and isinstance(h, int | np.integer) and w > 0 and h > 0
    ):
        raise PerceptionError(f"intrinsics width × height must be positive integers, got {w}×{h}")
    return K


def check_pose(T: np.ndarray, name: str = "T_world_camera") -> np.ndarray:
    """Return T as a float 4×4 array; PerceptionError unless it is a finite rigid transform."""
    try:
        T = np.asarray(T, dtype=float)
    except (TypeError, ValueError):
        raise PerceptionError(f"{name} must be a numeric 4×4 matrix") from None
    if T.shape != (4, 4):
        raise PerceptionError(f"{name} must be 4×4, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise PerceptionError(f"{name} has non-finite entries")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or not np.allclose(T[3], [0, 0, 0, 1]):
        raise PerceptionError(f"{name} must be a rigid transform (orthonormal rotation)")
    return T


def check_observation(obs: Observation) -> tuple[np.ndarray, np.ndarray]:
    """Validate an Observation for perception; return (K, T_world_camera) or raise PerceptionError.

    Requires RGB H×W×3 uint8, depth H×W float (metres; NaN or 0 = unknown) with some valid pixels,
    non-empty images whose size matches the intrinsics, a valid K and a rigid camera pose.
    """
    if not isinstance(obs, Observation):
        raise PerceptionError(f"expected an Observation, got {type(obs).__name__}")
    rgb, depth = obs.rgb, obs.depth
    if not isinstance(rgb, np.ndarray) or not isinstance(depth, np.ndarray):
        raise PerceptionError("rgb and depth must be numpy arrays")
    if rgb.size == 0 or depth.size == 0:
        raise PerceptionError(f"empty image: rgb shape {rgb.shape}, depth shape {depth.shape}")
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise PerceptionError(f"rgb must be H×W×3, got shape {rgb.shape}")
    if rgb.dtype != np.uint8:
        raise PerceptionError(f"rgb must be uint8, got dtype {rgb.dtype}")
    if depth.ndim != 2:
        raise PerceptionError(f"depth must be H×W, got shape {depth.shape}")
    if not np.issubdtype(depth.dtype, np.floating):
        raise PerceptionError(
            f"depth must be float metres (float32), got dtype {depth.dtype} "
            "(convert integer millimetre depth to metres first)"
        )
    if depth.shape != rgb.shape[:2]:
        raise PerceptionError(f"depth shape {depth.shape} differs from rgb shape {rgb.shape[:2]}")
    K = check_intrinsics(obs.intrinsics)
    if (obs.intrinsics.height, obs.intrinsics.width) != depth.shape:
        raise PerceptionError(
            f"intrinsics size {obs.intrinsics.width}×{obs.intrinsics.height} differs from the "
            f"image size {depth.shape[1]}×{depth.shape[0]}"
        )
    T = check_pose(obs.T_world_camera)
    if not np.any(np.isfinite(depth) & (depth > 0)):
        raise PerceptionError("depth has no valid pixel (all NaN, zero or negative)")
    return K, T


def transform(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4×4 rigid transform to N×3 points."""
    pts = np.asarray(points, dtype=float)
    return pts @ T[:3, :3].T + T[:3, 3]


def project_points(
    points_world: np.ndarray, intrinsics: CameraIntrinsics, T_world_camera: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project N×3 world points to pixels: (N×2 (u, v), N depths z in metres; z ≤ 0 = behind)."""
    K = check_intrinsics(intrinsics)
    T = check_pose(T_world_camera)
    pts = np.asarray(points_world, dtype=float).reshape(-1, 3)
    pc = transform(np.linalg.inv(T), pts)
    z = pc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (pc @ K.T)[:, :2] / z[:, None]
    return uv, z


def backproject(
    uv: np.ndarray, depth: np.ndarray, intrinsics: CameraIntrinsics, T_world_camera: np.ndarray
) -> np.ndarray:
    """World points (N×3, m) of pixels `uv` (N×2) at optical-axis depths `depth` (N, m)."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    z = np.asarray(depth, dtype=float).reshape(-1)
    if z.shape[0] != uv.shape[0]:
        raise PerceptionError(f"{uv.shape[0]} pixels but {z.shape[0]} depths")
    # Ray directions have a unit optical-axis component, so depth z scales them to the point.
    origin, directions = pixel_rays(uv, intrinsics, T_world_camera)
    return origin + directions * z[:, None]


def pixel_rays(
    uv: np.ndarray, intrinsics: CameraIntrinsics, T_world_camera: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World rays through pixels: (origin (3,), N×3 directions with unit optical-axis component)."""
    K = check_intrinsics(intrinsics)
    T = check_pose(T_world_camera)
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    rays = np.linalg.solve(K, np.c_[uv, np.ones(len(uv))].T).T
    return T[:3, 3].copy(), rays @ T[:3, :3].T


def robust_depth(depth: np.ndarray, u: float, v: float, radius: int = 3) -> float:
    """Median of the valid depths (finite, > 0) in a (2r+1)² window at pixel (u, v); NaN if none."""
    h, w = depth.shape
    c, r = int(np.rint(u)), int(np.rint(v))
    win = depth[
        max(0, r - radius) : min(h, r + radius + 1), max(0, c - radius) : min(w, c + radius + 1)
    ]
    vals = win[np.isfinite(win) & (win > 0)]
    return float(np.median(vals)) if vals.size else float("nan")


def backproject_pixel(obs: Observation, u: float, v: float, radius: int = 3) -> np.ndarray:
    """World point (3,) at pixel (u, v) using a robust depth lookup around it; NaN if no depth."""
    z = robust_depth(obs.depth, u, v, radius)
    return backproject(np.array([[u, v]]), np.array([z]), obs.intrinsics, obs.T_world_camera)[0]


@dataclass(frozen=True)
class Plane:
    """Plane n·x + d = 0 with unit normal n; height(x) = n·x + d is the signed distance (m)."""

    normal: np.ndarray
    offset: float

    def height(self, points: np.ndarray) -> np.ndarray:
        """Signed distances (m) of N×3 points from the plane along the normal."""
        return np.asarray(points, dtype=float) @ self.normal + self.offset

    def transformed(self, T: np.ndarray) -> Plane:
        """The same plane expressed in the frame T maps into (x' = T x)."""
        n = T[:3, :3] @ self.normal
        return Plane(normal=n, offset=float(self.offset - n @ T[:3, 3]))

    def intersect(
        self, origin: np.ndarray, directions: np.ndarray, height: float = 0.0
    ) -> np.ndarray:
        """Where rays origin + t·dir meet the parallel plane at `height` (NaN if parallel)."""
        dirs = np.asarray(directions, dtype=float).reshape(-1, 3)
        denom = dirs @ self.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (height - self.offset - origin @ self.normal) / denom
        t = np.where(np.abs(denom) > 1e-12, t, np.nan)
        return origin + t[:, None] * dirs


def fit_plane_lstsq(points: np.ndarray) -> Plane:
    """Least-squares plane through N ≥ 3 points (normal sign arbitrary)."""
    c = points.mean(axis=0)
    d = points - c
    _, vecs = np.linalg.eigh(d.T @ d)  # ascending eigenvalues: the normal is the first vector
    n = vecs[:, 0]
    return Plane(normal=n, offset=float(-n @ c))


def fit_plane_ransac(
    points: np.ndarray,
    threshold: float,
    rng: np.random.Generator,
    iterations: int = 64,
    up: np.ndarray | None = None,
    max_tilt: float = 0.45,
) -> tuple[Plane, np.ndarray]:
    """RANSAC plane (then least squares on its inliers): (plane, inlier mask).

    With `up` the normal is oriented along it and planes tilted more than `max_tilt` rad from it
    are rejected (the table is roughly level). Raises PerceptionError with fewer than 3 points.
    """
    pts = np.asarray(points, dtype=float)
    n_pts = len(pts)
    if n_pts < 3:
        raise PerceptionError(f"a plane needs at least 3 valid depth points, got {n_pts}")
    idx = rng.integers(0, n_pts, size=(iterations, 3))
    a, b, c = pts[idx[:, 0]], pts[idx[:, 1]], pts[idx[:, 2]]
    normals = np.cross(b - a, c - a)
    norms = np.linalg.norm(normals, axis=1)
    ok = norms > 1e-12
    normals[ok] /= norms[ok, None]
    if up is not None:
        cos_tilt = normals @ up
        normals *= np.where(cos_tilt < 0, -1.0, 1.0)[:, None]
        ok &= np.abs(cos_tilt) >= np.cos(max_tilt)
    if not np.any(ok):
        raise PerceptionError("no plausible table plane in the depth image")
    normals, a = normals[ok], a[ok]
    offsets = -np.einsum("ij,ij->i", normals, a)
    dist = np.abs(pts @ normals.T + offsets)  # N × iterations
    counts = (dist < threshold).sum(axis=0)
    best = int(np.argmax(counts))
    inliers = dist[:, best] < threshold
    plane = (
        fit_plane_lstsq(pts[inliers]) if inliers.sum() >= 3 else Plane(normals[best], offsets[best])
    )
    n = plane.normal
    if up is not None and n @ up < 0:
        plane = Plane(normal=-n, offset=-plane.offset)
    inliers = np.abs(plane.height(pts)) < threshold
    return plane, inliers


def polygon_area(points_2d: np.ndarray) -> float:
    """Area (shoelace) of a simple polygon given as N×2 vertices, any orientation."""
    x, y = points_2d[:, 0], points_2d[:, 1]
    return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
