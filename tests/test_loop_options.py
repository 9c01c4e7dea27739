"""The closed loop's switches set by name: checked, parsed from the command line, applied."""

import dataclasses
import math

import pytest

from foldbot.errors import ConfigError
from foldbot.loop import LoopConfig
from foldbot.loop_options import (
    GARMENT_LOOP_OPTIONS,
    LOOP_OPTION_KINDS,
    LOOP_OPTIONS,
    apply_loop_options,
    check_loop_option,
    check_loop_options,
    loop_option_default,
    loop_options_from_args,
    loop_options_help,
    parse_loop_option,
)
from foldbot.pipeline import EpisodeConfig, loop_config

KIND_OF_TYPE = {
    "bool": "switch",
    "int": "count",
    "float": "length",
    "float | None": "length or none",
}


def test_every_option_is_a_loop_field_of_its_kind():
    types = {f.name: f.type for f in dataclasses.fields(LoopConfig)}
    for name, kind in LOOP_OPTION_KINDS.items():
        assert KIND_OF_TYPE[types[name]] == kind, name


def test_no_option_is_a_field_the_episode_config_already_sets():
    """Recipe, retries, tolerances, … come from EpisodeConfig: an option may not override them."""
    set_by_episode = {
        "recipe", "retries", "place_tolerance", "regrasp_radius", "regrasp_label_radius",
        "fault_grasp_offset", "verify_iou", "place_lift", "require_full_view", "closed_loop",
        "layer_thickness", "stack_grasp_height",
    }  # fmt: skip
    assert not set_by_episode & set(LOOP_OPTIONS)
    fields = {f.name for f in dataclasses.fields(LoopConfig)}
    assert fields == set_by_episode | set(LOOP_OPTIONS)  # every other field can be set


@pytest.mark.parametrize(
    ("name", "value", "expected"),
    [
        ("top_layer_first", False, False),
        ("finish_actions", 0, 0),
        ("finish_actions", 5, 5),
        ("crease_band", 0, 0.0),
        ("relay_tolerance", 0.012, 0.012),
        ("pair_descent", None, None),
        ("crease_room", 0.01, 0.01),
    ],
)
def test_good_values_are_kept(name, value, expected):
    checked = check_loop_option(name, value)
    assert checked == expected and type(checked) is type(expected)


@pytest.mark.parametrize(
    ("name", "value", "allowed"),
    [
        ("top_layer_first", 1, "true or false"),
        ("top_layer_first", None, "true or false"),
        ("finish_actions", 1.5, "an integer in [0, 5]"),
        ("finish_actions", 6, "an integer in [0, 5]"),
        ("finish_actions", True, "an integer in [0, 5]"),
        ("crease_band", -0.01, "a length in m in [0, 0.5]"),
        ("crease_band", math.inf, "a length in m in [0, 0.5]"),
        ("crease_band", 2.0, "a length in m in [0, 0.5]"),
        ("crease_band", None, "a length in m in [0, 0.5]"),
        ("crease_band", "3 cm", "a length in m in [0, 0.5]"),
        ("pair_descent", False, "or none"),
    ],
)
def test_bad_values_name_the_option_the_value_and_what_is_allowed(name, value, allowed):
    with pytest.raises(ConfigError) as exc:
        check_loop_option(name, value)
    msg = str(exc.value)
    assert name in msg and repr(value) in msg and allowed in msg


def test_unknown_option_lists_the_allowed_ones():
    with pytest.raises(ConfigError) as exc:
        check_loop_options({"top_layer_frist": False})
    msg = str(exc.value)
    assert "'top_layer_frist'" in msg and "top_layer_first" in msg and "stack_edge_carry" in msg


def test_options_come_back_in_the_loop_configs_order():
    checked = check_loop_options({"stack_edge_carry": False, "finish_actions": 2})
    assert list(checked) == ["finish_actions", "stack_edge_carry"]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("top_layer_first=false", ("top_layer_first", False)),
        ("relay_corners = TRUE", ("relay_corners", True)),
        ("pair_descent=none", ("pair_descent", None)),
        ("finish_actions=2", ("finish_actions", 2)),
        ("crease_band=0.03", ("crease_band", 0.03)),
        ("crease_band=0", ("crease_band", 0.0)),
    ],
)
def test_command_line_values_are_parsed(text, expected):
    assert parse_loop_option(text) == expected


