"""Suite files: the repository's suites load, and every bad value gets one clear error."""

import dataclasses
import math

import pytest

from foldbot.bench.suite import (
    MAX_SEED,
    MAX_SEEDS,
    SUITES_DIR,
    EpisodeSpec,
    available_suites,
    load_suite,
    parse_seeds,
    suite_from_dict,
)
from foldbot.errors import ConfigError
from foldbot.pipeline import loop_config
from foldbot.sim.cloth import ClothConfig


def test_repository_suites_are_listed():
    assert {"smoke", "towel_full", "towel_compare"} <= set(available_suites())


def test_smoke_suite_is_tiny_and_covers_both_comparisons():
    suite = load_suite("smoke")
    assert 1 <= len(suite.episodes) <= 8
    assert {e.towel_resolution for e in suite.episodes} == {6}
    assert {e.video_fps for e in suite.episodes} == {0.0}
    assert set(suite.axes["perception"]) == {"vision", "oracle"}
    assert set(suite.axes["loop"]) == {"closed", "open"}


def test_full_towel_suite_has_50_randomised_seeds_per_recipe():
    suite = load_suite("towel_full")
    recipes = {"half", "quarter", "diagonal", "thirds"}
    assert recipes <= set(suite.axes["recipe"])
    for recipe in recipes:
        eps = [e for e in suite.episodes if e.recipe == recipe]
        assert len({e.seed for e in eps}) >= 50
        assert {e.perception for e in eps} == {"vision"}
        assert {e.towel_side_range for e in eps} == {(0.25, 0.45)}
    assert suite.randomised["towel_side_m"] == [0.25, 0.45]


def test_the_full_suites_first_20_seeds_are_the_loop_acceptance_suites_episodes():
    """towel_full is towel_loop over 50 seeds: the same cell, towels and draws."""
    full, loop = load_suite("towel_full"), load_suite("towel_loop")
    assert [e for e in full.episodes if e.seed < 20] == list(loop.episodes)
    assert {e.seed for e in full.episodes} == set(range(50))


def test_a_suite_over_other_seeds_draws_each_as_its_own_seeds(tmp_path):
    """load_suite(name, seeds): the suite's episodes for those seeds, each drawn alone: towel_full
    over seeds 3 and 30 is its own episodes for them; a bad seed is named."""
    full = load_suite("towel_full")
    picked = load_suite("towel_full", [30, 3])
    assert list(picked.episodes) == [e for e in full.episodes if e.seed in (3, 30)]
    assert picked.axes["seeds"] == [3, 30]
    bare = tmp_path / "bare.toml"
    bare.write_text('name = "bare"\n')  # no [axes] at all: the seeds are the only axis given
    assert [e.seed for e in load_suite(str(bare), [5]).episodes] == [5]
    with pytest.raises(ConfigError, match=r"axes\.seeds must name at least one seed"):
        load_suite("smoke", [])


def test_compare_suite_pairs_every_cell():
    suite = load_suite("towel_compare")
    cells = {(e.recipe, e.perception, e.loop) for e in suite.episodes}
    assert len(cells) == 2 * 2 * 2
    assert len(suite.episodes) == 8 * len(suite.axes["seeds"])
    # Re-measured with vertex rows on the half folds' lines, in towel_loop's cell.
    assert {(e.towel_resolution, e.towel_odd_grid) for e in suite.episodes} == {(17, True)}
    assert {e.park for e in suite.episodes} == {"out_of_view"}
    # Its towels are towel_loop's: the closed-loop vision episodes are the same specs.
    loop = {(e.recipe, e.seed): e for e in load_suite("towel_loop").episodes}
    for e in suite.episodes:
        if (e.perception, e.loop) == ("vision", "closed"):
            assert e == loop[(e.recipe, e.seed)]


