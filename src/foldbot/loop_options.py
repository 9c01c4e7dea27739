"""The closed loop's switches that a user may set by name: `foldbot fold --loop-option NAME=VALUE`,
a suite's `[loop_options]` table, EpisodeConfig.loop_options.

They are the LoopConfig fields that no other episode setting fixes (recipe, retries, tolerances
and the like come from EpisodeConfig). Each was measured at its default (docs/experiments.md says
where); setting one reproduces a trial from the command line instead of a patched copy of the code.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from foldbot.errors import ConfigError, option_word, options_from_args, split_name_value
from foldbot.loop import LoopConfig

LoopOptionValue = bool | int | float | None
"""What a loop option holds: a switch, a count, or a length in metres (None where allowed)."""

LOOP_OPTION_KINDS: dict[str, str] = {
    "finish_actions": "count",
    "stack_inset": "length",
    "crease_band": "length",
    "crease_room": "length or none",
    "relay_corners": "switch",
    "relay_tolerance": "length",
    "relay_reach": "length",
    "relay_min_rise": "length",
    "relay_side": "length",
    "relay_stadium": "switch",
    "top_layer_first": "switch",
    "pair_descent": "length or none",
    "stack_edge_carry": "switch",
    "slip_lay_back": "switch",
    "slip_lay_back_lift": "length",
}
"""Option name → kind: switch (true/false), count (an integer in [0, MAX_COUNT]), length (m, in
[0, MAX_LENGTH]), or length or none (None: the field's documented fallback)."""

LOOP_OPTIONS = tuple(LOOP_OPTION_KINDS)
"""The names allowed, in LoopConfig's order of meaning (see each field's docstring there)."""

GARMENT_LOOP_OPTIONS = ("top_layer_first", "relay_min_rise")
"""The options a garment's loop (foldbot.garment_loop) reads; the others act on towel folds only
(their corners, stacks, relays and finishing carries), so setting one for a garment is refused
rather than silently ignored."""

MAX_COUNT = 5
"""A count option's upper bound (finish_actions: extra carries per stage)."""
MAX_LENGTH = 0.5
"""A length option's upper bound (m): every one of them is a few cm in a 1 m workspace."""


def loop_option_default(name: str) -> LoopOptionValue:
    """LoopConfig's default for an option (what an episode uses when the option is not set)."""
    return {f.name: f.default for f in dataclasses.fields(LoopConfig)}[name]


def _allowed(name: str) -> str:
    kind = LOOP_OPTION_KINDS[name]
    return {
        "switch": "true or false",
        "count": f"an integer in [0, {MAX_COUNT}]",
        "length": f"a length in m in [0, {MAX_LENGTH:g}]",
        "length or none": f"a length in m in [0, {MAX_LENGTH:g}], or none",
    }[kind]


def check_loop_option(name: str, value: object) -> LoopOptionValue:
    """The option's value, checked (lengths as float); ConfigError naming the option, the value
    and what is allowed otherwise."""
    if name not in LOOP_OPTION_KINDS:
        raise ConfigError(f"unknown loop option {name!r}; allowed: {', '.join(LOOP_OPTIONS)}")
    kind = LOOP_OPTION_KINDS[name]
    bad = ConfigError(f"loop option {name} = {value!r} must be {_allowed(name)}")
    if kind == "switch":
        if not isinstance(value, bool):
            raise bad
        return value
    if value is None:
        if kind != "length or none":
            raise bad
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise bad
    if kind == "count":
        if not isinstance(value, int) or not 0 <= value <= MAX_COUNT:
            raise bad
        return value
    if not (math.isfinite(value) and 0.0 <= value <= MAX_LENGTH):
        raise bad
    return float(value)


def check_loop_options(
    options: Mapping[str, object], garment: str = "towel"
) -> dict[str, LoopOptionValue]:
    """Every option checked (check_loop_option), as a plain dict in LOOP_OPTIONS' order; for a
    garment other than a towel, only those its loop reads (GARMENT_LOOP_OPTIONS)."""
    if not isinstance(options, Mapping):
        raise ConfigError(f"loop options must be a table of name = value, got {options!r}")
    checked = {name: check_loop_option(name, value) for name, value in options.items()}
    if garment != "towel":
        unread = [
            name for name in LOOP_OPTIONS if name in checked and name not in GARMENT_LOOP_OPTIONS
        ]
        if unread:
            raise ConfigError(
                f"loop option{'s' if len(unread) > 1 else ''} {', '.join(unread)} act"
                f"{'' if len(unread) > 1 else 's'} on towel folds only; the {garment} loop reads "
                f"{', '.join(GARMENT_LOOP_OPTIONS)}"
            )
    return {name: checked[name] for name in LOOP_OPTIONS if name in checked}


def parse_loop_option(text: str) -> tuple[str, LoopOptionValue]:
    """'NAME=VALUE' from the command line → (name, checked value). VALUE is true/false, an
    integer, a number of metres, or none."""
    name, raw = split_name_value(text, "loop option", "top_layer_first=false", LOOP_OPTIONS)
    if name not in LOOP_OPTION_KINDS:
        check_loop_option(name, None)  # raises: unknown name, with the allowed ones
    try:
        value = option_word(raw)
    except ValueError:
        raise ConfigError(f"loop option {name} = {raw!r} must be {_allowed(name)}") from None
    return name, check_loop_option(name, value)


def loop_options_from_args(texts: list[str]) -> dict[str, LoopOptionValue]:
    """Repeated --loop-option NAME=VALUE, each checked; naming an option twice is an error."""
    return options_from_args(texts, parse_loop_option, "--loop-option", shown_value)


def apply_loop_options(loop: LoopConfig, options: Mapping[str, object]) -> LoopConfig:
    """`loop` with the options set (each checked first)."""
    return dataclasses.replace(loop, **check_loop_options(options))


def loop_options_help() -> str:
    """One line per option for --help: name, what it takes, default; which ones garments read."""
    return (
        "; ".join(
            f"{name} ({LOOP_OPTION_KINDS[name]}, default {shown_value(loop_option_default(name))})"
            for name in LOOP_OPTIONS
        )
        + f". A T-shirt's or pants' loop reads only {' and '.join(GARMENT_LOOP_OPTIONS)}"
    )


def shown_value(value: LoopOptionValue) -> str:
    """An option value as the command line writes it: true, false, none, or the number."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return "none" if value is None else f"{value:g}"
