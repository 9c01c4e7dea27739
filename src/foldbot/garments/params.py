"""Shared helpers of the parametric garment specs: range checks and uniform sampling of fields."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from foldbot.errors import require


def check_ranges(kind: str, spec: object, limits: Mapping[str, tuple[float, float, str]]) -> None:
    """ConfigError naming the field, its value and the allowed range unless every field is in it.

    `limits` maps a field name to (low, high, unit).
    """
    for name, (lo, hi, unit) in limits.items():
        value = getattr(spec, name)
        ok = (
            isinstance(value, int | float | np.floating | np.integer)
            and not isinstance(value, bool)
            and math.isfinite(value)
            and lo <= value <= hi
        )
        require(ok, f"{kind} {name} must be in [{lo}, {hi}] {unit}, got {value!r}")


def sample_ranges(
    rng: np.random.Generator, ranges: Mapping[str, tuple[float, float]]
) -> dict[str, float]:
    """One uniform draw per field from `ranges` (name → (low, high)), in the mapping's order."""
    return {name: float(rng.uniform(lo, hi)) for name, (lo, hi) in ranges.items()}