def test_replicates_fold_each_seeds_cloth_again_a_tenth_of_a_millimetre_away(tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data(seeds="3-4", replicates=3))
    assert [e.id for e in suite.episodes] == [
        "towel-half-oracle-closed-s0003",
        "towel-half-oracle-closed-s0003-r1",
        "towel-half-oracle-closed-s0003-r2",
        "towel-half-oracle-closed-s0004",
        "towel-half-oracle-closed-s0004-r1",
        "towel-half-oracle-closed-s0004-r2",
    ]
    assert [e.to_config().replicate for e in suite.episodes] == [0, 1, 2, 0, 1, 2]
    assert suite.axes["replicates"] == 3
    # Replicate 0 is the seed's episode as before: its spec (and so a resumed run) is unchanged.
    plain = suite_from_dict(tiny_suite_data(seeds="3-4"))
    assert suite.episodes[0] == plain.episodes[0] and "replicate" not in plain.episodes[0].as_dict()
    again = EpisodeSpec.from_dict(suite.episodes[1].as_dict())
    assert again == suite.episodes[1] and again.as_dict()["replicate"] == 1


def test_ids_are_stable_unique_and_round_trip(tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data(perception=["vision", "oracle"], seeds="3-4"))
    ids = [e.id for e in suite.episodes]
    assert ids == [
        "towel-half-vision-closed-s0003",
        "towel-half-vision-closed-s0004",
        "towel-half-oracle-closed-s0003",
        "towel-half-oracle-closed-s0004",
    ]
    for e in suite.episodes:
        assert EpisodeSpec.from_dict(e.as_dict()) == e


def test_spec_maps_onto_the_episode_config(tiny_suite_data):
    data = tiny_suite_data(loop=["open"])
    data["randomise"] = {"towel_side": [0.25, 0.35], "position_jitter": 0.02, "yaw_deg": 10}
    cfg = load_one(data).to_config()
    assert cfg.closed_loop is False
    assert cfg.towel_size_range == (0.25, 0.35)
    assert cfg.position_jitter == 0.02
    assert cfg.yaw_range == pytest.approx(math.radians(10))
    assert cfg.towel.resolution == 6 and cfg.video_fps == 0
    assert cfg.park == "home"
    data["episode"]["park"] = "out_of_view"
    assert load_one(data).to_config().park == "out_of_view"


def test_time_step_sets_the_physics_step_and_is_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().sim.time_step == pytest.approx(1 / 360)
    # Runs recorded before the key existed keep resuming: their specs have no time_step.
    assert "time_step" not in default.as_dict()
    data["episode"]["time_step"] = 1 / 480
    spec = load_one(data)
    assert spec.to_config().sim.time_step == pytest.approx(1 / 480)
    assert spec.as_dict()["time_step"] == pytest.approx(1 / 480)
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec


def test_speed_scale_slows_the_arms_and_is_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().motion.speed_scale == 1.0
    assert "speed_scale" not in default.as_dict()  # earlier runs resume unchanged
    data["episode"]["speed_scale"] = 0.5
    spec = load_one(data)
    assert spec.to_config().motion.speed_scale == 0.5
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec


def test_robot_reaches_the_cell_and_is_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().robot == "ur5"
    assert "robot" not in default.as_dict()  # earlier runs resume unchanged
    data["episode"]["robot"] = "ur5e"
    spec = load_one(data)
    assert spec.to_config().robot == "ur5e" and spec.as_dict()["robot"] == "ur5e"
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec


def test_odd_grid_reaches_the_towel_and_is_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().towel.odd_grid is False
    assert "towel_odd_grid" not in default.as_dict()  # older runs keep resuming
    data["towel"]["odd_grid"] = True
    spec = load_one(data)
    assert spec.to_config().towel.odd_grid is True
    assert spec.to_config().towel.grid_shape == (7, 7)  # resolution 6 → 7 odd
    assert spec.as_dict()["towel_odd_grid"] is True
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec
    assert "odd counts" in suite_from_dict(data).randomised["text"]


