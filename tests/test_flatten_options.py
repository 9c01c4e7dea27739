"""How a crumpled towel is flattened, set by name: checked, parsed from the command line, turned
into the pull and spread configurations, refused where an episode would not read it, and carried
into a real crumpled episode."""

import dataclasses
import json
import math
import subprocess
import sys

import pytest

from foldbot.errors import ConfigError
from foldbot.flatten_options import (
    FLATTEN_OPTION_FIELDS,
    FLATTEN_OPTIONS,
    SPREAD_OPTIONS,
    check_flatten_option,
    check_flatten_options,
    flatten_configs,
    flatten_option_default,
    flatten_options_from_args,
    flatten_options_help,
    parse_flatten_option,
    refused_flatten_options,
    shown_flatten_value,
)
from foldbot.pipeline import EpisodeConfig
from foldbot.planning.flatten import FlattenConfig
from foldbot.planning.spread import SpreadConfig

KIND_OF_TYPE = {
    "bool": {"switch"},
    "int": {"count"},
    "float": {"number"},
    "float | None": {"number or none"},
    "str": {"choice"},
}


def test_every_option_names_a_field_of_its_config_of_its_kind():
    for name, option in FLATTEN_OPTION_FIELDS.items():
        types = {f.name: f.type for f in dataclasses.fields(option.config)}
        assert option.kind in KIND_OF_TYPE[types[option.field]], name
        # The spreads' options say so in their name; the pulls' are the field's own name.
        assert name == (f"spread_{option.field}" if option.config is SpreadConfig else option.field)
    assert set(SPREAD_OPTIONS) == {n for n in FLATTEN_OPTIONS if n.startswith("spread_")}


def test_the_action_budget_is_not_an_option():
    """Flattening success is coverage ≥ 0.9 within 6 actions (issue 6): the budget stays."""
    assert "max_actions" not in FLATTEN_OPTIONS


@pytest.mark.parametrize(
    ("name", "value", "expected"),
    [
        ("finish_coverage", None, None),
        ("finish_coverage", 1, 1.0),
        ("target_coverage", 0.85, 0.85),
        ("grasp_layer", "top", "top"),
        ("retries", 0, 0),
        ("keep_yaw", False, False),
        ("spread_pull_from", 0.8, 0.8),
        ("spread_lay_speed", 0.05, 0.05),
        ("spread_grasp_lean", "sides", "sides"),
    ],
)
def test_good_values_are_kept(name, value, expected):
    checked = check_flatten_option(name, value)
    assert checked == expected and type(checked) is type(expected)


@pytest.mark.parametrize(
    ("name", "value", "allowed"),
    [
        ("keep_yaw", 1, "true or false"),
        ("grasp_layer", "middle", "one of all, top"),
        ("spread_grasp_lean", "up", "one of sides, apart"),
        ("spread_grasp_lean", 1.0, "one of sides, apart"),
        ("retries", 1.5, "an integer"),
        ("retries", True, "an integer"),
        ("grasp_inset", None, "a number (m)"),
        ("grasp_inset", "3 cm", "a number (m)"),
        ("finish_coverage", False, "a number (coverage), or none"),
        ("spread_lay_speed", "fast", "a number (m/s)"),
    ],
)
def test_bad_values_name_the_option_the_value_and_what_is_allowed(name, value, allowed):
    with pytest.raises(ConfigError) as exc:
        check_flatten_option(name, value)
    msg = str(exc.value)
    assert name in msg and repr(value) in msg and allowed in msg


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"grasp_inset": 0.5}, "flatten option grasp_inset must be in [0, 0.1], got 0.5"),
        ({"target_coverage": 2.0}, "flatten option target_coverage must be in (0, 1.5]"),
        ({"finish_coverage": math.inf}, "flatten option finish_coverage must be None or in"),
        ({"retries": 9}, "flatten option retries must be an integer in [0, 5], got 9"),
        (
            {"spread_release_height": 0.5},
            "flatten option spread_release_height must be in [0, 0.2], got 0.5",
        ),
    ],
)
def test_out_of_range_values_are_refused_by_the_configs_own_ranges(options, message):
    with pytest.raises(ConfigError) as exc:
        check_flatten_options(options)
    assert str(exc.value).startswith(message)


