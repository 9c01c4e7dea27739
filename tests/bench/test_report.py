"""summary.json, summary.md and errors.png from a synthetic run; nothing half-written is left."""

import json

from foldbot.bench.report import markdown, write_report
from foldbot.bench.suite import suite_from_dict
from foldbot.bench.summary import mean_interval, summarise


def test_report_files(tmp_path, tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data(perception=["vision", "oracle"], seeds="0-2"))
    records = []
    for e in suite.episodes:
        err = 5.0 + e.seed if e.perception == "oracle" else 12.0 + e.seed
        records.append(
            {
                "id": e.id,
                "result": {
                    "success": err < 13,
                    "fold_error_mm": err,
                    "perfect_fold_error_mm": 2.5,
                    "perfect_normalized": 0.875,
                    "normalized_performance": 0.85,
                    # The vision fold of seed 0 (a success) passed through itself.
                    "self_crossings": 7 if (e.perception, e.seed) == ("vision", 0) else 0,
                    "coverage": 0.5,
                    "sim_seconds": 10.0,
                    "wall_seconds": 25.0,
                    "actions": [{"retries": 0, "grasp_success": True}] * 2,
                },
            }
        )
    records[-1] = {"id": records[-1]["id"], "error_type": "Timeout", "error": "no result"}
    summary = summarise(suite, records)
    summary["command"] = "foldbot bench --suite tiny --out X"
    labels = {e.id: f"{e.recipe} {e.perception}" for e in suite.episodes}
    paths = write_report(summary, records, labels, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "errors.png",
        "summary.json",
        "summary.md",
    ]
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    stored = json.loads(paths["json"].read_text())
    assert stored["overall"]["episodes"] == 6 and stored["overall"]["failures"] == {
        "fold inaccurate": 2,
        "timeout": 1,
    }
    md = paths["md"].read_text()
    # 3 of 6 successes: Wilson 95 % interval 19–81 %; errors 12, 13, 14, 5, 6: t interval 4.8–15.2.
    assert "| **all** | 6 | 50 % (19–81) | 10.0 / 12.0 / 13.8 | 4.8–15.2 |" in md
    # Oracle minus vision on the two towels scored both ways: 7 mm closer on each.
    assert "| -7.0 (-7.0 to -7.0), 2 |" in md
    assert "| perfect fold: mm / normalized, mean |" in md and "physically perfect fold" in md
    assert "| 2.5 / 0.875 |" in md
    # Of the 5 scored folds one ended through itself, a success all the same.
    assert "| folded through itself (successes) |" in md and "| 1 of 5 (1) |" in md
    assert stored["overall"]["through_itself"] == {"recorded": 5, "folds": 1, "successes": 1}
    assert "towel half, oracle, closed loop" in md and "vision / oracle" in md
    assert "foldbot bench --suite tiny --out X" in md
    # Every scored episode simulated 10 s in 25 s of wall time: all five under real time.
    assert "| 0.40× (0.40–0.40; 5 under 1×) |" in md
    assert "FabricFlowNet" in md and "timeout" in md
    timed_out = records[-1]["id"]
    inaccurate = next(r["id"] for r in records if "result" in r and not r["result"]["success"])
    assert f"| timeout | 1 | [{timed_out}](episodes/{timed_out}.error.json) |" in md
    assert f"[{inaccurate}](episodes/{inaccurate})" in md


def test_markdown_says_incomplete(tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data(seeds="0-1"))
    md = markdown(summarise(suite, []))
    assert "0 of 2 (INCOMPLETE)" in md


def test_markdown_names_the_loop_options_a_suite_sets(tiny_suite_data):
    plain = markdown(summarise(suite_from_dict(tiny_suite_data()), []))
    assert "Loop options" not in plain
    data = tiny_suite_data()
    data["loop_options"] = {"pair_descent": "none", "relay_corners": False}
    summary = summarise(suite_from_dict(data), [])
    assert summary["suite"]["loop_options"] == {"relay_corners": False, "pair_descent": None}
    assert "Loop options set: relay_corners = false, pair_descent = none" in markdown(summary)


def test_markdown_names_an_arm_other_than_the_ur5(tiny_suite_data):
    plain = summarise(suite_from_dict(tiny_suite_data()), [])
    assert "robot" not in plain["suite"] and "Arm:" not in markdown(plain)
    data = tiny_suite_data()
    data["episode"] = {**data["episode"], "robot": "ur5e"}
    summary = summarise(suite_from_dict(data), [])
    assert summary["suite"]["robot"] == "ur5e"
    assert "Arm: ur5e (`[episode] robot`; the default is the ur5)." in markdown(summary)


def test_markdown_names_the_cloth_options_a_suite_sets(tiny_suite_data):
    assert "Cloth set" not in markdown(summarise(suite_from_dict(tiny_suite_data()), []))
    data = tiny_suite_data()
    data["cloth"] = {"margin_divisor": 6.5}
    summary = summarise(suite_from_dict(data), [])
    assert summary["suite"]["cloth_options"] == {"margin_divisor": 6.5}
    assert "Cloth set: margin_divisor = 6.5 (the others at ClothConfig's defaults)" in markdown(
        summary
    )


def test_markdown_names_the_flatten_options_a_suite_sets(tiny_suite_data):
    assert "Flattening set" not in markdown(summarise(suite_from_dict(tiny_suite_data()), []))
    data = tiny_suite_data()
    data["episode"] = {**data["episode"], "start": "crumpled"}
    data["flatten_options"] = {"grasp_layer": "top", "finish_coverage": "none"}
    summary = summarise(suite_from_dict(data), [])
    assert summary["suite"]["flatten_options"] == {"finish_coverage": None, "grasp_layer": "top"}
    assert (
        "Flattening set: finish_coverage = none, grasp_layer = top (the others at "
        "FlattenConfig's and SpreadConfig's defaults)." in markdown(summary)
    )