def test_max_vertices_reaches_the_towel_and_is_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().towel.max_vertices is None
    assert "towel_max_vertices" not in default.as_dict()  # older runs keep resuming
    data["towel"].update(resolution=13, odd_grid=True, max_vertices=143)
    spec = load_one(data)
    assert spec.to_config().towel.grid_shape == (11, 11)  # the 30 cm square: 13 × 13 is 169
    assert spec.as_dict()["towel_max_vertices"] == 143
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec
    assert "at most 143 vertices" in suite_from_dict(data).randomised["text"]


def test_arms_reach_the_cell_and_are_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().arms == 1
    assert "arms" not in default.as_dict()  # older runs keep resuming
    data["episode"]["arms"] = 2
    spec = load_one(data)
    assert spec.to_config().arms == 2
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec


def test_jaw_catch_reaches_the_cell_and_is_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().jaw_catch == "vertices"
    assert "jaw_catch" not in default.as_dict()  # older runs keep resuming
    data["episode"]["jaw_catch"] = "surface"
    spec = load_one(data)
    assert spec.to_config().jaw_catch == "surface"
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec


def test_loop_options_reach_the_loop_and_are_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().loop_options == {}
    assert "loop_options" not in default.as_dict()  # older runs keep resuming
    assert suite_from_dict(data).loop_options == {}
    data["loop_options"] = {"stack_edge_carry": False, "pair_descent": "none", "crease_band": 0}
    spec = load_one(data)
    expected = {"crease_band": 0.0, "pair_descent": None, "stack_edge_carry": False}
    assert spec.to_config().loop_options == expected
    assert loop_config(spec.to_config()).stack_edge_carry is False
    assert spec.as_dict()["loop_options"] == expected
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec
    assert suite_from_dict(data).loop_options == expected


def test_cloth_options_reach_the_cloth_and_are_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().cloth == ClothConfig()
    assert "cloth_options" not in default.as_dict()  # older runs keep resuming
    assert suite_from_dict(data).cloth_options == {}
    data["cloth"] = {"margin_divisor": 6.5, "friction": 2}
    spec = load_one(data)
    expected = {"friction": 2.0, "margin_divisor": 6.5}
    assert spec.to_config().cloth == ClothConfig(friction=2.0, margin_divisor=6.5)
    assert spec.as_dict()["cloth_options"] == expected
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec
    assert suite_from_dict(data).cloth_options == expected


def test_flatten_options_reach_the_episode_and_are_left_out_of_specs_by_default(
    tiny_suite_data,
):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().flatten_options == {}
    assert "flatten_options" not in default.as_dict()  # older runs keep resuming
    assert suite_from_dict(data).flatten_options == {}
    data["episode"] = {**data["episode"], "start": "crumpled", "arms": 2}
    data["axes"] = {**data["axes"], "perception": ["vision"]}
    data["flatten_options"] = {"finish_coverage": "none", "spread_lay_speed": 0.05}
    spec = load_one(data)
    expected = {"finish_coverage": None, "spread_lay_speed": 0.05}
    assert spec.to_config().flatten_options == expected
    assert spec.as_dict()["flatten_options"] == expected
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec
    assert suite_from_dict(data).flatten_options == expected


@pytest.mark.parametrize(
    ("episode", "perception", "table", "needle"),
    [
        (
            {"start": "crumpled"},
            ["vision"],
            {"finsh_coverage": 0.97},
            "unknown key 'flatten_options.finsh_coverage'; allowed in [flatten_options]:",
        ),
        (
            {"start": "crumpled"},
            ["vision"],
            {"grasp_inset": 0.5},
            "[flatten_options] flatten option grasp_inset must be in [0, 0.1], got 0.5",
        ),
        (
            {},
            ["vision"],
            {"finish_coverage": "none"},
            "tiny.toml: flatten options (finish_coverage) act on crumpled starts only",
        ),
        (
            {"start": "crumpled", "arms": 2},
            ["vision", "oracle"],
            {"spread_hang_time": 0.5},
            "tiny.toml: flatten option spread_hang_time acts on the two-arm cell's spreads",
        ),
    ],
)
def test_a_bad_flatten_options_table_is_named(tiny_suite_data, episode, perception, table, needle):
    """A bad table, or one the suite's episodes would not read (a flat start; spreads that the
    oracle's episodes never make), is refused when the suite loads, before any run."""
    data = tiny_suite_data(perception=perception)
    data["episode"] = {**data["episode"], **episode}
    data["flatten_options"] = table
    with pytest.raises(ConfigError) as exc:
        suite_from_dict(data, "tiny.toml")
    assert needle in str(exc.value)


