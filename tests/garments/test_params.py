"""The garment specs' shared range check and uniform draws."""

from dataclasses import dataclass

import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.garments.params import check_ranges, sample_ranges

LIMITS = {"width": (0.2, 0.8, "m"), "sleeves": (0, 4, "sleeves")}


@dataclass
class Spec:
    width: object = 0.5
    sleeves: object = 2


def test_values_inside_their_ranges_pass():
    check_ranges("shirt", Spec(), LIMITS)
    check_ranges("shirt", Spec(width=np.float64(0.2), sleeves=np.int64(4)), LIMITS)  # the ends


@pytest.mark.parametrize(
    ("spec", "says"),
    [
        (Spec(width=0.9), "shirt width must be in [0.2, 0.8] m, got 0.9"),
        (Spec(width=float("nan")), "shirt width must be in [0.2, 0.8] m, got nan"),
        (Spec(width="0.5"), "shirt width must be in [0.2, 0.8] m, got '0.5'"),
        (Spec(sleeves=True), "shirt sleeves must be in [0, 4] sleeves, got True"),
        (Spec(sleeves=-1), "shirt sleeves must be in [0, 4] sleeves, got -1"),
    ],
)
def test_a_value_outside_its_range_is_named_with_the_range(spec, says):
    with pytest.raises(ConfigError) as exc:
        check_ranges("shirt", spec, LIMITS)
    assert str(exc.value) == says


def test_draws_are_uniform_in_their_ranges_in_order_and_seeded():
    ranges = {"b": (1.0, 2.0), "a": (-3.0, -2.5)}
    draws = [sample_ranges(np.random.default_rng(seed), ranges) for seed in range(200)]
    assert all(list(d) == ["b", "a"] for d in draws)  # the mapping's order
    b = np.array([d["b"] for d in draws])
    a = np.array([d["a"] for d in draws])
    assert b.min() >= 1.0 and b.max() <= 2.0 and a.min() >= -3.0 and a.max() <= -2.5
    assert 1.4 < b.mean() < 1.6 and b.max() - b.min() > 0.9  # spread over the range
    assert sample_ranges(np.random.default_rng(7), ranges) == draws[7]  # the seed's draw