def test_unknown_option_lists_the_allowed_ones():
    with pytest.raises(ConfigError) as exc:
        check_flatten_options({"finsh_coverage": None})
    msg = str(exc.value)
    assert "'finsh_coverage'" in msg and "finish_coverage" in msg and "spread_lay_speed" in msg
    with pytest.raises(ConfigError, match="name = value"):
        check_flatten_options([("finish_coverage", None)])  # type: ignore[arg-type]


def test_options_come_back_in_their_listed_order():
    checked = check_flatten_options({"spread_lay_speed": 0.05, "finish_coverage": None})
    assert list(checked) == ["finish_coverage", "spread_lay_speed"]


def test_the_configs_get_the_options_and_keep_the_rest():
    pulls, spreads = flatten_configs(
        {"finish_coverage": None, "grasp_layer": "top", "spread_release_height": 0.05}
    )
    assert pulls == FlattenConfig(finish_coverage=None, grasp_layer="top")
    assert spreads == SpreadConfig(release_height=0.05)
    assert pulls.stop_coverage == pulls.target_coverage  # no finishing pulls
    assert flatten_configs({}) == (FlattenConfig(), SpreadConfig())
    assert flatten_option_default("spread_pull_from") is None
    assert flatten_option_default("finish_coverage") == FlattenConfig().finish_coverage


def test_a_cell_laid_out_elsewhere_moves_the_defaults_placed_in_the_world():
    """The flattening's region and a spread's laid-towel centre move with the workspace, how far
    out a spread holds the towel with the arm's base; the options given are set beside them."""
    from foldbot.sim.layout import CellLayout

    layout = CellLayout(
        table_height=0.7, robot_base_xyz=(0.02, 0.0, 0.7), workspace_center_xy=(0.5, 0.06)
    )
    pulls, spreads = flatten_configs({}, layout)
    (x0, x1, y0, y1), (dx0, dx1, dy0, dy1) = pulls.workspace, FlattenConfig().workspace
    assert (x0, x1, y0, y1) == pytest.approx((dx0 + 0.05, dx1 + 0.05, dy0 + 0.06, dy1 + 0.06))
    assert spreads.center_xy == pytest.approx((0.5, 0.06))
    assert spreads.hold_far_x == pytest.approx(SpreadConfig().hold_far_x + 0.02)
    assert dataclasses.replace(pulls, workspace=FlattenConfig().workspace) == FlattenConfig()
    pulls, _ = flatten_configs({"grasp_layer": "top"}, layout)
    assert pulls.grasp_layer == "top" and pulls.workspace[0] == pytest.approx(dx0 + 0.05)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("finish_coverage=none", ("finish_coverage", None)),
        ("finish_coverage = 0.97", ("finish_coverage", 0.97)),
        ("target_coverage=1", ("target_coverage", 1.0)),
        ("grasp_layer=top", ("grasp_layer", "top")),
        ("grasp_layer=all", ("grasp_layer", "all")),  # a layer's name, not a keyword
        ("keep_yaw=FALSE", ("keep_yaw", False)),
        ("retries=2", ("retries", 2)),
        ("spread_hang_time=0", ("spread_hang_time", 0.0)),
        ("spread_grasp_lean=sides", ("spread_grasp_lean", "sides")),
    ],
)
def test_command_line_values_are_parsed(text, expected):
    name, value = parse_flatten_option(text)
    assert (name, value) == expected and type(value) is type(expected[1])


@pytest.mark.parametrize(
    ("text", "needles"),
    [
        ("finish_coverage", ["NAME=VALUE", "finish_coverage=none"]),
        ("=3", ["NAME=VALUE"]),
        ("nosuch=1", ["'nosuch'", "allowed"]),
        ("grasp_inset=abc", ["grasp_inset", "'abc'", "a number (m)"]),
        ("keep_yaw=no", ["keep_yaw", "'no'", "true or false"]),
        ("retries=1.5", ["retries", "1.5", "an integer"]),
        ("spread_grasp_lean=top", ["spread_grasp_lean", "'top'", "one of sides, apart"]),
        ("grasp_inset=0.2", ["grasp_inset must be in [0, 0.1], got 0.2"]),
    ],
)
def test_bad_command_line_values_get_a_clear_error(text, needles):
    with pytest.raises(ConfigError) as exc:
        parse_flatten_option(text)
    for needle in needles:
        assert needle in str(exc.value)