def test_a_layout_table_reaches_the_cell_and_is_left_out_of_specs_by_default(tiny_suite_data):
    from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout

    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().sim.layout == DEFAULT_LAYOUT
    assert "layout" not in default.as_dict()  # older runs keep resuming
    data["layout"] = {"table_height": 0.7, "robot_base_xyz": [0.0, 0.0, 0.7]}
    spec = load_one(data)
    assert spec.to_config().sim.layout == CellLayout(
        table_height=0.7, robot_base_xyz=(0.0, 0.0, 0.7)
    )
    assert spec.as_dict()["layout"] == data["layout"]
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec
    data["layout"] = {"robot_base_xyz": [0.0, 0.0, 0.7]}
    with pytest.raises(ConfigError) as exc:
        suite_from_dict(data)
    assert "[layout]: layout robot_base_xyz (0.0, 0.0, 0.7) stands inside the table" in str(
        exc.value
    )
    data["layout"] = {"height": 0.7}
    with pytest.raises(ConfigError, match=r"unknown key 'layout\.height'; allowed in \[layout\]"):
        suite_from_dict(data)


def test_a_layouts_obstacles_reach_the_cell_and_resume_from_the_record(tiny_suite_data):
    import json

    from foldbot.sim.layout import Obstacle

    data = tiny_suite_data()
    post = {"name": "post", "center_xyz": [0.9, 0.5, 1.1], "size_xyz": [0.05, 0.05, 0.7]}
    data["layout"] = {"obstacles": [post]}  # a suite file's [[layout.obstacles]]
    spec = load_one(data)
    assert spec.to_config().sim.layout.obstacles == (
        Obstacle("post", (0.9, 0.5, 1.1), (0.05, 0.05, 0.7)),
    )
    record = json.loads(json.dumps(spec.as_dict()))
    assert record["layout"] == {"obstacles": [post]}
    assert EpisodeSpec.from_dict(record) == spec and hash(spec) == hash(
        EpisodeSpec.from_dict(record)
    )
    data["layout"] = {"obstacles": [{**post, "size_xyz": [0.05, 0.05]}]}
    with pytest.raises(ConfigError, match=r"\[layout\] obstacles\[0\]: obstacle 'post': size_xyz"):
        suite_from_dict(data)


@pytest.mark.parametrize(
    ("table", "needle"),
    [
        (
            {"thickness": 0.01},
            "unknown key 'cloth.thickness'; allowed in [cloth]: bending_stiffness",
        ),
        ({"margin_divisor": 1}, "[cloth] cloth margin_divisor must be in [2, 20]"),
        ({"friction": "high"}, "[cloth] cloth option friction = 'high' must be a finite number"),
    ],
)
def test_a_bad_cloth_table_is_named(tiny_suite_data, table, needle):
    data = tiny_suite_data()
    data["cloth"] = table
    with pytest.raises(ConfigError) as exc:
        suite_from_dict(data)
    assert needle in str(exc.value)


