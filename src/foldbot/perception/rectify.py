"""Rectify a real camera's images before perception: perception back-projects through the ideal
pinhole K, so a lens's distortion (camera_info's D, plumb_bob or rational_polynomial) is taken out
first, onto the same K. The simulated camera has none, and its images pass through untouched."""

from __future__ import annotations

import functools

import cv2
import numpy as np

from foldbot.errors import PerceptionError

DISTORTION_MODELS = ("plumb_bob", "rational_polynomial")
"""camera_info distortion models rectify takes (OpenCV's k1 k2 p1 p2 k3 [k4 k5 k6])."""


def _coefficients(distortion: np.ndarray | list[float], model: str) -> np.ndarray:
    d = np.asarray(distortion, dtype=float).reshape(-1)
    if not np.isfinite(d).all():
        raise PerceptionError(f"distortion coefficients must be finite, got {d.tolist()}")
    if not d.any():
        return d
    if model not in DISTORTION_MODELS:
        raise PerceptionError(
            f"cannot rectify distortion model {model!r} (coefficients {d.tolist()}); allowed: "
            f"{', '.join(DISTORTION_MODELS)}, or rectified images (zero coefficients)"
        )
    if d.size not in (4, 5, 8):
        raise PerceptionError(
            f"{model} distortion takes 4, 5 or 8 coefficients, got {d.size}: {d.tolist()}"
        )
    return d


@functools.lru_cache(maxsize=4)
def _maps(
    k: tuple[float, ...], d: tuple[float, ...], width: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    K = np.array(k, dtype=float).reshape(3, 3)
    return cv2.initUndistortRectifyMap(K, np.array(d), None, K, (width, height), cv2.CV_32FC1)


def rectify(
    rgb: np.ndarray,
    depth: np.ndarray | None,
    K: np.ndarray,
    distortion: np.ndarray | list[float],
    model: str = "plumb_bob",
) -> tuple[np.ndarray, np.ndarray | None]:
    """The colour (bilinear) and depth (nearest: no depth blended across an edge; None: none)
    images as an ideal pinhole camera with the same K would see them; unchanged (the same arrays)
    when every distortion coefficient is 0. Pixels that see nothing of the original are black /
    NaN."""
    d = _coefficients(distortion, model)
    if not d.any():
        return rgb, depth
    h, w = rgb.shape[:2]
    if depth is not None and depth.shape[:2] != (h, w):
        raise PerceptionError(
            f"colour ({rgb.shape[1]} × {rgb.shape[0]}) and depth ({w} × {h}) images differ in "
            "size; rectify needs them registered"
        )
    mx, my = _maps(tuple(np.asarray(K, float).ravel()), tuple(d), w, h)
    color = cv2.remap(rgb, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    if depth is None:
        return color, None
    return color, rectify_depth(depth, K, d, model)


def rectify_depth(
    depth: np.ndarray, K: np.ndarray, distortion: np.ndarray | list[float], model: str = "plumb_bob"
) -> np.ndarray:
    """A depth image alone rectified onto the same K (nearest: every value one the camera
    measured), as for a depth sensor with its own camera_info; unchanged (the same array) when
    every distortion coefficient is 0."""
    d = _coefficients(distortion, model)
    if not d.any():
        return depth
    h, w = depth.shape[:2]
    mx, my = _maps(tuple(np.asarray(K, float).ravel()), tuple(d), w, h)
    return cv2.remap(
        np.asarray(depth, dtype=np.float32),
        mx,
        my,
        cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=float("nan"),
    )