@pytest.mark.parametrize(
    ("text", "needles"),
    [
        ("top_layer_first", ["NAME=VALUE", "top_layer_first"]),
        ("=3", ["NAME=VALUE"]),
        ("crease_band=", ["NAME=VALUE"]),
        ("nosuch=1", ["'nosuch'", "allowed"]),
        ("crease_band=abc", ["crease_band", "'abc'", "a length in m"]),
        ("top_layer_first=no", ["top_layer_first", "'no'", "true or false"]),
        ("finish_actions=1.5", ["finish_actions", "1.5", "an integer"]),
    ],
)
def test_bad_command_line_values_get_a_clear_error(text, needles):
    with pytest.raises(ConfigError) as exc:
        parse_loop_option(text)
    for needle in needles:
        assert needle in str(exc.value)


def test_an_option_given_twice_is_refused():
    assert loop_options_from_args(["crease_band=0.01", "relay_corners=false"]) == {
        "crease_band": 0.01,
        "relay_corners": False,
    }
    with pytest.raises(ConfigError, match="relay_corners is given twice"):
        loop_options_from_args(["relay_corners=false", "relay_corners=true"])


def test_applied_options_set_their_fields_and_leave_the_rest():
    base = LoopConfig(recipe="quarter_y", retries=2)
    loop = apply_loop_options(base, {"stack_edge_carry": False, "pair_descent": None})
    assert loop.stack_edge_carry is False and loop.pair_descent is None
    assert dataclasses.replace(loop, stack_edge_carry=True, pair_descent=0.04) == base
    with pytest.raises(ConfigError, match="relay_side"):
        apply_loop_options(base, {"relay_side": -1.0})


def test_help_names_every_option_with_its_default():
    text = loop_options_help()
    for name in LOOP_OPTIONS:
        assert name in text
    assert "top_layer_first (switch, default true)" in text
    assert "pair_descent (length or none, default 0.04)" in text
    assert loop_option_default("finish_actions") == LoopConfig.finish_actions


def test_the_episode_config_checks_its_options_and_the_loop_gets_them():
    cfg = EpisodeConfig(
        garment="pants", recipe="leg_over_leg", loop_options={"top_layer_first": False}
    )
    loop = loop_config(cfg)
    assert loop.top_layer_first is False and loop.recipe == "leg_over_leg"
    assert loop_config(EpisodeConfig()) == dataclasses.replace(
        loop_config(EpisodeConfig(loop_options={"crease_band": 0.05})), crease_band=0.02
    )
    with pytest.raises(ConfigError, match=r"crease_band = 0\.9"):
        EpisodeConfig(loop_options={"crease_band": 0.9})


def test_a_garment_takes_only_the_options_its_loop_reads():
    """The garment loop reads top_layer_first and relay_min_rise; a towel option set for a
    T-shirt or pants would be silently ignored, so it is refused, naming what is read."""
    read = {"top_layer_first": False, "relay_min_rise": 0.01}
    assert check_loop_options(read, "tshirt") == read
    with pytest.raises(
        ConfigError,
        match=r"^loop options stack_inset, stack_edge_carry act on "
        r"towel folds only; the pants loop reads top_layer_first, relay_min_rise$",
    ):
        check_loop_options({"stack_edge_carry": False, "stack_inset": 0.01, **read}, "pants")
    with pytest.raises(ConfigError, match="finish_actions acts on towel folds only"):
        EpisodeConfig(garment="tshirt", recipe="retail", loop_options={"finish_actions": 0})
    assert set(GARMENT_LOOP_OPTIONS) <= set(LOOP_OPTIONS)
    # A towel takes every option.
    every = {name: loop_option_default(name) for name in LOOP_OPTIONS}
    assert check_loop_options(every) == every