def test_garment_yaw_reaches_the_pose_and_is_left_out_of_specs_by_default(tiny_suite_data):
    data = tiny_suite_data()
    default = load_one(data)
    assert default.to_config().garment_yaw == pytest.approx(math.pi / 2)
    assert "garment_yaw_deg" not in default.as_dict()  # older runs keep resuming
    data["randomise"] = {"garment_yaw_deg": 0}
    with pytest.raises(ConfigError, match="turns a T-shirt or pants"):
        load_one(data)  # the tiny suite folds towels: a garment's yaw has nothing to turn
    data["axes"].update(garment=["tshirt"], recipe=["retail"])
    spec = load_one(data)
    assert spec.to_config().garment_yaw == 0.0
    assert EpisodeSpec.from_dict(spec.as_dict()) == spec
    data["randomise"] = {"garment_yaw_deg": 400}
    with pytest.raises(ConfigError, match=r"randomise\.garment_yaw_deg = 400"):
        load_one(data)


@pytest.mark.parametrize(
    ("two_arms", "one_arm"),
    [("towel_two_arms", "towel_loop"), ("tshirt_two_arms", "tshirt"), ("pants_two_arms", "pants")],
)
def test_the_two_arm_suites_fold_the_one_arm_suites_cloths(two_arms, one_arm):
    two, one = load_suite(two_arms), load_suite(one_arm)
    assert {e.arms for e in two.episodes} == {2}
    # The same episodes but for the arms, so the two cells compare cloth for cloth.
    assert [dataclasses.replace(e, arms=1) for e in two.episodes] == list(one.episodes)


@pytest.mark.parametrize("garment", ["tshirt", "pants"])
def test_the_sideways_suites_turn_the_two_arm_suites_garments(garment):
    upright, sideways = (
        load_suite(f"{garment}_two_arms"),
        load_suite(f"{garment}_two_arms_sideways"),
    )
    assert {e.to_config().garment_yaw for e in sideways.episodes} == {math.pi}
    same = [dataclasses.replace(e, garment_yaw_deg=90.0) for e in sideways.episodes]
    seeds = {e.seed for e in sideways.episodes}
    assert seeds == set(range(10))  # measured on the first 10 of the upright suites' garments
    assert same == [e for e in upright.episodes if e.seed in seeds]


def test_the_loop_acceptance_suite_parks_out_of_view_over_20_seeds():
    suite = load_suite("towel_loop")
    assert len(suite.episodes) == 80
    assert {e.seed for e in suite.episodes} == set(range(20))
    assert {e.park for e in suite.episodes} == {"out_of_view"}
    # Measured: with vertex rows on the half folds' lines, half folds succeed more often.
    assert {(e.towel_resolution, e.towel_odd_grid) for e in suite.episodes} == {(17, True)}


@pytest.mark.parametrize(
    "name",
    [
        "tshirt",
        "pants",
        "tshirt_two_arms",
        "pants_two_arms",
        "towel_crumpled",
        "towel_crumpled_two_arms",
    ],
)
def test_the_garment_and_crumpled_suites_park_at_home(name):
    # Measured: parked out of view, garments folded worse and crumpled towels diverged more.
    assert {e.park for e in load_suite(name).episodes} == {"home"}
    # 20 seeds, as the towel targets: a 10-seed mean moved 2-7 mm between runs of the same code.
    assert {e.seed for e in load_suite(name).episodes} == set(range(20))


def test_the_two_arm_crumpled_suite_is_the_crumpled_one_with_two_arms():
    one, two = load_suite("towel_crumpled").episodes, load_suite("towel_crumpled_two_arms").episodes
    assert {e.arms for e in two} == {2} and {e.arms for e in one} == {1}
    # Its jaws also hold the cloth between mesh points (measured with spreads only).
    assert {e.jaw_catch for e in two} == {"surface"} and {e.jaw_catch for e in one} == {"vertices"}
    # Both cloths' layers slide on each other, and a guard puts back what goes through the cloth
    # (measured: with both, far fewer heaps blow up in either cell), so both cells flatten one cloth.
    cloth = (("layer_friction", 0.25), ("crossing_guard", 1))
    assert {e.cloth_options for e in two} == {cloth} and {e.cloth_options for e in one} == {cloth}
    same = [dataclasses.replace(e, arms=1, jaw_catch="vertices") for e in two]
    assert same == list(one)


