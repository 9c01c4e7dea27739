"""How a crumpled towel is flattened, set by name: `foldbot fold --flatten-option NAME=VALUE`,
`foldbot bench --flatten-option NAME=VALUE`, a suite's `[flatten_options]` table,
EpisodeConfig.flatten_options.

They are the fields of planning.flatten.FlattenConfig (the stop rule and the one-arm pulls) and,
prefixed `spread_`, of planning.spread.SpreadConfig (the two-arm cell's spreads) that a flattening
trial changes; each was measured at its default (docs/experiments.md says where), and setting one
reproduces such a trial from the command line instead of a patched copy of the code. The action
budget (FlattenConfig.max_actions, 6: the issue's "within 6 actions") and the planner's internals
(raster, yaw step, workspace) are not among them. result.json records the ones set
(`flatten_options`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

from foldbot.errors import ConfigError, option_word, options_from_args, split_name_value
from foldbot.planning.flatten import GRASP_LAYERS, FlattenConfig
from foldbot.planning.spread import LEAN_MODES, SpreadConfig
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout

FlattenOptionValue = bool | int | float | str | None
"""What a flatten option holds: a switch, a count, a number (SI units), a name, or None."""


@dataclass(frozen=True)
class FlattenOption:
    """One settable field: which config holds it, what kind of value it takes, its unit."""

    config: type
    """FlattenConfig or SpreadConfig."""
    field: str
    """The field's name there."""
    kind: str
    """switch, count, number, number or none, or choice (one of `choices`)."""
    unit: str = ""
    """The number's unit for help text: m, s, m/s, rad, or a coverage (top-view area / flat
    area)."""
    choices: tuple[str, ...] = ()
    """A choice's allowed names."""


def _pull(field: str, kind: str, unit: str = "", choices: tuple[str, ...] = ()) -> FlattenOption:
    return FlattenOption(FlattenConfig, field, kind, unit, choices)


def _spread(field: str, kind: str, unit: str = "", choices: tuple[str, ...] = ()) -> FlattenOption:
    return FlattenOption(SpreadConfig, field, kind, unit, choices)


FLATTEN_OPTION_FIELDS: dict[str, FlattenOption] = {
    "target_coverage": _pull("target_coverage", "number", "coverage"),
    "finish_coverage": _pull("finish_coverage", "number or none", "coverage"),
    "grasp_layer": _pull("grasp_layer", "choice", choices=GRASP_LAYERS),
    "grasp_inset": _pull("grasp_inset", "number", "m"),
    "max_inset": _pull("max_inset", "number", "m"),
    "retries": _pull("retries", "count"),
    "retry_step": _pull("retry_step", "number", "m"),
    "missed_radius": _pull("missed_radius", "number", "m"),
    "palm_clearance": _pull("palm_clearance", "number", "m"),
    "release_height": _pull("release_height", "number", "m"),
    "overshoot": _pull("overshoot", "number", "m"),
    "min_pull": _pull("min_pull", "number", "m"),
    "settle_time": _pull("settle_time", "number", "s"),
    "keep_yaw": _pull("keep_yaw", "switch"),
    "spread_pull_from": _spread("pull_from", "number or none", "coverage"),
    "spread_hang_time": _spread("hang_time", "number", "s"),
    "spread_descend_speed": _spread("descend_speed", "number", "m/s"),
    "spread_slow_descent": _spread("slow_descent", "number", "m"),
    "spread_lift_speed": _spread("lift_speed", "number", "m/s"),
    "spread_lay_speed": _spread("lay_speed", "number", "m/s"),
    "spread_release_height": _spread("release_height", "number", "m"),
    "spread_grasp_inset": _spread("grasp_inset", "number", "m"),
    "spread_top_depth": _spread("top_depth", "number", "m"),
    "spread_seek_cloth": _spread("seek_cloth", "number", "m"),
    "spread_grasp_tilt": _spread("grasp_tilt", "number", "rad"),
    "spread_grasp_lean": _spread("grasp_lean", "choice", choices=LEAN_MODES),
}
"""Option name → the config field it sets (see each field's docstring there for its meaning and
what was measured)."""

FLATTEN_OPTIONS = tuple(FLATTEN_OPTION_FIELDS)
"""The names allowed: the stop rule and the pulls, then the spreads."""
SPREAD_OPTIONS = tuple(n for n, o in FLATTEN_OPTION_FIELDS.items() if o.config is SpreadConfig)
"""The options only the two-arm cell's spreads read (a one-arm cell refuses them)."""


def flatten_option_default(name: str) -> FlattenOptionValue:
    """The config's default for an option (what an episode uses when the option is not set)."""
    option = FLATTEN_OPTION_FIELDS[name]
    return {f.name: f.default for f in dataclasses.fields(option.config)}[option.field]


def _allowed(name: str) -> str:
    option = FLATTEN_OPTION_FIELDS[name]
    unit = f" ({option.unit})" if option.unit else ""
    return {
        "switch": "true or false",
        "count": "an integer",
        "number": f"a number{unit}",
        "number or none": f"a number{unit}, or none",
        "choice": f"one of {', '.join(option.choices)}",
    }[option.kind]


