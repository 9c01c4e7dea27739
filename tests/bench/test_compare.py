"""Two run folders compared episode by episode: pairs, the same ones, the paired difference."""

import json

import pytest

from foldbot.bench.compare import compare_runs, load_run, markdown, plot_pairs
from foldbot.bench.summary import mean_interval, success_interval
from foldbot.errors import ConfigError, OutputError


@pytest.fixture
def runs(tmp_path, write_run):
    first = write_run(
        tmp_path / "a",
        {
            "towel-half-vision-closed-s0000": ("half", 0, 8.0),
            "towel-half-vision-closed-s0001": ("half", 1, 12.0),
            "towel-half-vision-closed-s0002": ("half", 2, 9.0),
            "towel-quarter-vision-closed-s0000": ("quarter", 0, 30.0),
            "towel-quarter-vision-closed-s0001": ("quarter", 1, "SimulationDivergedError"),
            "towel-quarter-vision-closed-s0002": ("quarter", 2, None),  # not finished
        },
    )
    second = write_run(
        tmp_path / "b",
        {
            "towel-half-vision-closed-s0000": ("half", 0, 8.0),
            "towel-half-vision-closed-s0001": ("half", 1, 9.0),
            "towel-half-vision-closed-s0002": ("half", 2, 11.0),
            "towel-quarter-vision-closed-s0000": ("quarter", 0, 24.0),
            "towel-quarter-vision-closed-s0001": ("quarter", 1, 40.0),
            "towel-quarter-vision-closed-s0002": ("quarter", 2, 20.0),
        },
        loop_options={"stack_edge_carry": False},
    )
    return first, second


def test_load_run_reads_scored_and_failed_episodes(runs):
    specs, records = load_run(runs[0])
    assert len(specs) == 6 and len(records) == 5
    assert records["towel-half-vision-closed-s0000"]["result"]["fold_error_mm"] == 8.0
    assert records["towel-quarter-vision-closed-s0001"]["error_type"] == "SimulationDivergedError"


def test_pairs_by_id_and_measures_the_paired_difference(runs):
    c = compare_runs(*runs)
    assert c["differing_settings"] == ["loop_options"]
    assert c["only_in_one"] == ["towel-quarter-vision-closed-s0002"]
    overall = c["overall"]
    assert overall["pairs"] == 5 and overall["same"] == 1  # half seed 0, despite its wall time
    assert overall["success_rate"] == [pytest.approx(2 / 5), pytest.approx(2 / 5)]
    assert overall["diverged"] == [1, 0]
    # Scored both ways: half 0, 1, 2 and quarter 0: differences 0, −3, +2, −6.
    assert overall["scored_both"] == 4
    assert overall["difference_mm"]["mean"] == pytest.approx(-7 / 4)
    lo, hi = overall["difference_mm"]["mean_ci95"]
    assert lo < -7 / 4 < hi and lo < 0 < hi  # these four towels show no difference
    assert (overall["difference_mm"]["closer"], overall["difference_mm"]["further"]) == (2, 1)
    half = next(g for g in c["groups"] if g["recipe"] == "half")
    assert half["pairs"] == 3 and half["fold_error_mm_mean"] == [
        pytest.approx(29 / 3),
        pytest.approx(28 / 3),
    ]
    changed = {x["id"]: x for x in c["changed"]}
    assert set(changed) == {
        "towel-half-vision-closed-s0001",
        "towel-half-vision-closed-s0002",
        "towel-quarter-vision-closed-s0000",
        "towel-quarter-vision-closed-s0001",
    }
    assert changed["towel-quarter-vision-closed-s0001"]["outcome"] == [
        "diverged",
        "fold inaccurate",
    ]
    assert changed["towel-half-vision-closed-s0001"]["fold_error_mm"] == [12.0, 9.0]


def test_counts_the_folds_through_themselves_where_recorded(runs):
    first, second = runs
    for eid in ("towel-half-vision-closed-s0001", "towel-quarter-vision-closed-s0000"):
        path = second / "episodes" / eid / "result.json"
        result = json.loads(path.read_text())
        path.write_text(json.dumps({**result, "self_crossings": 12 if "quarter" in eid else 0}))
    c = compare_runs(first, second)
    assert c["overall"]["through_itself"] == [None, {"recorded": 2, "folds": 1, "successes": 0}]
    md = markdown(c)
    assert "| folded through itself: first / second |" in md and "| – / 1 of 2 (0) |" in md


def test_markdown_names_the_changes(runs):
    md = markdown(compare_runs(*runs))
    assert "Episode settings that differ between the runs: `loop_options`." in md
    assert "| **all** | 5 | 1 | 40 % (12–77) / 40 % (12–77) |" in md
    assert "| towel-quarter-vision-closed-s0001 | – → 40.0 | diverged → fold inaccurate |" in md
    assert "| towel-half-vision-closed-s0001 | 12.0 → 9.0 | fold inaccurate → success |" in md


def test_folders_that_are_not_runs_or_share_nothing_are_refused(tmp_path, runs, write_run):
    with pytest.raises(ConfigError, match=r"no suite\.json"):
        compare_runs(tmp_path / "missing", runs[0])
    other = write_run(tmp_path / "c", {"towel-thirds-vision-closed-s0009": ("thirds", 9, 5.0)})
    with pytest.raises(ConfigError, match="share no finished episode"):
        compare_runs(runs[0], other)