def load_one(data):
    (spec,) = suite_from_dict(data).episodes
    return spec


def test_seeds():
    assert parse_seeds("0-3") == [0, 1, 2, 3]
    assert parse_seeds("5,1,1") == [1, 5]
    assert parse_seeds([2, 0]) == [0, 2]
    for bad in ("3-1", "a", "", "-2", [1.5]):
        with pytest.raises(ConfigError, match="seeds"):
            parse_seeds(bad)


@pytest.mark.parametrize(
    "bad",
    [
        "0-99999999999",  # refused before the range is expanded (it was a MemoryError)
        f"0-{MAX_SEEDS}",
        f"0-{MAX_SEEDS - 1},{MAX_SEEDS}",
        str(MAX_SEED + 1),
        [MAX_SEED + 1],
    ],
)
def test_too_many_seeds_or_too_large_a_seed_is_refused(bad, tiny_suite_data):
    with pytest.raises(ConfigError) as exc:
        parse_seeds(bad)
    assert f"at most {MAX_SEEDS} seeds" in str(exc.value) and repr(bad)[:20] in str(exc.value)
    data = tiny_suite_data(seeds=bad)
    with pytest.raises(ConfigError, match=rf"x.toml: axes.seeds must name at most {MAX_SEEDS}"):
        suite_from_dict(data, source="x.toml")


def test_the_most_seeds_and_the_largest_seed_are_allowed():
    assert len(parse_seeds(f"0-{MAX_SEEDS - 1}")) == MAX_SEEDS
    assert parse_seeds(f"{MAX_SEED - 1}-{MAX_SEED}") == [MAX_SEED - 1, MAX_SEED]
    assert parse_seeds(f"0-{MAX_SEEDS - 1},5") == list(range(MAX_SEEDS))  # counted once


def test_a_suite_file_with_a_huge_seed_range_is_refused_at_once(tmp_path):
    """The range is checked before it is expanded: `fold --suite` and `bench --suite` over
    such a file hung or ran out of memory."""
    path = tmp_path / "huge.toml"
    path.write_text('name = "huge"\n[axes]\nseeds = "0-99999999999"\n')
    with pytest.raises(ConfigError, match=r"huge.toml: axes.seeds must name at most 10000 seeds"):
        load_suite(str(path))


def test_unknown_suite_name_lists_the_available_ones():
    with pytest.raises(ConfigError) as exc:
        load_suite("no_such_suite")
    msg = str(exc.value)
    assert "no_such_suite" in msg and "smoke" in msg and "towel_full" in msg


