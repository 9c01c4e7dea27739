"""The cloth's physical parameters set by name: checked, parsed from the command line, applied,
and what an episode records of them."""

import dataclasses

import pytest

from foldbot.cloth_options import (
    CLOTH_OPTIONS,
    COUNT_CLOTH_OPTIONS,
    apply_cloth_options,
    changed_cloth_options,
    check_cloth_options,
    cloth_option_default,
    cloth_options_from_args,
    cloth_options_help,
    parse_cloth_option,
)
from foldbot.errors import ConfigError
from foldbot.sim.cloth import ClothConfig


def test_every_option_is_a_numeric_cloth_field():
    fields = {f.name: f for f in dataclasses.fields(ClothConfig)}
    for name in CLOTH_OPTIONS:
        if name == "layer_friction":  # unset by default: cloth–cloth friction follows friction²
            assert cloth_option_default(name) is None
            assert fields[name].type == "float | None"
            continue
        if name in COUNT_CLOTH_OPTIONS:  # physics steps: a whole number
            assert isinstance(cloth_option_default(name), int), name
            assert fields[name].type == "int", name
            continue
        assert isinstance(cloth_option_default(name), float), name
        assert fields[name].type == "float", name


def test_options_are_checked_and_kept_in_their_order():
    options = check_cloth_options({"margin_divisor": 8, "friction": 0.5})
    assert options == {"friction": 0.5, "margin_divisor": 8.0}
    assert list(options) == ["friction", "margin_divisor"]
    assert all(isinstance(v, float) for v in options.values())
    assert check_cloth_options({}) == {}


@pytest.mark.parametrize(
    ("options", "needle"),
    [
        ({"thickness": 0.01}, "unknown cloth option 'thickness'; allowed: mass, elastic_stiffness"),
        ({"friction": True}, "cloth option friction = True must be a finite number"),
        ({"friction": "high"}, "cloth option friction = 'high' must be a finite number"),
        ({"mass": float("inf")}, "cloth option mass = inf must be a finite number"),
        ({"mass": 0.0}, "cloth mass must be in (0, 5] kg, got 0.0"),
        ({"margin_divisor": 1.5}, "cloth margin_divisor must be in [2, 20]"),
        ({"damping_stiffness": -1}, "cloth damping_stiffness must be ≥ 0, got -1.0"),
        ({"layer_friction": 0}, "cloth layer_friction must be in (0, 4] (or unset: friction²)"),
        ({"crossing_guard": 1.5}, "cloth crossing_guard must be an integer in [0, 100] physics"),
        ({"crossing_guard": -1}, "cloth crossing_guard must be an integer in [0, 100] physics"),
    ],
)
def test_a_bad_option_names_itself_and_what_is_allowed(options, needle):
    with pytest.raises(ConfigError) as exc:
        check_cloth_options(options)
    assert needle in str(exc.value)


def test_the_command_line_form():
    assert parse_cloth_option("margin_divisor=6.5") == ("margin_divisor", 6.5)
    assert parse_cloth_option(" friction = 2 ") == ("friction", 2.0)
    assert parse_cloth_option("crossing_guard=2") == ("crossing_guard", 2)
    assert cloth_options_from_args(["mass=0.2", "friction=0.5"]) == {"mass": 0.2, "friction": 0.5}
    for text, needle in [
        ("friction", "must look like NAME=VALUE"),
        ("friction=", "must look like NAME=VALUE"),
        ("friction=high", "friction = 'high' must be a finite number"),
        ("colour=2", "unknown cloth option 'colour'"),
    ]:
        with pytest.raises(ConfigError, match=needle):
            parse_cloth_option(text)
    with pytest.raises(ConfigError, match="--cloth mass is given twice"):
        cloth_options_from_args(["mass=0.2", "mass=0.3"])


def test_applied_and_recorded_only_where_they_differ_from_the_defaults():
    cloth = apply_cloth_options(ClothConfig(), {"margin_divisor": 6.5, "mass": 0.1})
    assert cloth.margin_divisor == 6.5 and cloth.mass == 0.1
    assert changed_cloth_options(cloth) == {"margin_divisor": 6.5}  # mass 0.1 is the default
    assert changed_cloth_options(ClothConfig()) == {}
    layers = apply_cloth_options(ClothConfig(), {"layer_friction": 0.25})
    assert changed_cloth_options(layers) == {"layer_friction": 0.25}
    guarded = apply_cloth_options(ClothConfig(), {"crossing_guard": 1.0})
    assert guarded.crossing_guard == 1 and isinstance(guarded.crossing_guard, int)
    assert changed_cloth_options(guarded) == {"crossing_guard": 1}


def test_the_help_names_every_option_with_its_default():
    text = cloth_options_help()
    for name in CLOTH_OPTIONS:
        default = cloth_option_default(name)
        shown = "friction²" if default is None else f"{default:g}"
        assert f"{name} (default {shown})" in text