def check_flatten_option(name: str, value: object) -> FlattenOptionValue:
    """The option's value, type-checked (numbers as float); its range is the config's own
    (check_flatten_options). ConfigError naming the option, the value and what is allowed."""
    if name not in FLATTEN_OPTION_FIELDS:
        raise ConfigError(f"unknown flatten option {name!r}; allowed: {', '.join(FLATTEN_OPTIONS)}")
    kind = FLATTEN_OPTION_FIELDS[name].kind
    bad = ConfigError(f"flatten option {name} = {value!r} must be {_allowed(name)}")
    if kind == "switch":
        if not isinstance(value, bool):
            raise bad
        return value
    if kind == "choice":
        if value not in FLATTEN_OPTION_FIELDS[name].choices:
            raise bad
        return str(value)
    if value is None and kind == "number or none":
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise bad
    if kind == "count":
        if not isinstance(value, int):
            raise bad
        return value
    return float(value)


def check_flatten_options(options: Mapping[str, object]) -> dict[str, FlattenOptionValue]:
    """Every option checked (check_flatten_option, then the configs built with them, which
    check the ranges and name the field), as a plain dict in FLATTEN_OPTIONS' order."""
    if not isinstance(options, Mapping):
        raise ConfigError(f"flatten options must be a table of name = value, got {options!r}")
    checked = {name: check_flatten_option(name, value) for name, value in options.items()}
    try:
        flatten_configs(checked)
    except ConfigError as exc:  # "FlattenConfig.grasp_inset must be …": name the option instead
        message = str(exc)
        for name in checked:
            option = FLATTEN_OPTION_FIELDS[name]
            message = message.replace(f"{option.config.__name__}.{option.field} ", f"{name} ")
        raise ConfigError(f"flatten option {message}") from None
    return {name: checked[name] for name in FLATTEN_OPTIONS if name in checked}


def flatten_configs(
    options: Mapping[str, object], layout: CellLayout = DEFAULT_LAYOUT
) -> tuple[FlattenConfig, SpreadConfig]:
    """The pull and spread configurations with the (checked) options set, the rest at their
    defaults; in a cell laid out otherwise than the default one, the defaults placed in the
    world (the flattening's region and where a spread lays the towel: with the workspace; how
    far out a spread holds it: with the arm's base) moved as the layout moves them."""
    fields: dict[type, dict[str, object]] = {FlattenConfig: {}, SpreadConfig: {}}
    for name, value in options.items():
        option = FLATTEN_OPTION_FIELDS[name]
        fields[option.config][option.field] = value
    dx, dy, _ = layout.workspace_shift()
    if dx or dy:
        x0, x1, y0, y1 = FlattenConfig.workspace
        fields[FlattenConfig].setdefault("workspace", (x0 + dx, x1 + dx, y0 + dy, y1 + dy))
        cx, cy = SpreadConfig.center_xy
        fields[SpreadConfig].setdefault("center_xy", (cx + dx, cy + dy))
    bx = layout.base_shift()[0]
    if bx:
        fields[SpreadConfig].setdefault("hold_far_x", SpreadConfig.hold_far_x + bx)
    return FlattenConfig(**fields[FlattenConfig]), SpreadConfig(**fields[SpreadConfig])


def parse_flatten_option(text: str) -> tuple[str, FlattenOptionValue]:
    """'NAME=VALUE' from the command line → (name, checked value). VALUE is true/false, an
    integer, a number, none, or one of a choice's names."""
    name, raw = split_name_value(text, "flatten option", "finish_coverage=none", FLATTEN_OPTIONS)
    if name not in FLATTEN_OPTION_FIELDS:
        check_flatten_option(name, None)  # raises: unknown name, with the allowed ones
    try:
        value = option_word(raw, FLATTEN_OPTION_FIELDS[name].choices)
    except ValueError:
        raise ConfigError(f"flatten option {name} = {raw!r} must be {_allowed(name)}") from None
    return name, check_flatten_options({name: value})[name]


def flatten_options_from_args(texts: list[str]) -> dict[str, FlattenOptionValue]:
    """Repeated --flatten-option NAME=VALUE, each checked; naming an option twice is an error."""
    options = options_from_args(
        texts, parse_flatten_option, "--flatten-option", shown_flatten_value
    )
    return check_flatten_options(options)


def flatten_options_help() -> str:
    """One line for --help: each name with its unit and default."""
    parts = []
    for name in FLATTEN_OPTIONS:
        unit = FLATTEN_OPTION_FIELDS[name].unit
        default = shown_flatten_value(flatten_option_default(name))
        parts.append(f"{name} ({unit + ', ' if unit else ''}default {default})")
    return "; ".join(parts) + ". The spread_ ones act on the two-arm cell's spreads"


def shown_flatten_value(value: FlattenOptionValue) -> str:
    """An option value as the command line writes it: true, false, none, a name, the number."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "none"
    return value if isinstance(value, str) else f"{value:g}"


def refused_flatten_options(
    options: Mapping[str, object], start: str, arms: int, perception: str
) -> str | None:
    """Why an episode (its start, arms, perception) would not read some of `options` (the
    message), or None when it reads them all: flatten options act on crumpled starts only, the
    spread_ ones on the two-arm cell's spreads, which vision plans (the oracle pulls)."""
    if not options:
        return None
    if start != "crumpled":
        return (
            f"flatten options ({', '.join(options)}) act on crumpled starts only; this episode "
            f"starts {start}"
        )
    spread = [name for name in options if name in SPREAD_OPTIONS]
    if spread and (arms != 2 or perception != "vision"):
        cell = "a one-arm cell pulls" if arms != 2 else "the oracle pulls"
        return (
            f"flatten option{'s' if len(spread) > 1 else ''} {', '.join(spread)} act"
            f"{'' if len(spread) > 1 else 's'} on the two-arm cell's spreads, with vision "
            f"perception; {cell}"
        )
    return None