def test_markdown_shows_how_replicates_repeat(tiny_suite_data):
    from foldbot.pipeline import REPLICATE_NUDGE_M

    suite = suite_from_dict(tiny_suite_data(seeds="0-1", replicates=2))
    errors = iter((5.0, 7.0, 20.0, 40.0))
    records = [
        {"id": e.id, "result": {"success": e.seed == 0, "fold_error_mm": next(errors)}}
        for e in suite.episodes
    ]
    md = markdown(summarise(suite, records))
    assert f"laid {REPLICATE_NUDGE_M * 1000:g} mm apart" in md
    # Towel 0 (5, 7) always succeeds, towel 1 (20, 40) never: SD within √((2 + 200) / 2) = 10.0,
    # of the means (6, 30) 17.0.
    assert "| towel half, oracle, closed loop | 2 × 2 | 1 / 0 / 1 | 10.0 / 17.0 |" in md
    assert "## Replicates" not in markdown(summarise(suite_from_dict(tiny_suite_data()), []))


def test_markdown_shows_the_flattening_with_intervals_over_the_towels(tiny_suite_data):
    data = tiny_suite_data(seeds="0-1", replicates=2)
    data["episode"]["start"] = "crumpled"
    suite = suite_from_dict(data)
    # Towel 0 flattened to 0.95 and 0.97 in 2 actions; towel 1 left at 0.60 and 0.70 after 6.
    cover = iter((0.95, 0.97, 0.60, 0.70))
    records = []
    for e in suite.episodes:
        end = next(cover)
        flat = {"success": end >= 0.9, "actions": 2 if e.seed == 0 else 6,
                "coverage_start": 0.4, "coverage_end": end}  # fmt: skip
        records.append({"id": e.id, "result": {"success": False, "flatten": flat}})
    md = markdown(summarise(suite, records))
    assert "## Flattening" in md
    # Coverage after: towel means 0.96 and 0.65, Student's t over the two towels, not four folds.
    lo, hi = mean_interval([0.96, 0.65])
    assert f"| 0.80 / 0.82 / 0.97 | {lo:.2f}–{hi:.2f} | – |" in md  # crossings not recorded
    # With the crossings recorded: towel 1 crumpled through itself and stayed so, towel 0's
    # second run passed through itself while flattening.
    crossings = iter(((0, 0), (0, 3), (12, 9), (12, 14)))
    for r in records:
        start, end = next(crossings)
        r["result"]["flatten"].update(self_crossings_start=start, self_crossings_end=end)
    md = markdown(summarise(suite, records))
    assert f"| {lo:.2f}–{hi:.2f} | 2 / 3 of 4 (2 of 2) |" in md
    assert "*cloth passed through itself*" in md
    assert "episodes that ended in an error" not in md  # none did
    # Two more towels' episodes ended in errors: one while flattening a tangled heap, one in
    # the fold after flattening; a third's record (a run before facts were kept) says nothing.
    records[1:] = [
        {"id": records[1]["id"], "error_type": "SimulationDivergedError", "error": "x",
         "facts": {"flatten": {"success": False, "actions": 1, "self_crossings_start": 7}}},
        {"id": records[2]["id"], "error_type": "SimulationDivergedError", "error": "x",
         "facts": {"flatten": {"success": True, "actions": 2, "self_crossings_start": 0,
                               "self_crossings_end": 0}}},
        {"id": records[3]["id"], "error_type": "Timeout", "error": "no result"},
    ]  # fmt: skip
    md = markdown(summarise(suite, records))
    assert (
        "of the 3 episodes that ended in an error, 1 of the 2 whose record kept the crumple had "
        "passed through themselves once crumpled; 1 had been flattened before the error, in the "
        "fold."
    ) in md


def test_markdown_shows_the_first_frames_perception(tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data(seeds="0-1"))
    errors = iter(({"near_left": 0.5, "far_left": 12.0}, {"near_left": 1.5, "far_left": 2.0}))
    records = [
        {"id": e.id, "result": {"success": False, "first_frame_keypoint_error_mm": next(errors)}}
        for e in suite.episodes
    ]
    md = markdown(summarise(suite, records))
    assert "## Perception in the first frame" in md
    # Pooled: 0.5, 1.5, 2.0, 12.0 → median 1.75; one episode off by > 10 mm; far_left worst.
    assert "| 2 | 1.8 / " in md and "| 1 | far_left: 7.0 / 12.0 |" in md
    assert "## Perception in the first frame" not in markdown(summarise(suite, []))


def test_markdown_sets_the_loops_verdict_beside_success(tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data(seeds="0-1"))
    outcomes = iter(((True, 0.9), (False, 0.85)))  # verified both times; the second failed
    records = []
    for e in suite.episodes:
        success, iou = next(outcomes)
        stages = [{"mask_iou_vs_predicted": iou, "verified": True}]
        records.append({"id": e.id, "result": {"success": success, "stages": stages}})
    md = markdown(summarise(suite, records))
    assert "## The loop's own verdict against ground truth" in md
    assert "| 2 | 1 / 1 | 0 / 0 | 50 % | 0.90 (0.90–0.90) / 0.85 (0.85–0.85) |" in md
    assert "own verdict" not in markdown(summarise(suite, []))