@pytest.mark.parametrize(
    ("edit", "needles"),
    [
        (lambda d: d.update(colour="red"), ["'colour'", "allowed"]),
        (lambda d: d["axes"].update(recipe=["half", "origami"]), ["origami", "thirds"]),
        (lambda d: d["axes"].update(perception=["lidar"]), ["lidar", "oracle"]),
        (lambda d: d["axes"].update(loop=["sometimes"]), ["sometimes", "open"]),
        (lambda d: d["axes"].update(garment=["sock"]), ["sock", "towel"]),
        (lambda d: d["axes"].update(recipe=[]), ["axes.recipe", "empty"]),
        (lambda d: d["axes"].update(recipe="half"), ["axes.recipe", "list"]),
        (lambda d: d["axes"].update(seeds="9-2"), ["seeds", "9-2"]),
        (lambda d: d["axes"].update(replicates=0), ["axes.replicates = 0", "[1, 20]"]),
        (lambda d: d["axes"].update(replicates="3"), ["axes.replicates = '3'", "int"]),
        (lambda d: d["axes"].pop("seeds"), ["axes.seeds", "required"]),
        (lambda d: d["towel"].update(resolution=99), ["towel.resolution", "99"]),
        (lambda d: d["towel"].update(width=2.0), ["towel.width", "2.0"]),
        (lambda d: d["towel"].update(odd_grid="yes"), ["towel.odd_grid", "bool"]),
        (lambda d: d["towel"].update(max_vertices=10), ["towel.max_vertices = 10", "[25, 1600]"]),
        (lambda d: d["towel"].update(max_vertices=1.5), ["towel.max_vertices", "int"]),
        (lambda d: d.update(randomise={"towel_side": [0.4, 0.2]}), ["towel_side", "lo ≤ hi"]),
        (lambda d: d.update(randomise={"towel_side": 0.3}), ["towel_side", "[lo, hi]"]),
        (lambda d: d.update(randomise={"yaw_deg": -5}), ["yaw_deg", "-5"]),
        (lambda d: d.update(randomise={"spin": 1}), ["randomise.spin", "yaw_deg"]),
        (lambda d: d["episode"].update(retries=-1), ["episode.retries", "-1"]),
        (lambda d: d["episode"].update(park="garage"), ["episode.park", "garage", "out_of_view"]),
        (lambda d: d["episode"].update(time_step=0.5), ["episode.time_step", "0.5"]),
        (lambda d: d["episode"].update(arms=3), ["episode.arms", "3", "1, 2"]),
        (
            lambda d: d["episode"].update(jaw_catch="glue"),
            ["episode.jaw_catch", "glue", "vertices, surface"],
        ),
        (lambda d: d["episode"].update(time_step=0), ["episode.time_step", "0"]),
        (
            lambda d: d["episode"].update(speed_scale=0.01),
            ["episode.speed_scale = 0.01", "[0.05, 1]"],
        ),
        (
            lambda d: d["episode"].update(robot="ur10"),
            ["episode.robot = 'ur10'", "ur5, ur5e, panda"],
        ),
        (
            lambda d: d.update(loop_options={"top_layer_frist": False}),
            ["'loop_options.top_layer_frist'", "top_layer_first"],
        ),
        (
            lambda d: d.update(loop_options={"crease_band": 0.9}),
            ["[loop_options]", "crease_band = 0.9", "a length in m"],
        ),
        (
            lambda d: d.update(loop_options={"relay_corners": "no"}),
            ["[loop_options]", "relay_corners = 'no'", "true or false"],
        ),
        (
            lambda d: (
                d["axes"].update(garment=["pants"], recipe=["leg_over_leg"]),
                d.update(loop_options={"stack_inset": 0.02, "top_layer_first": False}),
            ),
            ["[loop_options]", "stack_inset acts on towel folds only", "the pants loop reads"],
        ),
        (lambda d: d.update(reference={"ravens_speed": "yes"}), ["ravens_speed", "bool"]),
        (lambda d: d.update(name=""), ["name"]),
    ],
)
def test_bad_fields_get_a_clear_error(tiny_suite_data, edit, needles):
    data = tiny_suite_data()
    edit(data)
    with pytest.raises(ConfigError) as exc:
        suite_from_dict(data, source="x.toml")
    msg = str(exc.value)
    assert "x.toml" in msg
    for needle in needles:
        assert needle in msg


def test_bad_toml_and_a_missing_file(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text("name = [unclosed\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_suite(str(bad))
    with pytest.raises(ConfigError, match="does not exist"):
        load_suite(str(tmp_path / "missing.toml"))


def test_a_suite_in_the_suites_folder_is_named_as_its_file(tmp_path, monkeypatch):
    import foldbot.bench.suite as suite_module

    text = (SUITES_DIR / "smoke.toml").read_text()
    assert 'name = "smoke"' in text
    (tmp_path / "a.toml").write_text(text.replace('name = "smoke"', 'name = "b"'))
    assert load_suite(str(tmp_path / "a.toml")).name == "b"  # a file elsewhere names itself
    monkeypatch.setattr(suite_module, "SUITES_DIR", tmp_path.resolve())
    with pytest.raises(ConfigError, match="name = 'b' must match the file name"):
        load_suite("a")


def test_repository_suite_names_match_their_files():
    for path in SUITES_DIR.glob("*.toml"):
        assert load_suite(path.stem).name == path.stem