def test_an_option_given_twice_is_refused():
    assert flatten_options_from_args(["spread_lay_speed=0.05", "finish_coverage=none"]) == {
        "finish_coverage": None,
        "spread_lay_speed": 0.05,
    }
    with pytest.raises(ConfigError, match=r"finish_coverage is given twice \(none, 0.97\)"):
        flatten_options_from_args(["finish_coverage=none", "finish_coverage=0.97"])


def test_help_names_every_option_with_its_unit_and_default():
    text = flatten_options_help()
    for name in FLATTEN_OPTIONS:
        assert name in text
    assert "finish_coverage (coverage, default 0.97)" in text
    assert "grasp_layer (default all)" in text
    assert "spread_lay_speed (m/s, default 0.1)" in text
    assert "spread_pull_from (coverage, default none)" in text
    assert [shown_flatten_value(v) for v in (True, None, "top", 0.05)] == [
        "true",
        "none",
        "top",
        "0.05",
    ]


def test_an_episode_refuses_the_options_it_would_not_read():
    """Flattening runs from crumpled starts only; spreads in the two-arm cell with vision only
    (the oracle pulls): an option that would be silently ignored is refused instead."""
    assert refused_flatten_options({}, "flat", 1, "vision") is None
    with pytest.raises(
        ConfigError, match=r"^flatten options \(finish_coverage\) act on crumpled starts only"
    ):
        EpisodeConfig(flatten_options={"finish_coverage": None})
    with pytest.raises(ConfigError, match=r"spread_lay_speed acts on .* a one-arm cell pulls$"):
        EpisodeConfig(start="crumpled", flatten_options={"spread_lay_speed": 0.05})
    with pytest.raises(ConfigError, match="the oracle pulls"):
        EpisodeConfig(
            start="crumpled",
            arms=2,
            perception="oracle",
            flatten_options={"spread_lay_speed": 0.05, "spread_hang_time": 0.5},
        )
    cfg = EpisodeConfig(
        start="crumpled",
        arms=2,
        flatten_options={"spread_lay_speed": 0.05, "finish_coverage": None},
    )
    assert cfg.flatten_options == {"finish_coverage": None, "spread_lay_speed": 0.05}
    # One arm reads the pulls' options, by perception or by the oracle.
    assert EpisodeConfig(
        start="crumpled", perception="oracle", flatten_options={"min_pull": 0.03}
    ).flatten_options == {"min_pull": 0.03}
    with pytest.raises(ConfigError, match="grasp_inset must be in"):
        EpisodeConfig(start="crumpled", flatten_options={"grasp_inset": -0.01})


def _fold(out, *options: str) -> dict:
    """A crumpled small towel folded by `foldbot fold` (a fresh process: Bullet's soft-body
    solver keeps process-global state), its result.json."""
    cmd = [
        *(sys.executable, "-m", "foldbot.cli", "fold", "--start", "crumpled", "--resolution", "5"),
        *("--seed", "0", "--video-fps", "0", "--out", str(out)),
    ]
    for option in options:
        cmd += ["--flatten-option", option]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads((out / "result.json").read_text())


@pytest.mark.slow
def test_the_options_reach_a_real_crumpled_episode(tmp_path):
    """With the stop target under the crumpled towel's perceived coverage and no finishing,
    the robot pulls nothing; at the defaults it pulls. result.json records what was set."""
    stopped = _fold(tmp_path / "stopped", "target_coverage=0.1", "finish_coverage=none")
    assert stopped["flatten_options"] == {"target_coverage": 0.1, "finish_coverage": None}
    flat = stopped["flatten"]
    assert flat["actions"] == 0 and flat["reached_target"]
    assert flat["perceived_coverage_start"] < 0.9
    default = _fold(tmp_path / "default")
    assert default["flatten_options"] == {}
    assert default["flatten"]["actions"] >= 1
    # The same towel, crumpled the same way, before either flattening.
    assert default["flatten"]["coverage_start"] == flat["coverage_start"]
