"""Register a depth image onto the colour camera: a real RGB-D camera's depth sensor sits a
centimetre or two beside its colour sensor, with its own intrinsics and often its own image size,
and perception reads depth at the colour image's pixels. Each depth pixel is lifted to 3-D,
moved into the colour camera's frame and drawn there over the colour pixels its footprint covers,
the nearest surface winning (what the colour camera sees in front). The simulated camera's depth
is rendered at the colour camera already and needs none of this."""

from __future__ import annotations

import numpy as np

from foldbot.errors import PerceptionError

MAX_FOOTPRINT_PX = 8
"""Largest footprint (colour pixels along a side) one depth pixel is drawn over: a depth camera
of far coarser resolution than the colour one is refused rather than drawn as blocks."""


def _intrinsics(K: np.ndarray, name: str) -> tuple[float, float, float, float]:
    K = np.asarray(K, dtype=float)
    if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise PerceptionError(f"{name} must be a finite 3×3 K with fx, fy > 0, got {K.tolist()}")
    return float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])


def register_depth(
    depth: np.ndarray,
    K_depth: np.ndarray,
    K_color: np.ndarray,
    T_color_depth: np.ndarray,
    color_size: tuple[int, int],
) -> np.ndarray:
    """The depth image `depth` (metres, NaN or 0: no reading) of a camera with intrinsics K_depth,
    as a depth image of the colour camera (K_color, `color_size` = (width, height)), where
    T_color_depth maps the depth camera's coordinates (OpenCV axes) into the colour camera's.
    Each valid depth pixel covers the colour pixels between the projections of its corners;
    where several land on one colour pixel the nearest wins; colour pixels no depth reading
    reaches (the depth sensor's shadow beside an edge, outside its view) are NaN."""
    z = np.asarray(depth, dtype=np.float64)
    if z.ndim != 2:
        raise PerceptionError(f"depth must be an H×W image, got shape {z.shape}")
    T = np.asarray(T_color_depth, dtype=float)
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise PerceptionError(f"T_color_depth must be a finite 4×4 transform, got shape {T.shape}")
    width, height = (int(v) for v in color_size)
    if width <= 0 or height <= 0:
        raise PerceptionError(f"colour image size must be positive, got {color_size!r}")
    fxd, fyd, cxd, cyd = _intrinsics(K_depth, "K_depth")
    fxc, fyc, cxc, cyc = _intrinsics(K_color, "K_color")

    v, u = np.nonzero(np.isfinite(z) & (z > 0))
    d = z[v, u]
    # The depth pixel's two opposite corners, lifted at its depth and moved into the colour frame.
    corners = []
    for du, dv in ((-0.5, -0.5), (0.5, 0.5)):
        p = np.stack([(u + du - cxd) * d / fxd, (v + dv - cyd) * d / fyd, d])
        corners.append(T[:3, :3] @ p + T[:3, 3:4])
    (x0, y0, z0), (x1, y1, z1) = corners
    zc = 0.5 * (z0 + z1)
    ahead = (z0 > 0) & (z1 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        u0, u1 = fxc * x0 / z0 + cxc, fxc * x1 / z1 + cxc
        v0, v1 = fyc * y0 / z0 + cyc, fyc * y1 / z1 + cyc
    # Colour pixels whose centre (integer coordinates) lies in the footprint [lo, hi).
    ulo = np.ceil(np.minimum(u0, u1))
    uhi = np.ceil(np.maximum(u0, u1)) - 1
    vlo = np.ceil(np.minimum(v0, v1))
    vhi = np.ceil(np.maximum(v0, v1)) - 1
    # A footprint that holds no pixel centre still lands on the pixel under its middle.
    um = np.rint(0.5 * (u0 + u1))
    vm = np.rint(0.5 * (v0 + v1))
    ulo, uhi = np.where(uhi < ulo, um, ulo), np.where(uhi < ulo, um, uhi)
    vlo, vhi = np.where(vhi < vlo, vm, vlo), np.where(vhi < vlo, vm, vhi)
    ok = ahead & np.isfinite(ulo + uhi + vlo + vhi)
    ok &= (uhi >= 0) & (ulo <= width - 1) & (vhi >= 0) & (vlo <= height - 1)
    ulo, uhi, vlo, vhi, zc = ulo[ok], uhi[ok], vlo[ok], vhi[ok], zc[ok]
    span = max(int((uhi - ulo).max(initial=0.0)) + 1, int((vhi - vlo).max(initial=0.0)) + 1)
    if span > MAX_FOOTPRINT_PX:
        raise PerceptionError(
            f"one depth pixel covers up to {span} colour pixels along a side (at most "
            f"{MAX_FOOTPRINT_PX}); give a depth image nearer the colour image's resolution"
        )
    out = np.full(height * width, np.inf)
    for du in range(span):
        for dv in range(span):
            uu, vv = ulo + du, vlo + dv
            hit = (uu <= uhi) & (vv <= vhi) & (uu >= 0) & (uu < width) & (vv >= 0) & (vv < height)
            idx = vv[hit].astype(np.int64) * width + uu[hit].astype(np.int64)
            np.minimum.at(out, idx, zc[hit])
    out[~np.isfinite(out)] = np.nan
    return out.reshape(height, width).astype(np.float32)
