"""The cloth's physical parameters a user may set by name: `foldbot fold --cloth NAME=VALUE`,
`foldbot bench --cloth NAME=VALUE`, a suite's `[cloth]` table.

They are sim.cloth.ClothConfig's physics fields (mass, spring stiffnesses, friction with the
table and between layers, the collision margin's share of a mesh edge). Each was measured at its
default, and most physics trials in docs/experiments.md change one of them: setting it
reproduces such a trial from the command line instead of a patched copy of the code. result.json
records the ones that differ from the defaults (`cloth_options`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from foldbot.errors import ConfigError, options_from_args, split_name_value
from foldbot.sim.cloth import ClothConfig

CLOTH_OPTIONS = (
    "mass",
    "elastic_stiffness",
    "damping_stiffness",
    "bending_stiffness",
    "friction",
    "layer_friction",
    "margin_divisor",
    "crossing_guard",
)
"""The names allowed (see each field's docstring in ClothConfig; every value is a number)."""

COUNT_CLOTH_OPTIONS = ("crossing_guard",)
"""The options that count (physics steps): a whole number is kept as an int."""


def cloth_option_default(name: str) -> float | None:
    """ClothConfig's default for an option (None: layer_friction unset, friction²)."""
    return {f.name: f.default for f in dataclasses.fields(ClothConfig)}[name]


def check_cloth_options(options: Mapping[str, object]) -> dict[str, float]:
    """Every option checked (a known name, a finite number, a value ClothConfig accepts), as a
    plain dict of floats (ints for a count) in CLOTH_OPTIONS' order; ConfigError naming the
    option, the value and what is allowed otherwise."""
    if not isinstance(options, Mapping):
        raise ConfigError(f"cloth options must be a table of name = number, got {options!r}")
    checked: dict[str, float] = {}
    for name, value in options.items():
        if name not in CLOTH_OPTIONS:
            raise ConfigError(f"unknown cloth option {name!r}; allowed: {', '.join(CLOTH_OPTIONS)}")
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise ConfigError(f"cloth option {name} = {value!r} must be a finite number")
        checked[name] = float(value)
        if name in COUNT_CLOTH_OPTIONS and checked[name].is_integer():
            checked[name] = int(checked[name])
    ClothConfig(**checked)  # its own ranges: ConfigError naming the field and the value
    return {name: checked[name] for name in CLOTH_OPTIONS if name in checked}


def apply_cloth_options(cloth: ClothConfig, options: Mapping[str, object]) -> ClothConfig:
    """`cloth` with the options set (each checked first)."""
    return dataclasses.replace(cloth, **check_cloth_options(options))


def changed_cloth_options(cloth: ClothConfig) -> dict[str, float]:
    """The options whose value in `cloth` differs from ClothConfig's default (what result.json
    records: an episode at the defaults records {})."""
    return {
        n: getattr(cloth, n) for n in CLOTH_OPTIONS if getattr(cloth, n) != cloth_option_default(n)
    }


def parse_cloth_option(text: str) -> tuple[str, float]:
    """'NAME=VALUE' from the command line → (name, checked value)."""
    name, raw = split_name_value(text, "cloth option", "margin_divisor=6.5", CLOTH_OPTIONS)
    try:
        value = float(raw)
    except ValueError:
        value = raw  # check_cloth_options names it: not a number (or an unknown name first)
    return name, check_cloth_options({name: value})[name]


def cloth_options_from_args(texts: list[str]) -> dict[str, float]:
    """Repeated --cloth NAME=VALUE, each checked; naming an option twice is an error."""
    return options_from_args(texts, parse_cloth_option, "--cloth", lambda v: f"{v:g}")


def cloth_options_help() -> str:
    """One line for --help: each name with its default."""
    return "; ".join(f"{n} (default {_default_text(n)})" for n in CLOTH_OPTIONS)


def _default_text(name: str) -> str:
    default = cloth_option_default(name)
    return "friction²" if default is None else f"{default:g}"