def test_two_recipes_on_the_same_towels_pair_by_seed(tmp_path, write_run):
    quarter = write_run(
        tmp_path / "q",
        {
            f"towel-quarter-vision-closed-s000{k}": ("quarter", k, e)
            for k, e in [(0, 40.0), (1, 30.0)]
        },
    )
    quarter_y = write_run(
        tmp_path / "qy",
        {
            f"towel-quarter_y-vision-closed-s000{k}": ("quarter_y", k, e)
            for k, e in [(0, 35.0), (1, 31.0)]
        },
    )
    with pytest.raises(ConfigError, match="share no finished episode"):
        compare_runs(quarter, quarter_y)  # by id, nothing pairs
    c = compare_runs(quarter, quarter_y, pair_by="seed")
    assert c["differing_settings"] == ["recipe"] and c["overall"]["pairs"] == 2
    assert c["overall"]["difference_mm"]["mean"] == pytest.approx(-2.0)
    assert c["groups"][0]["recipe"] == "quarter / quarter_y"
    assert (
        c["changed"][0]["id"]
        == "towel-quarter-vision-closed-s0000 / towel-quarter_y-vision-closed-s0000"
    )
    assert "paired by seed" in markdown(c)
    two = write_run(
        tmp_path / "two",
        {
            "towel-half-vision-closed-s0000": ("half", 0, 8.0),
            "towel-quarter-vision-closed-s0000": ("quarter", 0, 30.0),
        },
    )
    with pytest.raises(
        ConfigError, match=r"one recipe per garment.*towel-half-vision-closed-s0000"
    ):
        compare_runs(two, quarter, pair_by="seed")
    with pytest.raises(ConfigError, match="pair_by = 'recipe'"):
        compare_runs(two, quarter, pair_by="recipe")


def test_replicates_count_as_their_towels(tmp_path, write_run):
    # Two towels, each folded three times in both runs: towel 0 always succeeds and folds
    # 1 mm closer in the second run, towel 1 never succeeds and folds 5 mm further.
    def episodes(shift0, shift1):
        return {
            f"towel-half-vision-closed-s000{t}{'' if k == 0 else f'-r{k}'}": (
                "half",
                t,
                (5.0 + k + shift0) if t == 0 else (20.0 + k + shift1),
            )
            for t in range(2)
            for k in range(3)
        }

    first = write_run(tmp_path / "a", episodes(0.0, 0.0))
    second = write_run(tmp_path / "b", episodes(-1.0, 5.0))
    overall = compare_runs(first, second)["overall"]
    assert overall["pairs"] == 6 and overall["difference_mm"]["mean"] == pytest.approx(2.0)
    # Over the two towels' mean differences (−1, +5), not the six pairs.
    assert overall["difference_mm"]["mean_ci95"] == pytest.approx(mean_interval([-1.0, 5.0]))
    # Three of six succeed, always the same towel: the interval is 1 of 2 towels'.
    assert overall["success_ci95"][0] == pytest.approx(success_interval(1, 2))


def test_pair_by_seed_pairs_replicate_with_replicate(tmp_path, write_run):
    def run(folder, recipe, errors):
        return write_run(
            tmp_path / folder,
            {
                f"towel-{recipe}-vision-closed-s0000{'' if k == 0 else f'-r{k}'}": (recipe, 0, e)
                for k, e in enumerate(errors)
            },
        )

    c = compare_runs(
        run("q", "quarter", (40.0, 30.0, 20.0)),
        run("qy", "quarter_y", (35.0, 31.0, 22.0)),
        pair_by="seed",
    )
    assert c["overall"]["pairs"] == 3
    assert [p["fold_error_mm"] for p in c["pairs"]] == [[40.0, 35.0], [30.0, 31.0], [20.0, 22.0]]
    # One towel folded three times: no interval over a single towel's mean difference.
    assert c["overall"]["difference_mm"]["mean_ci95"] is None


EID = "towel-half-vision-closed-s0000"


@pytest.mark.parametrize(
    ("file", "text", "says"),
    [
        (f"episodes/{EID}/result.json", "{not json", "is not valid JSON"),
        (f"episodes/{EID}/result.json", "", "is empty"),
        (f"episodes/{EID}/result.json", "[]", "holds a JSON array, not an object"),
        (
            f"episodes/{EID}/result.json",
            json.dumps({"success": False, "fold_error_mm": "big"}),
            "fold_error_mm = 'big' must be a number (mm) or null",
        ),
        (
            f"episodes/{EID}/result.json",
            json.dumps({"fold_error_mm": 3.0, "actions": [1]}),
            "actions = [1] must be a list of objects",
        ),
        ("suite.json", "garbage", "is not valid JSON"),
        ("suite.json", "[]", "holds a JSON array, not an object"),
        ("suite.json", json.dumps({"episodes": {EID: 3}}), f"episode '{EID}' = 3 must be a spec"),
        (f"episodes/{EID}.error.json", "garbage", "is not valid JSON"),
        (f"episodes/{EID}.error.json", json.dumps({"error": 7}), "error = 7 must be a string"),
    ],
)
def test_a_malformed_run_file_is_named(tmp_path, write_run, file, text, says):
    record = "SimulationDivergedError" if file.endswith(".error.json") else 8.0
    run = write_run(tmp_path / "a", {EID: ("half", 0, record)})
    (run / file).write_text(text)
    with pytest.raises(ConfigError) as caught:
        load_run(run)
    assert str(run / file) in str(caught.value) and says in str(caught.value)


def test_a_plot_that_cannot_be_written_leaves_no_temp_file(tmp_path, runs):
    folder = tmp_path / "pairs.png"
    folder.mkdir()
    with pytest.raises(OutputError, match=r"pairs\.png: it is a folder"):
        plot_pairs(compare_runs(*runs), folder)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b", "pairs.png"]
    assert list(folder.iterdir()) == []
